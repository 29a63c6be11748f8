//! The grid part of `chronomap demo`: a real symbolic map (the Aruba apartment) and the
//! synthetic office, with predicted maps written as Nav2 maps and drawn side by side
//! (`chronomap_app::demo` runs the studies, this prints and writes).

use std::path::Path;

use anyhow::Result;
use chronomap_app::demo::{aruba_text, office_study};
use chronomap_core::TimeSeries;
use chronomap_io::navmap::{SaveOptions, save_map};
use chronomap_plot::{MapImage, render_maps_png};
use chronomap_spatial::OccupancyMap;

use crate::bundled;
use crate::format::time;
use crate::outln;
use crate::output::ProgressBar;

/// Prints section 4 of the demo; writes maps into `out` if given. Returns the files written.
pub fn run(out: Option<&Path>) -> Result<Vec<String>> {
    let rooms: Vec<TimeSeries> = bundled::ARUBA_ROOMS
        .iter()
        .map(|r| r.pairs())
        .collect::<Result<_>>()?;
    outln!("{}", aruba_text(&rooms, &ProgressBar::new())?)?;
    let office = office_study(&ProgressBar::new())?;
    outln!("{}", office.text())?;
    let Some(out) = out else {
        return Ok(Vec::new());
    };
    let g = office.grid.geometry();
    let (w, h) = (g.width, g.height);
    let mut written = Vec::new();
    let mut images = Vec::new();
    for (t, layer, values) in office.monday_maps() {
        let origin = [g.origin[0], g.origin[1], 0.0];
        let map = OccupancyMap::from_probabilities(w, h, g.resolution as f32, origin, &values);
        let hour = ((t % 86_400.0) / 3600.0) as u32;
        let saved = save_map(
            &out.join(format!("office_{hour:02}00")),
            &map,
            &SaveOptions {
                comment: Some(format!(
                    "map predicted by chronomap for t = {t} ({}), layer {layer}",
                    time(t)
                )),
                free_thresh: 0.196,
                ..SaveOptions::default()
            },
        )?;
        written.push(format!("{}  (Nav2 map, {})", saved.yaml.display(), time(t)));
        images.push(MapImage {
            title: format!("office layer {layer} predicted for {}", time(t)),
            width: w,
            height: h,
            values,
        });
    }
    let png = out.join("office_maps.png");
    render_maps_png(&images, &png, 9)?;
    written.push(format!(
        "{}  (the two predicted maps side by side)",
        png.display()
    ));
    Ok(written)
}
