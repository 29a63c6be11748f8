//! The README's library example: learn an office door's rhythm from ten weeks of minutes and
//! predict it a week later. Run with `cargo run --release --example door`.

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // README:BEGIN
    use chronomap_core::{FremenModel, TemporalModel};
    use chronomap_io::read_pairs;

    let door = read_pairs("data/door_greg_2016/training_data.txt.xz")?; // "t value" lines
    let mut model = FremenModel::with_order(2); // mean + the 2 strongest periodic processes
    model.observe(&door.times, &door.values)?; // any times (unix s), states in [0, 1]
    let monday_1pm = 1_458_565_200.0; // 2016-03-21 13:00 UTC, a week after the data
    let (p, h) = (model.predict(monday_1pm), model.entropy(monday_1pm));
    println!("P(open) = {p:.2}, uncertainty {h:.2} bit");
    for c in model.components() {
        let hours = c.period_secs / 3600.0;
        println!("{hours} h: amplitude {:.3}", 2.0 * c.amplitude);
    }
    // README:END
    Ok(())
}
