//! The CASAS Aruba apartment as a 10-cell symbolic map through the grid container: trained on
//! twelve weeks, it must predict the four held-back weeks better than a static map.

use chronomap_core::FremenConfig;
use chronomap_core::TimeSeries;
use chronomap_grid::{FremenGrid, GridConfig, GridGeometry, OrderChoice};
use chronomap_io::read_pairs;
use chronomap_testutil::data_path;

fn rooms() -> Vec<TimeSeries> {
    (0..10)
        .map(|r| {
            let path = data_path(&format!("aruba_rooms_1min/presence_minutes_{r}.txt.xz"));
            read_pairs(path).unwrap()
        })
        .collect()
}

/// Brier score and binary error of a fitted grid over frames `[from, to)`.
fn scores(
    grid: &FremenGrid,
    orders: OrderChoice,
    rooms: &[TimeSeries],
    from: usize,
    to: usize,
) -> (f64, f64) {
    let fitted = grid.fitted(orders, chronomap_core::Parallelism::Rayon(0));
    let (mut brier, mut binary, mut n) = (0.0, 0.0, 0.0);
    for f in from..to {
        let p = fitted.predict_map(rooms[0].times[f]);
        for (room, &q) in rooms.iter().zip(&p) {
            let (s, q) = (room.values[f], f64::from(q));
            brier += (q - s) * (q - s);
            binary += f64::from(u8::from((q > 0.5) != (s == 1.0)));
            n += 1.0;
        }
    }
    (brier / n, binary / n)
}

#[test]
fn fremen_grid_predicts_held_back_weeks_of_the_apartment_better_than_a_static_map() {
    let rooms = rooms();
    assert_eq!(rooms[0].len(), 16 * 7 * 1440);
    let train = 12 * 7 * 1440;
    let geometry = GridGeometry::planar(10, 1, 1.0, [0.0, 0.0]).unwrap();
    let config = GridConfig {
        fremen: FremenConfig::with_order(2),
        keep_history: true,
    };
    let mut grid = FremenGrid::new(geometry, config).unwrap();
    let mut trained = None;
    for f in 0..train {
        if f == train * 3 / 4 {
            trained = Some(grid.clone());
        }
        // Exactly one room holds the resident each minute.
        let frame: Vec<i8> = rooms
            .iter()
            .map(|r| if r.values[f] == 1.0 { 100 } else { 0 })
            .collect();
        assert_eq!(frame.iter().filter(|&&v| v == 100).count(), 1);
        grid.observe_occupancy(rooms[0].times[f], &frame).unwrap();
    }
    let end = rooms[0].len();
    let (static_brier, static_binary) = scores(&grid, OrderChoice::Fixed(0), &rooms, train, end);
    let (fremen_brier, fremen_binary) = scores(&grid, OrderChoice::Fixed(2), &rooms, train, end);
    let orders = grid
        .select_cell_orders(&trained.unwrap(), 5, chronomap_core::Parallelism::Rayon(0))
        .unwrap();
    let (auto_brier, auto_binary) = scores(&grid, OrderChoice::PerCell(orders), &rooms, train, end);
    // Measured: static 0.0752 / 10.0 %, order 2 0.0535 / 7.1 %, auto 0.0535 / 7.0 %.
    assert!(
        (static_brier - 0.0752).abs() < 0.001,
        "static Brier {static_brier}"
    );
    assert!(
        fremen_brier < 0.8 * static_brier,
        "order 2 Brier {fremen_brier} vs static {static_brier}"
    );
    assert!(
        fremen_binary < 0.8 * static_binary,
        "order 2 binary {fremen_binary} vs {static_binary}"
    );
    assert!(
        auto_brier < 0.8 * static_brier && auto_binary < 0.8 * static_binary,
        "auto {auto_brier} {auto_binary}"
    );
}
