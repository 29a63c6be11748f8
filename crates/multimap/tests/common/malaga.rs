//! A few lines reading the bundled Málaga 2006 loop (scans and odometry increments), for the
//! tests and examples of this crate (the io crate has the full reader).

use std::io::Read;
use std::path::Path;

use chronomap_lidar::Scan2d;
use chronomap_multimap::se2::Pose2;

/// The xz-compressed text file at `path`.
fn read_xz(path: &Path) -> String {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut text = String::new();
    lzma_rust2::XzReader::new(std::io::BufReader::new(file), true)
        .read_to_string(&mut text)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text
}

/// The scans of `scans.txt.xz` (no-returns as `+inf`) and the sensor's pose on the robot.
pub fn scans(path: &Path) -> (Vec<Scan2d>, Pose2) {
    let mut mount = Pose2::IDENTITY;
    let scans = read_xz(path)
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.starts_with('#') && !l.trim().is_empty())
        .map(|(i, line)| {
            let f: Vec<f64> = line
                .split_whitespace()
                .map(|v| {
                    v.parse()
                        .unwrap_or_else(|e| panic!("line {}: {v}: {e}", i + 1))
                })
                .collect();
            let n = f[8] as usize;
            assert_eq!(f.len(), 9 + 2 * n, "line {}", i + 1);
            assert_eq!(f[2], 1.0, "line {}: right_to_left", i + 1);
            mount = Pose2::new(f[4], f[5], f[7]).unwrap();
            let ranges = (0..n)
                .map(|k| {
                    if f[9 + n + k] != 0.0 {
                        f[9 + k]
                    } else {
                        f64::INFINITY
                    }
                })
                .collect();
            Scan2d::new(f[0], -f[1] / 2.0, f[1] / 2.0, f[3], ranges)
                .unwrap_or_else(|e| panic!("line {}: {e}", i + 1))
        })
        .collect();
    (scans, mount)
}

/// The odometry increments of `odometry.txt.xz`, robot frame.
pub fn increments(path: &Path) -> Vec<Pose2> {
    read_xz(path)
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|line| {
            let f: Vec<f64> = line
                .split_whitespace()
                .map(|v| v.parse().unwrap())
                .collect();
            Pose2::new(f[1], f[2], f[3]).unwrap()
        })
        .collect()
}
