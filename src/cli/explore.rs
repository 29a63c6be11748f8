//! Flags of `chronomap explore`.

#[allow(unused_imports)]
use super::*;

pub(super) const EXPLORE_HELP: &str = "\
Examples:
  chronomap explore --dataset aruba --data data/aruba_rooms_1min --ratio 0.5
  chronomap explore --dataset brayford --data data/brayford_week --ratio 0.5 --json
  chronomap explore --dataset aruba --data data/aruba_rooms_1min \\
      --plot-sweep docs/img/exploration_sweep.png --plot-behaviour docs/img/exploration_behaviour.png";

/// Datasets `explore` reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DatasetArg {
    /// CASAS Aruba apartment: presence_minutes_R.txt[.xz] ("t value", one per minute).
    Aruba,
    /// Brayford office: presence_L.txt[.xz] (one value per 10-minute slot).
    Brayford,
}

/// `chronomap explore`.
#[derive(Debug, Args)]
pub struct ExploreArgs {
    /// Which dataset format the directory holds.
    #[arg(long, value_enum)]
    pub dataset: DatasetArg,
    /// The dataset's directory.
    #[arg(long)]
    pub data: PathBuf,
    /// Exploration ratio e: the fraction of 10-minute slots spent observing.
    #[arg(long, default_value_t = 0.5, value_parser = parse_ratio)]
    pub ratio: f64,
    /// Seed of every random choice (runs are repeatable).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Explore only the first N days.
    #[arg(long)]
    pub days: Option<usize>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Also draw the exploration-ratio sweep ([Santos 2017] Fig. 5) into this PNG.
    #[arg(long, alias = "sweep")]
    pub plot_sweep: Option<PathBuf>,
    /// Also draw the behaviour of the first days ([Santos 2017] Fig. 6) into this PNG.
    #[arg(long, alias = "behaviour")]
    pub plot_behaviour: Option<PathBuf>,
}

pub(super) fn parse_ratio(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(e) if e > 0.0 && e <= 1.0 => Ok(e),
        _ => Err(format!("{text:?} is not an exploration ratio in (0, 1]")),
    }
}
