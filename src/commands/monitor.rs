//! `chronomap monitor sim`: the fault-injection simulation of the system monitoring of
//! [Stüde 2024] §5.3 ([`chronomap_app_bt::monitor::simulate`]), printed as the intervention table
//! and the metrics of Tables 5.2 and 5.3.

use anyhow::Result;
use chronomap_app_bt::monitor::{SimSetup, simulate};

use crate::cli::MonitorSimArgs;
use crate::output::print_json;
use crate::{errln, out};

pub fn sim(args: &MonitorSimArgs) -> Result<()> {
    let setup = SimSetup {
        hours: args.hours,
        seed: args.seed,
        faults: args.faults.as_deref(),
        certain: args.certain,
        arbiter: args.arbiter.as_deref(),
    };
    let report = simulate(&setup, &mut |warning| errln!("warning: {warning}"))?;
    if args.json {
        return print_json(&report);
    }
    out!("{report}")?;
    Ok(())
}
