//! A small writer of BehaviorTree.CPP v4 XML for a synthesised person search tree
//! ([`chronomap_core::psbt`], seed 002 Fig. 5.9): `Sequence(Fallback(actions…), MoveTo x₀)`.
//!
//! ```
//! use chronomap_core::psbt::path::CellPath;
//! use chronomap_core::psbt::{PersonSearchTree, Phase, Step};
//! use chronomap_io::psbt_xml::psbt_to_xml;
//!
//! let tree = PersonSearchTree {
//!     start: [1.0, 2.0],
//!     phases: vec![
//!         Phase {
//!             step: Step::Search { from: [1.0, 2.0], to: [5.25, 2.75], path: CellPath { cells: vec![], length: 4.5 } },
//!             return_length_m: 4.5,
//!         },
//!         Phase { step: Step::Wait { at: [5.25, 2.75], cell: 0, timeout_s: 30.0 }, return_length_m: 4.5 },
//!     ],
//! };
//! let xml = psbt_to_xml(&tree);
//! assert!(xml.starts_with(r#"<root BTCPP_format="4" main_tree_to_execute="PersonSearch">"#));
//! assert!(xml.contains(r#"<Action ID="SearchPath" from="1.00;2.00" to="5.25;2.75"/>"#));
//! assert!(xml.contains(r#"<Action ID="WaitAt" x="5.25" y="2.75" timeout_s="30.0"/>"#));
//! assert!(xml.contains(r#"<Action ID="MoveTo" x="1.00" y="2.00"/>"#));
//! ```
//!
//! # Format
//! Points are `x;y` in metres (two decimals), the separator BehaviorTree.CPP's
//! `convertFromString` splits on; `timeout_s` has one decimal. The search tree is the main
//! tree `PersonSearch`; a caller's tree runs it where help is needed (Fig. 5.9's
//! "Symbiotic error" condition is the caller's).

use std::fmt::Write;

use chronomap_core::psbt::{PersonSearchTree, Step};

/// The tree as BehaviorTree.CPP v4 XML (two-space indentation, a final newline).
pub fn psbt_to_xml(tree: &PersonSearchTree) -> String {
    let point = |p: [f64; 2]| format!("{:.2};{:.2}", p[0], p[1]);
    let mut xml = String::new();
    xml.push_str("<root BTCPP_format=\"4\" main_tree_to_execute=\"PersonSearch\">\n");
    xml.push_str("  <BehaviorTree ID=\"PersonSearch\">\n");
    xml.push_str("    <Sequence>\n");
    xml.push_str("      <Fallback>\n");
    for phase in &tree.phases {
        // Writing to a String cannot fail.
        let _ = match &phase.step {
            Step::Search { from, to, .. } => writeln!(
                xml,
                "        <Action ID=\"SearchPath\" from=\"{}\" to=\"{}\"/>",
                point(*from),
                point(*to)
            ),
            Step::Wait { at, timeout_s, .. } => writeln!(
                xml,
                "        <Action ID=\"WaitAt\" x=\"{:.2}\" y=\"{:.2}\" timeout_s=\"{:.1}\"/>",
                at[0], at[1], timeout_s
            ),
        };
    }
    xml.push_str("      </Fallback>\n");
    let _ = writeln!(
        xml,
        "      <Action ID=\"MoveTo\" x=\"{:.2}\" y=\"{:.2}\"/>",
        tree.start[0], tree.start[1]
    );
    xml.push_str("    </Sequence>\n");
    xml.push_str("  </BehaviorTree>\n");
    xml.push_str("</root>\n");
    xml
}
