//! `chronomap export parquet`: a service store's observations and predictions as Parquet
//! ([`chronomap_serve::export`] reads and writes, this prints).

use anyhow::Result;
use chronomap_serve::export::{ExportError, ExportSpec, PredictionGrid, export_parquet};
use chronomap_serve::startup::StoreLocation;

use crate::cli::ExportParquetArgs;
use crate::out;
use crate::output::{ProgressBar, print_json, usage};

/// `chronomap export parquet`.
pub fn parquet(args: &ExportParquetArgs) -> Result<()> {
    let grid = match (args.from, args.to) {
        (Some(from), Some(to)) if !args.no_predictions => {
            Some(PredictionGrid::new(from, to, args.step).map_err(flag_error)?)
        }
        _ => None,
    };
    let store = match &args.postgres {
        Some(config) => StoreLocation::Postgres {
            config: config.clone(),
            schema: args.postgres_schema.clone(),
        },
        None => StoreLocation::Redb {
            data: args
                .data
                .clone()
                .expect("clap requires --data without --postgres"),
        },
    };
    let spec = ExportSpec {
        store,
        output: args.output.clone(),
        force: args.force,
        prefix: args.prefix.clone(),
        grid,
    };
    let report = {
        let bar = ProgressBar::new();
        export_parquet(&spec, &bar).map_err(flag_error)?
    };
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    Ok(out!("{}", report.text())?)
}

/// A prediction grid the flags ask for that cannot be written is a usage error (exit code 2).
fn flag_error(error: ExportError) -> anyhow::Error {
    if error.is_usage() {
        usage(error.to_string())
    } else {
        error.into()
    }
}
