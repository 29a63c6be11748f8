//! The bundled ATC tracks read as the data README says.

use chronomap_io::{read_track_files, read_tracks};

fn data(name: &str) -> String {
    chronomap_testutil::data(&format!("atc_20121024_1hz/{name}"))
}

#[test]
fn the_ten_o_clock_file_has_every_row_in_time_order() {
    let ten = read_tracks(data("atc-1024-10_train.csv.xz")).unwrap();
    assert_eq!(ten.len(), 38_633);
    assert!(ten.windows(2).all(|w| w[0].t <= w[1].t));
    // 10:00 to 11:00 JST.
    assert_eq!(ten[0].t, 1_351_040_400.164);
    assert_eq!(ten.last().unwrap().t, 1_351_043_999.998);
    let (min_x, max_x) = ten
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), e| (a.min(e.x), b.max(e.x)));
    assert_eq!((min_x, max_x), (-40.862, 47.934));
}

#[test]
fn files_merge_in_time_order() {
    let both = read_track_files(&[
        data("atc-1024-20_train.csv.xz"),
        data("atc-1024-9_train.csv.xz"),
    ])
    .unwrap();
    assert_eq!(both.len(), 10_833 + 14_942);
    assert!(both.windows(2).all(|w| w[0].t <= w[1].t));
    assert_eq!(both[0].t, 1_351_038_020.969);
}
