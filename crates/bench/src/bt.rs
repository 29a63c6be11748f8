//! Reading and checking BehaviorTree.CPP 4 XML (`chronomap bt check`) on generated trees that
//! made the reader quadratic before (100,000 siblings, 1,000-level nesting, attribute-heavy
//! nodes), timed against parsing the same text with roxmltree alone (the XML parser the reader
//! is built on: the least any reader of the file must do) in the same run.

use std::fmt::Write as _;
use std::time::Instant;

use chronomap_bt::Registry;
use chronomap_io::bt_xml::{BtXmlError, parse_bt_xml};
use roxmltree::{Document, ParsingOptions};
use serde::Serialize;

/// One generated document.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BtCase {
    /// What it is (`siblings`, `deep`, `attributes`).
    pub name: String,
    /// The XML text.
    pub text: String,
    /// The number of tree nodes.
    pub nodes: usize,
}

/// `count` leaves under one `Sequence`, one a line, with instance names, and explicit-form
/// leaves of 100 custom IDs among them (their models are inferred).
pub fn siblings(count: usize) -> BtCase {
    let mut text = String::from(
        "<root BTCPP_format=\"4\" main_tree_to_execute=\"Wide\">\n<BehaviorTree ID=\"Wide\">\n<Sequence>\n",
    );
    for i in 0..count {
        if i % 2 == 0 {
            let _ = writeln!(text, "  <AlwaysSuccess name=\"step{i}\"/>");
        } else {
            let _ = writeln!(
                text,
                "  <Action ID=\"Task{}\" name=\"step{i}\" target=\"{{goal}}\"/>",
                i % 100
            );
        }
    }
    text.push_str("</Sequence>\n</BehaviorTree>\n</root>\n");
    BtCase {
        name: format!("{count} siblings"),
        text,
        nodes: count + 1,
    }
}

/// `trees` trees, each `levels` deep (decorators around a leaf), one element a line.
pub fn deep(trees: usize, levels: usize) -> BtCase {
    let mut text = String::from("<root BTCPP_format=\"4\" main_tree_to_execute=\"Deep0\">\n");
    for t in 0..trees {
        let _ = writeln!(text, "<BehaviorTree ID=\"Deep{t}\">");
        for l in 0..levels - 1 {
            if l % 2 == 0 {
                text.push_str("<Inverter>\n");
            } else {
                text.push_str("<ForceSuccess>\n");
            }
        }
        text.push_str("<AlwaysFailure/>\n");
        for l in (0..levels - 1).rev() {
            if l % 2 == 0 {
                text.push_str("</Inverter>\n");
            } else {
                text.push_str("</ForceSuccess>\n");
            }
        }
        text.push_str("</BehaviorTree>\n");
    }
    text.push_str("</root>\n");
    BtCase {
        name: format!("{trees} trees {levels} deep"),
        text,
        nodes: trees * levels,
    }
}

/// `count` declared custom actions with `ports` ports each, used once each with every port set,
/// all on one line (so that a position search from the line start would be quadratic).
pub fn attributes(count: usize, ports: usize) -> BtCase {
    let mut text = String::from(
        "<root BTCPP_format=\"4\" main_tree_to_execute=\"Busy\"><BehaviorTree ID=\"Busy\"><Sequence>",
    );
    for i in 0..count {
        let _ = write!(text, "<Act{i}");
        for p in 0..ports {
            let _ = write!(text, " p{p}=\"{}\"", i + p);
        }
        text.push_str("/>");
    }
    text.push_str("</Sequence></BehaviorTree><TreeNodesModel>");
    for i in 0..count {
        let _ = write!(text, "<Action ID=\"Act{i}\">");
        for p in 0..ports {
            let _ = write!(text, "<input_port name=\"p{p}\" type=\"int\"/>");
        }
        text.push_str("</Action>");
    }
    text.push_str("</TreeNodesModel></root>\n");
    BtCase {
        name: format!("{count} nodes x {ports} attributes, one line"),
        text,
        nodes: count + 1,
    }
}

/// The default cases: 100,000 siblings, 100 trees 1,000 deep, 2,000 nodes with 50 attributes.
pub fn default_cases() -> Vec<BtCase> {
    vec![
        siblings(20_000),
        siblings(100_000),
        deep(100, 1000),
        attributes(2_000, 50),
    ]
}

/// The timings of one case.
#[derive(Clone, Debug, Serialize)]
pub struct BtBench {
    /// The case.
    pub case: String,
    /// Its size in bytes.
    pub bytes: usize,
    /// Its tree nodes.
    pub nodes: usize,
    /// Median time of `parse_bt_xml` (parse, read, infer models, validate, positions), ms.
    pub read_ms: f64,
    /// Median time of parsing the text with roxmltree alone, ms.
    pub roxmltree_ms: f64,
    /// `read_ms / roxmltree_ms`.
    pub ratio: f64,
    /// Read throughput, MB/s.
    pub read_mb_per_s: f64,
}

/// Times each case `repeats` times (at least 1) and reports the medians.
///
/// # Errors
/// The reader's error if a case does not load (a bug of the generator or the reader).
pub fn run(cases: &[BtCase], repeats: usize) -> Result<Vec<BtBench>, BtXmlError> {
    let repeats = repeats.max(1);
    let mut out = Vec::new();
    for case in cases {
        let mut read = Vec::new();
        let mut baseline = Vec::new();
        for _ in 0..repeats {
            let start = Instant::now();
            let options = ParsingOptions {
                allow_dtd: false,
                ..ParsingOptions::default()
            };
            // Errors show in the reader's run below.
            if let Ok(doc) = Document::parse_with_options(&case.text, options) {
                std::hint::black_box(doc.descendants().count());
            }
            baseline.push(start.elapsed().as_secs_f64() * 1e3);

            let start = Instant::now();
            let loaded = parse_bt_xml(&case.name, &case.text, &Registry::new())?;
            std::hint::black_box(&loaded);
            read.push(start.elapsed().as_secs_f64() * 1e3);
            drop(loaded);
        }
        let read_ms = crate::median(&read);
        let roxmltree_ms = crate::median(&baseline);
        out.push(BtBench {
            case: case.name.clone(),
            bytes: case.text.len(),
            nodes: case.nodes,
            read_ms,
            roxmltree_ms,
            ratio: read_ms / roxmltree_ms,
            read_mb_per_s: case.text.len() as f64 / 1e6 / (read_ms / 1e3),
        });
    }
    Ok(out)
}

/// The measurements of [`run`] as `chronomap bench bt` prints them (`repeats`: the runs each
/// median is of).
pub fn text(rows: &[BtBench], repeats: u32) -> String {
    let mut out = format!(
        "BehaviorTree.CPP 4 XML read and checked (parse_bt_xml) against roxmltree's parse of the \
         same text, one thread, median of {repeats}\n"
    );
    let _ = writeln!(
        out,
        "{:<40} {:>10} {:>9} {:>10} {:>13} {:>7} {:>8}",
        "case", "bytes", "nodes", "read [ms]", "roxmltree [ms]", "ratio", "MB/s"
    );
    for r in rows {
        let _ = writeln!(
            out,
            "{:<40} {:>10} {:>9} {:>10.1} {:>13.1} {:>7.2} {:>8.1}",
            r.case, r.bytes, r.nodes, r.read_ms, r.roxmltree_ms, r.ratio, r.read_mb_per_s
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generated_cases_load_with_their_node_counts() {
        for case in [siblings(10), deep(2, 5), attributes(3, 4)] {
            let loaded = parse_bt_xml(&case.name, &case.text, &Registry::new()).unwrap();
            let nodes: usize = loaded
                .document
                .trees
                .iter()
                .map(|t| {
                    let mut n = 0;
                    t.root.walk(&mut |_, _| n += 1);
                    n
                })
                .sum();
            assert_eq!(nodes, case.nodes, "{}", case.name);
        }
        let rows = run(&[siblings(100)], 1).unwrap();
        assert!(rows[0].ratio > 0.0);
    }
}
