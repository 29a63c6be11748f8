//! `chronomap grid` end to end: frames from ROS/Nav2 map files and per-cell series, predicted
//! maps that our map reader (Nav2 semantics) reads back, and clear errors for bad frames.

use std::path::{Path, PathBuf};
use std::process::Output;

use crate::common::{assert_mentions, chronomap, json, scratch, stdout};
use chronomap_grid::AnyGrid;
use chronomap_io::navmap::{LoadSemantics, MapMode, SaveOptions, load_map, save_map};
use chronomap_io::read_grid_file;
use chronomap_spatial::OccupancyMap;

/// A 4×3 map: a wall column (x = 0), a door (cell 5) closed from 18:00 to 8:00, an unseen
/// corner (cell 11), the rest free.
fn door_map(hour: u64) -> OccupancyMap {
    let mut data = vec![0i8; 12];
    for y in 0..3 {
        data[y * 4] = 100;
    }
    data[5] = if (8..18).contains(&hour) { 0 } else { 100 };
    data[11] = -1;
    OccupancyMap {
        width: 4,
        height: 3,
        resolution: 0.05,
        origin: [-1.5, 2.25, 0.0],
        data,
    }
}

/// Writes two weeks of hourly maps and the frame list; returns the list's path.
fn write_frames(dir: &Path) -> PathBuf {
    let mut list = String::from("# time map\n");
    let start = 1_451_865_600u64; // Monday 2016-01-04 00:00 UTC
    for h in 0..14 * 24u64 {
        let name = format!("maps/frame_{h:04}");
        save_map(
            &dir.join(&name),
            &door_map(h % 24),
            &SaveOptions {
                free_thresh: 0.196,
                ..SaveOptions::default()
            },
        )
        .unwrap();
        list.push_str(&format!("{} {name}.yaml\n", start + 3600 * h));
    }
    let path = dir.join("frames.txt");
    std::fs::write(&path, list).unwrap();
    path
}

/// Runs `chronomap grid build --frames LIST -o OUTPUT EXTRA...`.
fn build_from_frames(list: &Path, output: &str, extra: &[&str]) -> Output {
    let list = list.display().to_string();
    let args = [
        &["grid", "build", "--frames", &list, "-o", output][..],
        extra,
    ]
    .concat();
    chronomap(&args)
}

#[test]
fn predicted_maps_are_nav2_maps_that_read_back() {
    let dir = scratch("grid_predict");
    std::fs::create_dir_all(dir.join("maps")).unwrap();
    let list = write_frames(&dir);
    let grid = dir.join("door.cmg").display().to_string();
    stdout(&build_from_frames(&list, &grid, &["--order", "4"]));
    let AnyGrid::State(state) = read_grid_file(&grid).unwrap() else {
        panic!("not a learning state")
    };
    assert_eq!(state.frames(), 14 * 24);

    // 3:00 and 13:00 a week after the data: the door closed, then open (the old spelling
    // `--out` of the output is still accepted).
    for (hour, door, output) in [(3u64, 100i8, "-o"), (13, 0, "--out")] {
        let t = 1_451_865_600 + (21 * 24 + hour) * 3600;
        let base = dir.join(format!("predicted/at_{hour}"));
        let out = chronomap(&[
            "grid",
            "predict",
            &grid,
            "--time",
            &t.to_string(),
            output,
            &base.with_extension("yaml").display().to_string(),
            "--order",
            "4",
        ]);
        stdout(&out);
        let yaml = std::fs::read_to_string(base.with_extension("yaml")).unwrap();
        assert!(yaml.starts_with("# map predicted by chronomap"), "{yaml}");
        assert!(yaml.contains(&format!("t = {t}")), "{yaml}");
        assert!(yaml.contains("image: at_"), "{yaml}");
        let map = load_map(&base.with_extension("yaml"), LoadSemantics::Nav2).unwrap();
        assert_eq!((map.width, map.height, map.resolution), (4, 3, 0.05));
        assert_eq!(map.origin, [-1.5, 2.25, 0.0]);
        let mut expected = door_map(hour).data;
        expected[5] = door;
        assert_eq!(map.data, expected, "{hour}:00");
    }

    // A scale-mode mask for a costmap filter.
    let base = dir.join("predicted/mask");
    let out = chronomap(&[
        "grid",
        "predict",
        &grid,
        "--time",
        "2016-01-25T00:00:00Z",
        "-o",
        &base.display().to_string(),
        "--mode",
        "scale",
        "--json",
    ]);
    stdout(&out);
    assert!(base.with_extension("png").exists());
    let yaml = std::fs::read_to_string(base.with_extension("yaml")).unwrap();
    assert!(yaml.contains("mode: scale"), "{yaml}");
    // The JSON of the prediction: 2016-01-25 00:00 is 1453680000, at night: the wall and the
    // door occupied, the corner unknown.
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["time"], 1_453_680_000.0);
    assert_eq!(
        (json["width"].as_u64(), json["height"].as_u64()),
        (Some(4), Some(3))
    );
    assert_eq!(
        (json["occupied"].as_u64(), json["unknown"].as_u64()),
        (Some(4), Some(1))
    );
    assert_eq!(json["free"], 7);
    assert_eq!(json["mode"], "scale");
    assert_eq!(
        json["image"],
        base.with_extension("png").display().to_string()
    );

    let out = chronomap(&["grid", "stats", &grid]);
    let text = String::from_utf8(out.stdout).unwrap();
    assert_mentions(&text, &["336", "compression"]);
    let out = chronomap(&["grid", "stats", &grid, "--json"]);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["kind"], "grid-state");
    assert_eq!(json["frames"]["count"], 336);
    assert_eq!(json["geometry"]["cells"], 12);
    assert_eq!(json["cell_observations"], 12.0 * 336.0);
    let bytes = json["bytes"].as_u64().unwrap();
    assert_eq!(bytes, std::fs::metadata(&grid).unwrap().len());
    let ratio = json["compression_ratio"].as_f64().unwrap();
    assert_eq!(ratio, 12.0 * 336.0 / (8.0 * bytes as f64));
    assert!(
        text.contains(&format!("in {bytes} bytes = 1:{ratio:.0}")),
        "{text}"
    );
    // The door and the unseen corner changed or needed storage.
    let cells = json["contents"]["dynamic_cells"].as_u64().unwrap();
    assert!(
        text.contains(&format!("{cells} cells with storage")),
        "{text}"
    );

    // Maps for two times given comma-separated; the old `-o` still names the picture.
    for flag in ["--plot", "-o"] {
        let png = dir.join(format!("maps{flag}.png"));
        stdout(&chronomap(&[
            "grid",
            "plot",
            &grid,
            "--time",
            "1453680000,2016-01-25T13:00Z",
            flag,
            &png.display().to_string(),
        ]));
        assert!(std::fs::metadata(&png).unwrap().len() > 1000);
    }
    let _ = MapMode::Trinary;
}

#[test]
fn bad_frames_give_clear_errors() {
    let dir = scratch("grid_bad");
    std::fs::create_dir_all(dir.join("maps")).unwrap();
    let opts = SaveOptions {
        free_thresh: 0.196,
        ..SaveOptions::default()
    };
    save_map(&dir.join("maps/a"), &door_map(3), &opts).unwrap();
    let mut wide = door_map(3);
    wide.width = 6;
    wide.data = vec![0; 18];
    save_map(&dir.join("maps/wide"), &wide, &opts).unwrap();
    let mut blind = door_map(3);
    blind.data = vec![-1; 12];
    save_map(&dir.join("maps/blind"), &blind, &opts).unwrap();
    save_map(&dir.join("maps/cut"), &door_map(3), &opts).unwrap();
    let pgm = std::fs::read(dir.join("maps/cut.pgm")).unwrap();
    std::fs::write(dir.join("maps/cut.pgm"), &pgm[..pgm.len() - 5]).unwrap();

    let cases = [
        (
            "backwards",
            "100 maps/a.yaml\n50 maps/a.yaml\n",
            "frames.txt:2",
            "earlier",
        ),
        (
            "dimensions",
            "100 maps/a.yaml\n200 maps/wide.yaml\n",
            "frames.txt:2",
            "6x3 but the first map is 4x3",
        ),
        (
            "unknown_only",
            "100 maps/a.yaml\n200 maps/blind.yaml\n",
            "frames.txt:2",
            "observes no cell",
        ),
        (
            "truncated",
            "100 maps/a.yaml\n200 maps/cut.yaml\n",
            "cut.pgm",
            "trunc",
        ),
        (
            "not_a_time",
            "100 maps/a.yaml\nsoon maps/a.yaml\n",
            "frames.txt:2",
            "not a number",
        ),
    ];
    for (name, list, where_, what) in cases {
        let list_path = dir.join(format!("{name}/frames.txt"));
        std::fs::create_dir_all(list_path.parent().unwrap()).unwrap();
        let list = list.replace("maps/", "../maps/");
        std::fs::write(&list_path, list).unwrap();
        let out = build_from_frames(&list_path, &dir.join("x.cmg").display().to_string(), &[]);
        assert_eq!(out.status.code(), Some(1), "{name} accepted");
        let err = String::from_utf8_lossy(&out.stderr).to_lowercase();
        assert!(
            err.contains(&where_.to_lowercase()) && err.contains(&what.to_lowercase()),
            "{name}: {err}"
        );
        assert!(!err.contains("panicked"), "{name}: {err}");
    }
}

#[test]
fn symbolic_maps_from_cell_series_and_the_synthetic_office() {
    let dir = scratch("grid_series");
    let files: Vec<String> = (0..3)
        .map(|r| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join(format!("data/aruba_rooms_1min/presence_minutes_{r}.txt.xz"))
                .display()
                .to_string()
        })
        .collect();
    let out_path = dir.join("flat.cmg").display().to_string();
    let out = chronomap(&[
        "grid",
        "build",
        "--cell-series",
        &files.join(","),
        "--store",
        "lossy",
        "--order",
        "auto",
        "-o",
        &out_path,
    ]);
    stdout(&out);
    assert!(matches!(
        read_grid_file(&out_path).unwrap(),
        AnyGrid::Lossy(_)
    ));

    let office = dir.join("office.cmg").display().to_string();
    let args = [
        "grid",
        "build",
        "--synthetic",
        "--cells",
        "6400",
        "--days",
        "14",
        "--errors",
        "--store",
        "lossless",
        "-o",
        &office,
    ];
    let out = chronomap(&args);
    stdout(&out);
    let text = String::from_utf8(out.stdout).unwrap();
    assert_mentions(&text, &["static (order 0)", "FreMEn auto"]);
    let AnyGrid::Lossless(lossless) = read_grid_file(&office).unwrap() else {
        panic!("not lossless")
    };
    assert_eq!(lossless.frames(), 14 * 17_280);
    // The same build on one thread, as JSON: the error table's numbers are the text's.
    let mut one_thread = args.to_vec();
    one_thread.extend(["--threads", "1", "--json"]);
    let json = json(&chronomap(&one_thread));
    assert_eq!(json["frames"], 14 * 17_280);
    assert_eq!(json["kind"], "grid-lossless");
    let errors = &json["errors"];
    let rows = errors["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 7);
    assert_eq!(rows[0]["model"], "static (order 0)");
    assert_eq!(rows[6]["order"], "auto");
    let changed = errors["changed_cells"].as_u64().unwrap();
    assert!(
        text.contains(&format!("Errors over the {changed} cells that changed")),
        "{text}"
    );
    for row in rows {
        let line = text
            .lines()
            .find(|l| l.starts_with(row["model"].as_str().unwrap()))
            .unwrap();
        for key in ["estimation_error", "prediction_error"] {
            let percent = format!("{:.2} %", 100.0 * row[key].as_f64().unwrap());
            assert!(line.contains(&percent), "{key} {percent}: {line}");
        }
        // Predictions and errors do not depend on the threads; the static error of the
        // office is about 6 % ([Krajník 2017] §VI).
        if row["order"] == 0 {
            let e = row["estimation_error"].as_f64().unwrap();
            assert!((0.04..0.08).contains(&e), "{e}");
        }
    }
}
