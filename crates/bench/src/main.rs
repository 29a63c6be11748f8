//! Benchmarks of chronomap: every fast path is timed against a baseline measured in the
//! same run on the same machine, and the ratio is printed (see BENCHMARKS.md).
//!
//! ```text
//! cargo run --release -p chronomap-bench -- [all|fft|observe|predict] [--quick]
//! ```

use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use chronomap_core::fft::{FftFremen, FftFremenConfig, SpectrumMethod, edges_of};
use chronomap_core::naive::{naive_dft, naive_fremen_predict, naive_spectrum};
use chronomap_core::{FremenModel, Ordered, Parallelism, TemporalModel};
use chronomap_io::{TimeSeries, read_pairs, read_test_set};

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data")
}

/// Median wall time in seconds of `runs` calls after one warm-up call.
fn time<T>(runs: usize, mut f: impl FnMut() -> T) -> f64 {
    black_box(f());
    let mut samples: Vec<f64> = (0..runs.max(1))
        .map(|_| {
            let start = Instant::now();
            black_box(f());
            start.elapsed().as_secs_f64()
        })
        .collect();
    samples.sort_by(f64::total_cmp);
    samples[samples.len() / 2]
}

fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|info| {
            info.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!("{cpu}, {threads} hardware threads")
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let quick = args.iter().any(|a| a == "--quick");
    let which = args
        .iter()
        .find(|a| !a.starts_with("--"))
        .map_or("all", String::as_str);
    if !matches!(which, "all" | "fft" | "observe" | "predict") {
        eprintln!("usage: chronomap-bench [all|fft|observe|predict] [--quick]");
        return ExitCode::from(2);
    }
    println!("# chronomap benchmarks\n");
    println!("machine: {}", machine());
    println!("build: release, rayon threads: {}\n", rayon_threads());
    let result = (|| -> Result<(), Box<dyn std::error::Error>> {
        if matches!(which, "all" | "fft") {
            bench_fft(quick)?;
        }
        if matches!(which, "all" | "observe") {
            bench_observe(quick)?;
        }
        if matches!(which, "all" | "predict") {
            bench_predict(quick)?;
        }
        Ok(())
    })();
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

fn rayon_threads() -> usize {
    Parallelism::Rayon(0).tasks()
}

/// FFT FreMEn model build on the tom door week at 2 Hz (1,209,600 samples), the setting of
/// seed 001 §V ("3.7 ms on an i7 with FFTW").
fn bench_fft(quick: bool) -> Result<(), Box<dyn std::error::Error>> {
    let dir = data_dir().join("door_tom_2013/sec");
    let week = read_test_set(
        dir.join("test_times_0.txt.xz"),
        dir.join("test_data_0.txt.xz"),
    )?;
    // The paper subsampled the 30 Hz camera stream to 2 Hz; the published data are at 1 Hz,
    // so each second is repeated twice to get the paper's 1,209,600 samples.
    let samples: Vec<u8> = week
        .values
        .iter()
        .flat_map(|&v| [v as u8, v as u8])
        .collect();
    let n = samples.len();
    let runs = if quick { 5 } else { 31 };
    println!(
        "## FFT FreMEn build (seed 001 §III-B) — tom door week at 2 Hz, {n} samples, {} changes\n",
        edges_of(&samples)?.len()
    );
    println!(
        "Paper: 3.7 ms (FFTW, i7). Goal here: <= 2 ms. Every build below is checked lossless.\n"
    );
    println!("| what | order | time (ms) | ratio to chronomap build |");
    println!("|---|---|---|---|");

    // The floor: reading every input byte once (a vectorised XOR reduction).
    let scan = time(runs, || samples.iter().fold(0u8, |a, &b| a ^ b));
    let mut chronomap_ms = Vec::new();
    for order in [2usize, 5, 10] {
        let config = FftFremenConfig::with_order(order);
        let model = FftFremen::build(0.0, 0.5, &samples, config)?;
        assert_eq!(model.reconstruct(), samples, "build must be lossless");
        let t = time(runs, || {
            FftFremen::build(0.0, 0.5, &samples, config).expect("valid")
        });
        chronomap_ms.push((order, t));
        println!(
            "| chronomap build, periods >= 2 h (run-length spectrum) | {order} | {:.3} | 1.0 |",
            t * 1e3
        );
    }
    let base = chronomap_ms[1].1;
    println!(
        "| bare memory scan of the input (XOR of all bytes) | - | {:.3} | {:.2} |",
        scan * 1e3,
        scan / base
    );

    let fft_config = FftFremenConfig::with_order(5);
    let fft = time(runs.min(7), || {
        FftFremen::build_with(0.0, 0.5, &samples, fft_config, SpectrumMethod::Fft).expect("valid")
    });
    println!(
        "| same model, spectrum by real FFT (realfft) | 5 | {:.3} | {:.1} |",
        fft * 1e3,
        fft / base
    );
    let full = FftFremenConfig {
        order: 5,
        shortest_period_secs: None,
    };
    let full_model = FftFremen::build_with(0.0, 0.5, &samples, full, SpectrumMethod::Fft)?;
    assert_eq!(full_model.reconstruct(), samples);
    let full_t = time(runs.min(7), || {
        FftFremen::build_with(0.0, 0.5, &samples, full, SpectrumMethod::Fft).expect("valid")
    });
    println!(
        "| whole spectrum up to Nyquist by real FFT | 5 | {:.3} | {:.1} |",
        full_t * 1e3,
        full_t / base
    );
    let bins = 84;
    let signal: Vec<f64> = samples.iter().map(|&s| f64::from(s)).collect();
    let naive = time(1, || naive_dft(&signal, bins + 1));
    println!(
        "| naive DFT of the same 84 candidate bins (spectrum only) | - | {:.1} | {:.0} |",
        naive * 1e3,
        naive / base
    );
    println!();
    Ok(())
}

/// Greg door training data (10 weeks at 1 min) tiled to ~1 M observations.
fn greg_series(copies: usize) -> Result<TimeSeries, Box<dyn std::error::Error>> {
    let train = read_pairs(data_dir().join("door_greg_2016/training_data.txt.xz"))?;
    let span = train.times.last().unwrap() - train.times[0] + 60.0;
    let mut series = TimeSeries {
        times: Vec::new(),
        values: Vec::new(),
    };
    for copy in 0..copies {
        series
            .times
            .extend(train.times.iter().map(|t| t + copy as f64 * span));
        series.values.extend_from_slice(&train.values);
    }
    Ok(series)
}

/// FreMEn observe throughput: exact incremental spectrum vs the direct O(N·K) transform.
fn bench_observe(quick: bool) -> Result<(), Box<dyn std::error::Error>> {
    let series = greg_series(if quick { 2 } else { 10 })?;
    let n = series.times.len();
    let periods = FremenModel::with_order(0).config().periods.periods();
    let k = periods.len();
    let runs = if quick { 3 } else { 7 };
    println!("## FreMEn observe — greg door training tiled to {n} observations, {k} periods\n");
    println!("| what | time (ms) | observations x periods per second | speed-up vs naive |");
    println!("|---|---|---|---|");
    let naive = time(1, || {
        naive_spectrum(&series.times, &series.values, &periods)
    });
    let rate = |t: f64| (n * k) as f64 / t;
    println!(
        "| naive: one sin_cos per observation and period, f64 sums | {:.1} | {:.3e} | 1.0 |",
        naive * 1e3,
        rate(naive)
    );
    for (label, par) in [
        ("chronomap, sequential", Parallelism::Sequential),
        ("chronomap, all threads", Parallelism::Rayon(0)),
    ] {
        let t = time(runs, || {
            let mut m = FremenModel::with_order(4);
            m.observe_par(&series.times, &series.values, par)
                .expect("valid");
            m
        });
        println!(
            "| {label} (exact sums, harmonic recurrence) | {:.1} | {:.3e} | {:.1} |",
            t * 1e3,
            rate(t),
            naive / t
        );
    }
    println!();
    Ok(())
}

/// FreMEn predict throughput over evenly spaced and irregular times vs direct evaluation.
fn bench_predict(quick: bool) -> Result<(), Box<dyn std::error::Error>> {
    let train = read_pairs(data_dir().join("door_greg_2016/training_data.txt.xz"))?;
    let start = train.times.last().unwrap() + 60.0;
    let count = if quick { 20_160 } else { 201_600 };
    let even: Vec<f64> = (0..count).map(|i| start + 60.0 * i as f64).collect();
    let irregular: Vec<f64> = (0..count)
        .map(|i| start + 60.0 * i as f64 + ((i * 7919) % 53) as f64)
        .collect();
    let runs = if quick { 3 } else { 11 };
    println!("## FreMEn predict — model trained on greg door, {count} query times\n");
    println!("| order | times | chronomap (ns/prediction) | naive (ns/prediction) | speed-up |");
    println!("|---|---|---|---|---|");
    for order in [4usize, 20] {
        let mut model = FremenModel::with_order(order);
        model.observe(&train.times, &train.values)?;
        let periods = model.config().periods.periods();
        let (mean, gammas) = naive_spectrum(&train.times, &train.values, &periods);
        let chosen: Vec<usize> = model
            .components()
            .iter()
            .map(|c| {
                periods
                    .iter()
                    .position(|&p| p == c.period_secs)
                    .expect("period")
            })
            .collect();
        assert_eq!(model.order(), chosen.len());
        for (label, times) in [("evenly spaced", &even), ("irregular", &irregular)] {
            let fast = time(runs, || model.predict_many(times));
            let naive = time(runs.min(3), || {
                times
                    .iter()
                    .map(|&t| naive_fremen_predict(mean, &gammas, &periods, &chosen, t))
                    .collect::<Vec<f64>>()
            });
            let per = |t: f64| t / times.len() as f64 * 1e9;
            println!(
                "| {order} | {label} | {:.1} | {:.1} | {:.1} |",
                per(fast),
                per(naive),
                naive / fast
            );
        }
    }
    println!();
    Ok(())
}
