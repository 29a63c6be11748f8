//! Commands whose output pipe is closed (`chronomap … | true`, `… 2>&1 | true`) end quietly
//! with exit 0 on a closed stdout, and never panic on a closed stderr.

use std::process::{Command, Stdio};

use crate::common::{chronomap, closed_pipe, data, repo, scratch, stdout};

/// Runs `args` with stdout and stderr both pipes that are closed before anything is read: the
/// exit code, which must not be the 101 of a panic.
fn both_closed(args: &[&str]) -> Option<i32> {
    let child = Command::new(env!("CARGO_BIN_EXE_chronomap"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut child = child;
    drop(child.stdout.take());
    drop(child.stderr.take());
    child.wait().unwrap().code()
}

#[test]
fn inspect_psbt_grid_and_topo_into_a_closed_pipe_exit_0_without_a_panic() {
    let dir = scratch("closed_pipes");
    let model = dir.join("door.cmm").display().to_string();
    let train = data("door_greg_2016/training_data.txt.xz");
    stdout(&chronomap(&[
        "fit", "--train", &train, "--model", "fremen:2", "-o", &model,
    ]));
    // Grid frames: three 4 x 3 maps.
    let maps = dir.join("maps");
    std::fs::create_dir_all(&maps).unwrap();
    let mut list = String::new();
    for f in 0..3u8 {
        let mut pgm = b"P5\n4 3\n255\n".to_vec();
        pgm.extend((0..12u8).map(|c| if (c + f) % 3 == 0 { 0 } else { 254 }));
        std::fs::write(maps.join(format!("f{f}.pgm")), pgm).unwrap();
        std::fs::write(
            maps.join(format!("f{f}.yaml")),
            format!(
                "image: f{f}.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n\
                 occupied_thresh: 0.65\nfree_thresh: 0.196\n"
            ),
        )
        .unwrap();
        list.push_str(&format!("{} maps/f{f}.yaml\n", 100 * (u32::from(f) + 1)));
    }
    let frames = dir.join("frames.txt");
    std::fs::write(&frames, list).unwrap();
    let (frames, grid) = (
        frames.display().to_string(),
        dir.join("g.cmg").display().to_string(),
    );
    let edges = data("witham_topological_nav/edges");
    let topo = dir.join("w.cmt").display().to_string();
    let map = repo("data/atc_copa_map_grid/atc_map.yaml");
    let tracks = repo("data/atc_20121024_1hz/atc-1024-14_train.csv.xz");
    let commands: [&[&str]; 6] = [
        &["inspect", &model],
        &["inspect", &model, "--json"],
        &["grid", "build", "--frames", &frames, "-o", &grid],
        &["topo", "fit", "--edges", &edges, "-o", &topo],
        &[
            "psbt",
            "--map",
            &map,
            "--activity",
            &tracks,
            "--from=21.25,-18.25",
            "--time",
            "2012-10-24T05:30Z",
        ],
        &["grid", "stats", &grid],
    ];
    for args in commands {
        let (_, err) = closed_pipe(args, 0);
        assert!(!err.contains("error"), "{args:?}: {err}");
    }
    // A failing command whose stderr is closed too: exit 1, not a panic's 101.
    let missing = dir.join("missing.cmm").display().to_string();
    assert_eq!(both_closed(&["grid", "stats", &missing]), Some(1));
    assert_eq!(both_closed(&["inspect", &model]), Some(0));
}
