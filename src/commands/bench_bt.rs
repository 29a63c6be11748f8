//! `chronomap bench bt`: reading and checking BehaviorTree.CPP 4 XML on generated trees against
//! parsing the same text with roxmltree alone, in the same run ([`chronomap_bench::bt`]
//! measures and reports, this prints).

use anyhow::Result;
use chronomap_bench::bt::default_cases;

use crate::cli::BenchBtArgs;
use crate::out;
use crate::output::print_bench;

pub fn bt(args: &BenchBtArgs) -> Result<()> {
    let rows = chronomap_bench::bt::run(&default_cases(), args.repeats as usize)?;
    print_bench(args.json, &rows, |rows| {
        Ok(out!("{}", chronomap_bench::bt::text(rows, args.repeats))?)
    })
}
