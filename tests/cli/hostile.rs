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
/// `x` and a newline), `copy NAME` (a file of the corpus, beside the generated ones), `fill
/// TEMPLATE CHARS NAME` (a corpus file with `@LONG@` replaced by CHARS `x`) or `mcap TOPIC
/// TYPE NAME` (an MCAP bag with a topic, and with TYPE > 0 a type name, of that many
/// characters: [`bool_mcap`]); `ply-random N NAME` is a binary PLY cloud of N points scattered
/// through a 20 m cube.
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
        ["fill", template, chars, name] => {
            // The corpus file `template` with `@LONG@` replaced by `chars` × `x`.
            let text = std::fs::read_to_string(corpus.join(template)).unwrap();
            let long = "x".repeat(chars.parse().unwrap());
            std::fs::write(out.join(name), text.replace("@LONG@", &long)).unwrap();
        }
        ["mcap", topic, ty, name] => {
            let (topic, ty): (usize, usize) = (topic.parse().unwrap(), ty.parse().unwrap());
            std::fs::write(out.join(name), bool_mcap(topic, ty)).unwrap();
        }
        ["mcap_fields", fields, name] => {
            std::fs::write(out.join(name), wide_mcap(fields.parse().unwrap())).unwrap();
        }
        ["gz_comments", mib, name] => {
            // `mib` gzip members, each 1 MiB of comment lines (1 KiB each) when decompressed.
            let line = [&b"#"[..], &[b'x'; 1022], b"\n"].concat();
            let mut member = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
            for _ in 0..1024 {
                std::io::Write::write_all(&mut member, &line).unwrap();
            }
            let member = member.finish().unwrap();
            let mut file = std::io::BufWriter::new(std::fs::File::create(out.join(name)).unwrap());
            for _ in 0..mib.parse::<usize>().unwrap() {
                std::io::Write::write_all(&mut file, &member).unwrap();
            }
            std::io::Write::flush(&mut file).unwrap();
        }
        ["mcap_nested", levels, n, name] => {
            let (levels, n) = (levels.parse().unwrap(), n.parse().unwrap());
            std::fs::write(out.join(name), nested_mcap(levels, n)).unwrap();
        }
        ["ply-random", n, name] => {
            // `n` points spread through a 20 m cube (binary float x, y, z; a fixed xorshift
            // sequence), so that almost every point keeps its own voxel on a fine grid.
            let n: u64 = n.parse().unwrap();
            let mut bytes = format!(
                "ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty float x\n\
                 property float y\nproperty float z\nend_header\n"
            )
            .into_bytes();
            let mut state = 0x9e37_79b9_7f4a_7c15u64;
            for _ in 0..3 * n {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let x = 20.0 * (state >> 40) as f32 / (1u64 << 24) as f32;
                bytes.extend_from_slice(&x.to_le_bytes());
            }
            std::fs::write(out.join(name), bytes).unwrap();
        }
        _ => panic!("unknown `make: {spec}`"),
    }
}

/// An MCAP file (header, schema, channel, `messages`, data end, footer; no chunks, CRCs or
/// summary) of one schema, `ty` in ROS 2 `definition`, on `topic`: each message its sequence
/// number, its log and publish time (ns) and its CDR bytes.
fn one_topic_mcap(
    ty: &str,
    definition: &str,
    topic: &str,
    messages: &[(u32, u64, &[u8])],
) -> Vec<u8> {
    fn string(out: &mut Vec<u8>, s: &str) {
        out.extend_from_slice(&(s.len() as u32).to_le_bytes());
        out.extend_from_slice(s.as_bytes());
    }
    fn record(out: &mut Vec<u8>, op: u8, body: &[u8]) {
        out.push(op);
        out.extend_from_slice(&(body.len() as u64).to_le_bytes());
        out.extend_from_slice(body);
    }
    const MAGIC: &[u8] = b"\x89MCAP0\r\n";
    let mut out = MAGIC.to_vec();
    let mut body = Vec::new();
    string(&mut body, "ros2");
    string(&mut body, "chronomap hostile corpus");
    record(&mut out, 0x01, &body);
    body.clear();
    body.extend_from_slice(&1u16.to_le_bytes());
    string(&mut body, ty);
    string(&mut body, "ros2msg");
    string(&mut body, definition);
    record(&mut out, 0x03, &body);
    body.clear();
    body.extend_from_slice(&1u16.to_le_bytes());
    body.extend_from_slice(&1u16.to_le_bytes());
    string(&mut body, topic);
    string(&mut body, "cdr");
    body.extend_from_slice(&0u32.to_le_bytes());
    record(&mut out, 0x04, &body);
    for &(sequence, ns, cdr) in messages {
        body.clear();
        body.extend_from_slice(&1u16.to_le_bytes());
        body.extend_from_slice(&sequence.to_le_bytes());
        body.extend_from_slice(&ns.to_le_bytes());
        body.extend_from_slice(&ns.to_le_bytes());
        body.extend_from_slice(cdr);
        record(&mut out, 0x05, &body);
    }
    record(&mut out, 0x0F, &0u32.to_le_bytes());
    record(&mut out, 0x02, &[0u8; 20]);
    out.extend_from_slice(MAGIC);
    out
}

/// An MCAP file ([`one_topic_mcap`]) whose one schema calls itself `std_msgs/msg/Bool` but is a
/// sequence of messages nested `levels` deep around one `bool`, with one message on `/deep` of
/// `n` such elements (one byte each on the wire).
fn nested_mcap(levels: usize, n: usize) -> Vec<u8> {
    let sep = "=".repeat(80);
    let mut text = String::from("N1[] items\n");
    for i in 1..levels {
        text.push_str(&format!("{sep}\nMSG: std_msgs/N{i}\nN{} x\n", i + 1));
    }
    text.push_str(&format!("{sep}\nMSG: std_msgs/N{levels}\nbool b\n"));
    let mut cdr = vec![0, 1, 0, 0];
    cdr.extend_from_slice(&(n as u32).to_le_bytes());
    cdr.resize(8 + n, 1);
    one_topic_mcap("std_msgs/msg/Bool", &text, "/deep", &[(0, 0, &cdr)])
}

/// An MCAP file ([`one_topic_mcap`]) whose one schema, `a/msg/Wide`, has `fields` fields `int8
/// f0` … and then `f0` once more, with one message on `/wide`.
fn wide_mcap(fields: usize) -> Vec<u8> {
    let mut text: String = (0..fields).map(|i| format!("int8 f{i}\n")).collect();
    text.push_str("int8 f0\n");
    one_topic_mcap("a/msg/Wide", &text, "/wide", &[(0, 0, &[0, 1, 0, 0, 0])])
}

/// A minimal MCAP file ([`one_topic_mcap`]) of three `std_msgs/msg/Bool` messages a minute
/// apart on the topic `/xxx…` of `topic` characters; with `ty` > 0, the schema's type name is
/// `std_msgs/msg/Bxxx…` of `ty` characters instead.
fn bool_mcap(topic: usize, ty: usize) -> Vec<u8> {
    let topic = format!("/{}", "x".repeat(topic.max(2) - 1));
    let ty = if ty == 0 {
        "std_msgs/msg/Bool".to_owned()
    } else {
        format!("std_msgs/msg/B{}", "x".repeat(ty.saturating_sub(14)))
    };
    let cdr: Vec<[u8; 8]> = (0..3).map(|i| [0, 1, 0, 0, i % 2, 0, 0, 0]).collect();
    let messages: Vec<(u32, u64, &[u8])> = (0..3u32)
        .map(|i| {
            let ns = (1_700_000_000 + 60 * u64::from(i)) * 1_000_000_000;
            (i, ns, &cdr[i as usize][..])
        })
        .collect();
    one_topic_mcap(&ty, "bool data", &topic, &messages)
}

/// The chronomap under test: this build's, or the one `CHRONOMAP_HOSTILE_BIN` names, to show
/// which cases an older build fails (`CHRONOMAP_HOSTILE_BIN=old/chronomap cargo test --test
/// cli hostile` lists them).
fn binary() -> PathBuf {
    std::env::var_os("CHRONOMAP_HOSTILE_BIN")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_BIN_EXE_chronomap")))
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
    let mut child = Command::new(binary())
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
