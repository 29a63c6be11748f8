//! Door passages, link-point candidates and maps on the real Málaga 2006 loop ([Stüde 2024]
//! §3.3.2): `cargo run --release -p chronomap-multimap --example malaga_doors`.

use chronomap_io::laser_text::{read_odometry, read_scans};
use chronomap_multimap::door::{DoorParams, detect_door_posts};
use chronomap_multimap::mapper::{Mapper, MapperParams};
use chronomap_multimap::se2::Pose2;

fn main() {
    let data =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/malaga_laser_2006");
    // The io crate's reader: no-returns as +inf, every scan counter-clockwise (the Málaga
    // scans are right to left already, so their beam order is kept).
    let lasers = read_scans(data.join("scans.txt.xz")).unwrap_or_else(|e| panic!("{e}"));
    let s = lasers[0].sensor;
    let mount = Pose2::new(s.x, s.y, s.yaw).unwrap();
    let scans: Vec<_> = lasers.into_iter().map(|l| l.scan).collect();
    let increments: Vec<Pose2> = read_odometry(data.join("odometry.txt.xz"))
        .unwrap_or_else(|e| panic!("{e}"))
        .iter()
        .map(|o| Pose2::new(o.dx, o.dy, o.dyaw).unwrap())
        .collect();
    println!(
        "{} scans, {} odometry increments, sensor at {mount:?}",
        scans.len(),
        increments.len()
    );
    let params = MapperParams {
        door: DoorParams {
            sensor: mount,
            ..DoorParams::default()
        },
        ..MapperParams::default()
    };
    let mut mapper = Mapper::new(params).unwrap();
    let (mut fronts, mut c3) = (0, 0);
    for (k, scan) in scans.iter().enumerate() {
        let inc = if k == 0 {
            Pose2::IDENTITY
        } else {
            increments[k - 1]
        };
        let r = mapper.step(scan, &inc).unwrap();
        fronts += usize::from(!r.detector.front.is_empty());
        c3 += usize::from(r.detector.c3);
        if let Some(p) = r.passage {
            let odom = mapper.odometry_pose();
            let b = p.bbox.unwrap();
            println!(
                "scan {k:3} t={:6.2} s: passage, criteria {:?}, door width {:.2} m at ({:.2}, {:.2}) (odometry frame), robot at ({:.2}, {:.2}), new map {} box {:.1} × {:.1} m → {:?}",
                p.time - scans[0].time,
                p.criteria,
                p.door.width(),
                p.door.center()[0],
                p.door.center()[1],
                odom.x,
                odom.y,
                r.new_map.unwrap(),
                b.width(),
                b.height(),
                mapper.graph().maps()[r.new_map.unwrap()].config,
            );
        }
        for c in &r.candidates {
            let cand = mapper.graph().candidates()[*c];
            let d = r.detector.front[0];
            println!(
                "scan {k:3}: candidate {c} in map {} (door width {:.2} m, centre ({:.2}, {:.2}) odometry frame)",
                cand.map,
                d.width(),
                d.center()[0],
                d.center()[1]
            );
        }
    }
    // Door-post pairs at any bearing, and what the (C3) threshold sees.
    let mut any = Vec::new();
    for (k, scan) in scans.iter().enumerate() {
        let pairs = detect_door_posts(scan, &params.door).unwrap();
        if !pairs.is_empty() {
            let c = pairs[0].center();
            any.push(format!(
                "{k}: {} pair(s), first {:.2} m wide at bearing {:.0}°",
                pairs.len(),
                pairs[0].width(),
                c[1].atan2(c[0]).to_degrees()
            ));
        }
    }
    println!(
        "scans with door-post pairs at any bearing: {} {:?}",
        any.len(),
        any
    );
    let g = mapper.graph();
    println!(
        "scans with door posts ahead: {fronts}; scans with a (C3) box change: {c3}; maps {}, link points {}, candidates {}",
        g.maps().len(),
        g.links().len(),
        g.candidates().len()
    );
    let o = mapper.odometry_pose();
    println!(
        "odometry end pose ({:.2}, {:.2}, {:.3} rad)",
        o.x, o.y, o.theta
    );
}
