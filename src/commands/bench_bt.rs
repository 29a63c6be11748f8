//! `chronomap bench bt`: reading and checking BehaviorTree.CPP 4 XML on generated trees against
//! parsing the same text with roxmltree alone, in the same run ([`chronomap_bench::bt`]
//! measures, this prints).

use anyhow::Result;
use chronomap_bench::bt::{BtBench, default_cases};

use crate::cli::BenchBtArgs;
use crate::outln;
use crate::output::print_bench;

pub fn bt(args: &BenchBtArgs) -> Result<()> {
    let rows = chronomap_bench::bt::run(&default_cases(), args.repeats as usize)?;
    print_bench(args.json, &rows, |rows| print(rows, args.repeats))
}

fn print(rows: &[BtBench], repeats: u32) -> Result<()> {
    outln!(
        "BehaviorTree.CPP 4 XML read and checked (parse_bt_xml) against roxmltree's parse of the \
         same text, one thread, median of {repeats}"
    )?;
    outln!(
        "{:<40} {:>10} {:>9} {:>10} {:>13} {:>7} {:>8}",
        "case",
        "bytes",
        "nodes",
        "read [ms]",
        "roxmltree [ms]",
        "ratio",
        "MB/s"
    )?;
    for r in rows {
        outln!(
            "{:<40} {:>10} {:>9} {:>10.1} {:>13.1} {:>7.2} {:>8.1}",
            r.case,
            r.bytes,
            r.nodes,
            r.read_ms,
            r.roxmltree_ms,
            r.ratio,
            r.read_mb_per_s
        )?;
    }
    Ok(())
}
