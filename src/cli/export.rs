//! Flags of `chronomap export`.

#[allow(unused_imports)]
use super::*;

pub(super) const EXPORT_PARQUET_HELP: &str = "\
Examples:
  chronomap export parquet --data chronomap-data -o history \\
      --from 2026-11-01T00:00Z --to 2026-12-01T00:00Z --step 3600
  chronomap export parquet --postgres 'host=db.lab dbname=lab' --prefix robot1/ -o robot1 \\
      --no-predictions
  duckdb -c \"SELECT namespace, avg(value) FROM 'history/observations.parquet' GROUP BY 1\"

Writes OUTPUT/observations.parquet (namespace, model_id, time, time_s, value, seq: every
observation of the models the store holds, since each was last created, in log order) and
OUTPUT/predictions.parquet (namespace, model_id, time, time_s, probability, value: each model
at --from, --from + --step, ... up to --to). Columns and how to read them: docs/parquet.md.
A redb store (--data) can be exported only while no service runs on it; --postgres reads
beside running services (it takes no lock) and exports the log up to where it ended when the
export began.";

/// `chronomap export`: a store's history as files for analysis tools.
#[derive(Debug, Subcommand)]
pub enum ExportCommand {
    /// Observations and predictions of a service store's models as Apache Parquet tables
    /// (for DuckDB, DataFusion, pandas, Polars).
    #[command(after_help = EXPORT_PARQUET_HELP)]
    Parquet(ExportParquetArgs),
}

/// `chronomap export parquet`.
#[derive(Debug, Args)]
pub struct ExportParquetArgs {
    /// Data directory of a `chronomap serve` whose store is DATA/chronomap.redb (stop the
    /// service first: redb lets one process open the file).
    #[arg(
        long,
        required_unless_present = "postgres",
        conflicts_with = "postgres"
    )]
    pub data: Option<PathBuf>,
    /// Read the store from PostgreSQL instead: a libpq connection string or postgresql://
    /// URL. Takes no lock; safe beside running services.
    #[arg(long)]
    pub postgres: Option<String>,
    /// PostgreSQL schema of the store.
    #[arg(long, default_value = "chronomap", requires = "postgres")]
    pub postgres_schema: String,
    /// Directory to write observations.parquet and predictions.parquet into (created if
    /// missing).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Replace existing observations.parquet / predictions.parquet in OUTPUT.
    #[arg(long)]
    pub force: bool,
    /// Only models whose id starts with this text (a robot: `robot1/`).
    #[arg(long)]
    pub prefix: Option<String>,
    /// First time of the prediction grid: seconds or an ISO 8601 date-time (UTC unless it has
    /// an offset). Required unless --no-predictions.
    #[arg(long, value_parser = parse_time, requires = "to",
          required_unless_present = "no_predictions")]
    pub from: Option<f64>,
    /// Last time of the prediction grid (included when it falls on a step).
    #[arg(long, value_parser = parse_time, requires = "from")]
    pub to: Option<f64>,
    /// Seconds between the times of the prediction grid.
    #[arg(long, default_value_t = 3600.0, value_parser = parse_positive)]
    pub step: f64,
    /// Write observations.parquet only.
    #[arg(long, conflicts_with_all = ["from", "to"])]
    pub no_predictions: bool,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}
