//! The hostile-input corpus (`tests/hostile/`): every case is a command run on a file written
//! to break it, with the exit code and the error it must give. No case may panic, abort, print
//! more than [`MAX_STDERR_BYTES`] of errors, or run longer than [`TIME_LIMIT`]; the format of
//! `tests/hostile/cases.txt` is described at its top; `cases_*.txt` beside it hold more cases in
//! the same format, one file per family of readers.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::common::scratch;

/// Most bytes of stderr a refused input may produce (a bad line is quoted, not echoed whole).
const MAX_STDERR_BYTES: usize = 64 * 1024;
/// Longest a case may run before it counts as hanging.
const TIME_LIMIT: Duration = Duration::from_secs(120);

/// One case of `cases.txt`.
#[derive(Debug, Default)]
struct Case {
    name: String,
    line: usize,
    make: Vec<String>,
    run: String,
    exit: i32,
    stderr: Vec<String>,
    stdout: Vec<String>,
}

fn parse_cases(text: &str) -> Vec<Case> {
    let mut cases: Vec<Case> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            cases.push(Case {
                name: name.to_owned(),
                line: i + 1,
                exit: -1,
                ..Case::default()
            });
            continue;
        }
        let case = cases
            .last_mut()
            .unwrap_or_else(|| panic!("cases.txt:{}: a key before the first [case]", i + 1));
        let (key, value) = line
            .split_once(':')
            .unwrap_or_else(|| panic!("cases.txt:{}: expected `key: value`", i + 1));
        let value = value.trim().to_owned();
        match key.trim() {
            "make" => case.make.push(value),
            "run" => case.run = value,
            "exit" => case.exit = value.parse().expect("exit code"),
            "stderr" => case.stderr.push(value),
            "stdout" => case.stdout.push(value),
            other => panic!("cases.txt:{}: unknown key {other:?}", i + 1),
        }
    }
    for case in &cases {
        assert!(
            !case.run.is_empty() && case.exit >= 0,
            "cases.txt:{}: [{}] needs `run:` and `exit:`",
            case.line,
            case.name
        );
    }
    cases
}

/// Writes a generated input into `out`: `png W H NAME` (an all-zero 8-bit grey PNG, small
/// when compressed but W × H bytes when decoded), `line BYTES NAME` (one line of that many
/// `x` and a newline) or `copy NAME` (a file of the corpus, beside the generated ones).
fn make(spec: &str, corpus: &Path, out: &Path) {
    let words: Vec<&str> = spec.split_whitespace().collect();
    match words.as_slice() {
        ["png", w, h, name] => {
            let (w, h): (u32, u32) = (w.parse().unwrap(), h.parse().unwrap());
            let file = std::fs::File::create(out.join(name)).unwrap();
            let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), w, h);
            encoder.set_color(png::ColorType::Grayscale);
            encoder.set_depth(png::BitDepth::Eight);
            encoder.set_compression(png::Compression::Fast);
            let mut writer = encoder.write_header().unwrap();
            let mut stream = writer.stream_writer().unwrap();
            let row = vec![0u8; w as usize];
            for _ in 0..h {
                std::io::Write::write_all(&mut stream, &row).unwrap();
            }
            stream.finish().unwrap();
        }
        ["copy", name] => {
            std::fs::copy(corpus.join(name), out.join(name)).unwrap();
        }
        ["line", bytes, name] => {
            let mut text = vec![b'x'; bytes.parse().unwrap()];
            text.push(b'\n');
            std::fs::write(out.join(name), text).unwrap();
        }
        _ => panic!("unknown `make: {spec}`"),
    }
}

/// Runs one case; returns what is wrong with its outcome, if anything.
fn check(case: &Case, corpus: &Path, out: &Path) -> Option<String> {
    for spec in &case.make {
        make(spec, corpus, out);
    }
    let out_text = out.display().to_string();
    let args: Vec<String> = case
        .run
        .split_whitespace()
        .map(|w| w.replace("OUT", &out_text))
        .collect();
    let mut child = Command::new(env!("CARGO_BIN_EXE_chronomap"))
        .args(&args)
        .current_dir(corpus)
        .env("RUST_BACKTRACE", "0")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start chronomap");
    // Read both pipes on threads (a full pipe would block the child), bounded in memory.
    let take = |mut pipe: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            Read::by_ref(&mut pipe)
                .take(4 * MAX_STDERR_BYTES as u64)
                .read_to_end(&mut bytes)
                .ok();
            std::io::copy(&mut pipe, &mut std::io::sink()).ok();
            bytes
        })
    };
    let stdout = take(Box::new(child.stdout.take().unwrap()));
    let stderr = take(Box::new(child.stderr.take().unwrap()));
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if started.elapsed() > TIME_LIMIT {
            child.kill().ok();
            child.wait().ok();
            return Some(format!("ran longer than {TIME_LIMIT:?}"));
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let stdout = String::from_utf8_lossy(&stdout.join().unwrap()).into_owned();
    let stderr_bytes = stderr.join().unwrap();
    let stderr = String::from_utf8_lossy(&stderr_bytes).into_owned();
    let short = |s: &str| s.chars().take(600).collect::<String>();
    if stderr.contains("panicked") || status.code().is_none() {
        return Some(format!("crashed ({status}): {}", short(&stderr)));
    }
    if status.code() != Some(case.exit) {
        return Some(format!(
            "exit code {:?}, expected {}; stderr: {}",
            status.code(),
            case.exit,
            short(&stderr)
        ));
    }
    if stderr_bytes.len() > MAX_STDERR_BYTES {
        return Some(format!(
            "{} bytes on stderr (at most {MAX_STDERR_BYTES})",
            stderr_bytes.len()
        ));
    }
    for part in &case.stderr {
        if !stderr.contains(part.as_str()) {
            return Some(format!("stderr lacks {part:?}: {}", short(&stderr)));
        }
    }
    for part in &case.stdout {
        if !stdout.contains(part.as_str()) {
            return Some(format!("stdout lacks {part:?}: {}", short(&stdout)));
        }
    }
    None
}

#[test]
fn every_hostile_input_of_the_corpus_gets_its_error() {
    let corpus = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/hostile");
    // `cases.txt` and one `cases_<surface>.txt` per reader family (bags, clouds, outputs, …).
    let mut files: Vec<PathBuf> = std::fs::read_dir(&corpus)
        .unwrap()
        .map(|entry| entry.unwrap().path())
        .filter(|path| {
            let name = path.file_name().unwrap().to_string_lossy();
            name.starts_with("cases") && name.ends_with(".txt")
        })
        .collect();
    files.sort();
    let cases: Vec<(String, Case)> = files
        .iter()
        .flat_map(|path| {
            let file = path.file_name().unwrap().to_string_lossy().into_owned();
            parse_cases(&std::fs::read_to_string(path).unwrap())
                .into_iter()
                .map(move |case| (file.clone(), case))
        })
        .collect();
    assert!(cases.len() >= 20, "only {} cases", cases.len());
    let root = scratch("hostile_corpus");
    let failures: Vec<String> = cases
        .iter()
        .enumerate()
        .filter_map(|(i, (file, case))| {
            let out = root.join(format!("case_{i}"));
            std::fs::create_dir_all(&out).unwrap();
            check(case, &corpus, &out)
                .map(|why| format!("{file}:{} [{}]: {why}", case.line, case.name))
        })
        .collect();
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}
