//! The topological part of `chronomap demo` ([Fentanes 2015]): edge models of the Witham Wharf
//! deployment, their score on the later weeks, and a now-or-later table through the lab door
//! ([`chronomap_app::topo::witham_demo`]).

use std::path::Path;

use anyhow::Result;
use chronomap_plot::render_heatmap_png;

use crate::output::ProgressBar;
use crate::{bundled, out, outln};

/// Prints section 5 of the demo; writes the heat map into `out` if given. Returns the files
/// written.
pub fn run(out: Option<&Path>) -> Result<Vec<String>> {
    outln!(
        "\n5. Now or later? Navigation on a topological map whose edges know time ([Fentanes 2015]).\n"
    )?;
    let demo = {
        let bar = ProgressBar::new();
        chronomap_app::topo::witham_demo(&bundled::witham_edges()?, &bar)?
    };
    out!("{demo}")?;
    let mut written = Vec::new();
    if let Some(dir) = out {
        let path = dir.join("witham_now_or_later.png");
        render_heatmap_png(&demo.table.heatmap(), &path)?;
        written.push(path.display().to_string());
    }
    Ok(written)
}
