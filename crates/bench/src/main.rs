//! The FreMEn benchmarks of [`chronomap_bench::fremen`] as markdown tables: every fast path is
//! timed against a baseline measured in the same run on the same machine, and the ratio is
//! printed (see BENCHMARKS.md).
//!
//! ```text
//! cargo run --release -p chronomap-bench -- [all|fft|observe|predict] [--quick]
//! ```

use std::path::Path;
use std::process::ExitCode;

use chronomap_bench::fremen::{self, FremenConfig};
use chronomap_core::Parallelism;

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
    println!(
        "build: release, rayon threads: {}\n",
        Parallelism::Rayon(0).tasks()
    );
    let config = FremenConfig {
        data: Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data"),
        quick,
    };
    let result = (|| -> Result<(), chronomap_bench::BenchError> {
        if matches!(which, "all" | "fft") {
            print_fft(&fremen::fft(&config)?);
        }
        if matches!(which, "all" | "observe") {
            print_observe(&fremen::observe(&config)?);
        }
        if matches!(which, "all" | "predict") {
            print_predict(&fremen::predict(&config)?);
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

fn print_fft(b: &fremen::FftBench) {
    println!(
        "## FFT FreMEn build ([Krajník 2017] §III-B) — tom door week at 2 Hz, {} samples, {} changes\n",
        b.samples, b.changes
    );
    println!(
        "Paper: 3.7 ms (FFTW, i7). Goal here: <= 2 ms. Every build below is checked lossless.\n"
    );
    println!("| what | order | time (ms) | ratio to chronomap build |");
    println!("|---|---|---|---|");
    for build in &b.builds {
        println!(
            "| chronomap build, periods >= 2 h (run-length spectrum) | {} | {:.3} | 1.0 |",
            build.order,
            build.seconds * 1e3
        );
    }
    println!(
        "| bare memory scan of the input (XOR of all bytes) | - | {:.3} | {:.2} |",
        b.scan_seconds * 1e3,
        b.ratio_scan
    );
    println!(
        "| same model, spectrum by real FFT (realfft) | 5 | {:.3} | {:.1} |",
        b.fft_seconds * 1e3,
        b.ratio_fft
    );
    println!(
        "| whole spectrum up to Nyquist by real FFT | 5 | {:.3} | {:.1} |",
        b.full_spectrum_seconds * 1e3,
        b.ratio_full_spectrum
    );
    println!(
        "| naive DFT of the same {} candidate bins (spectrum only) | - | {:.1} | {:.0} |",
        b.naive_dft_bins,
        b.naive_dft_seconds * 1e3,
        b.ratio_naive_dft
    );
    println!();
}

fn print_observe(b: &fremen::ObserveBench) {
    println!(
        "## FreMEn observe — greg door training tiled to {} observations, {} periods\n",
        b.observations, b.periods
    );
    println!("| what | time (ms) | observations x periods per second | speed-up vs naive |");
    println!("|---|---|---|---|");
    println!(
        "| naive: one sin_cos per observation and period, f64 sums | {:.1} | {:.3e} | 1.0 |",
        b.naive_seconds * 1e3,
        b.naive_rate
    );
    for (label, run) in [
        ("chronomap, sequential", &b.sequential),
        ("chronomap, all threads", &b.parallel),
    ] {
        println!(
            "| {label} (exact sums, harmonic recurrence) | {:.1} | {:.3e} | {:.1} |",
            run.seconds * 1e3,
            run.rate,
            run.speedup
        );
    }
    println!();
}

fn print_predict(b: &fremen::PredictBench) {
    println!(
        "## FreMEn predict — model trained on greg door, {} query times\n",
        b.times
    );
    println!("| order | times | chronomap (ns/prediction) | naive (ns/prediction) | speed-up |");
    println!("|---|---|---|---|---|");
    for row in &b.rows {
        println!(
            "| {} | {} | {:.1} | {:.1} | {:.1} |",
            row.order,
            row.times.label(),
            row.chronomap_ns,
            row.naive_ns,
            row.speedup
        );
    }
    println!();
}
