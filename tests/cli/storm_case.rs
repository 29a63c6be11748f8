//! The files of one case of the Storm cross-check of `chronomap_topo::mdp` and the values that
//! `tests/oracle/storm_check.py` expects of them. Shared by the `storm_witham` test and the
//! `mdp_storm_cases` example (which includes this file by its path).

use std::error::Error;
use std::path::{Path, PathBuf};

use chronomap_topo::mdp::{NavigationMdp, Solution, SparseMdp, product_drn, restricted_drn};
use serde_json::{Value, json};

/// Writes into `dir` the product `mdp` solved by `sol` (`NAME.drn`), its restricted product
/// (`NAME.restricted.drn`), the Navigation MDP `nav` from `start` in PRISM (`NAME.nm`) and its
/// co-safe LTL `property` (`NAME.props`); adds what storm_check.py expects of the first three
/// files to `expected`. The paths of those three files.
pub fn write_case(
    dir: &Path,
    name: &str,
    (nav, start): (&NavigationMdp, usize),
    mdp: &SparseMdp,
    sol: &Solution,
    property: &str,
    expected: &mut impl Extend<(String, Value)>,
) -> Result<[PathBuf; 3], Box<dyn Error>> {
    let write = |file: String, contents: String| -> Result<PathBuf, Box<dyn Error>> {
        let path = dir.join(file);
        std::fs::write(&path, contents)?;
        Ok(path)
    };
    let files = [
        write(format!("{name}.drn"), product_drn(mdp, sol)?)?,
        write(format!("{name}.restricted.drn"), restricted_drn(mdp, sol)?)?,
        write(format!("{name}.nm"), nav.to_prism(start)?)?,
    ];
    write(format!("{name}.props"), format!("{property}\n"))?;
    // The DRN file gives every state without a choice a self-loop `absorb`.
    let absorbing = (0..mdp.state_count())
        .filter(|&s| mdp.choices(s).is_empty())
        .count();
    expected.extend([
        (
            format!("{name}.drn"),
            json!({
                "states": mdp.state_count(),
                "choices": mdp.choice_count() + absorbing,
                "initial": sol.initial,
                "pmax": sol.pmax,
                "pmax_initial": sol.pmax_initial,
            }),
        ),
        (
            format!("{name}.restricted.drn"),
            json!({
                "pmax": sol.pmax,
                "rmin": sol.cost,
                "pmax_initial": sol.pmax_initial,
                "rmin_initial": sol.cost_initial,
            }),
        ),
        (
            format!("{name}.nm"),
            json!({ "properties": { property: sol.pmax_initial } }),
        ),
    ]);
    Ok(files)
}
