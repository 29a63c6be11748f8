//! A synthesised person search tree ([`chronomap_psbt`], [Stüde 2024] Fig. 5.9) as a
//! BehaviorTree.CPP v4 document: `Sequence(Fallback(actions…), MoveTo x₀)`, written by the
//! canonical writer of [`crate::bt_xml`] with a `<TreeNodesModel>` of its three actions, so
//! that the file is self-describing (Groot2 shows the ports) and reads back with
//! [`crate::bt_xml::parse_bt_xml`].
//!
//! ```
//! use chronomap_psbt::path::CellPath;
//! use chronomap_psbt::{PersonSearchTree, Phase, Step};
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
//! assert!(xml.contains(r#"<root BTCPP_format="4" main_tree_to_execute="PersonSearch">"#));
//! assert!(xml.contains(r#"<SearchPath from="1.00;2.00" to="5.25;2.75"/>"#));
//! assert!(xml.contains(r#"<WaitAt x="5.25" y="2.75" timeout_s="30.0"/>"#));
//! assert!(xml.contains(r#"<MoveTo x="1.00" y="2.00"/>"#));
//! assert!(xml.contains(r#"<Action ID="WaitAt">"#)); // its model
//! ```
//!
//! # Format
//! Points are `x;y` in metres (two decimals), the separator BehaviorTree.CPP's
//! `convertFromString` splits on; `timeout_s` has one decimal. The search tree is the main
//! tree `PersonSearch`; a caller's tree runs it where help is needed (Fig. 5.9's
//! "Symbiotic error" condition is the caller's).

use chronomap_bt::{BtDocument, NodeCategory, NodeDef, NodeModel, PortSpec, TreeDef};
use chronomap_psbt::{PersonSearchTree, Step};

use crate::bt_xml::encode_bt_xml;

/// The ID of the tree.
pub const PSBT_TREE_ID: &str = "PersonSearch";

/// The tree as a BehaviorTree.CPP v4 document, with the models of its actions.
pub fn psbt_document(tree: &PersonSearchTree) -> BtDocument {
    let point = |p: [f64; 2]| format!("{:.2};{:.2}", p[0], p[1]);
    let mut fallback = NodeDef::control("Fallback");
    for phase in &tree.phases {
        fallback = fallback.child(match &phase.step {
            Step::Search { from, to, .. } => NodeDef::action("SearchPath")
                .port("from", &point(*from))
                .port("to", &point(*to)),
            Step::Wait { at, timeout_s, .. } => NodeDef::action("WaitAt")
                .port("x", &format!("{:.2}", at[0]))
                .port("y", &format!("{:.2}", at[1]))
                .port("timeout_s", &format!("{timeout_s:.1}")),
        });
    }
    let move_back = NodeDef::action("MoveTo")
        .port("x", &format!("{:.2}", tree.start[0]))
        .port("y", &format!("{:.2}", tree.start[1]));
    let root = NodeDef::control("Sequence")
        .child(fallback)
        .child(move_back);
    let mut doc = BtDocument::single(TreeDef::new(PSBT_TREE_ID, root));
    let metres = |name: &str, what: &str| PortSpec::input(name).typed("double").described(what);
    doc.node_models = vec![
        NodeModel::new(NodeCategory::Action, "SearchPath")
            .port(
                PortSpec::input("from")
                    .described("start of the search path, x;y in metres (eq. 5.13)"),
            )
            .port(PortSpec::input("to").described("end of the search path, x;y in metres")),
        NodeModel::new(NodeCategory::Action, "WaitAt")
            .port(metres("x", "where to wait, metres"))
            .port(metres("y", "where to wait, metres"))
            .port(metres(
                "timeout_s",
                "give up after this many seconds (T' of eq. 5.11)",
            )),
        NodeModel::new(NodeCategory::Action, "MoveTo")
            .port(metres("x", "the help location, metres"))
            .port(metres("y", "the help location, metres")),
    ];
    doc
}

/// The tree as BehaviorTree.CPP v4 XML (canonical form of [`encode_bt_xml`]).
pub fn psbt_to_xml(tree: &PersonSearchTree) -> String {
    encode_bt_xml(&psbt_document(tree))
        .expect("the person search tree uses only plain port names, which are always writable")
}

#[cfg(test)]
mod tests {
    use chronomap_bt::Registry;
    use chronomap_psbt::path::CellPath;
    use chronomap_psbt::{PersonSearchTree, Phase, Step};

    use super::{psbt_document, psbt_to_xml};
    use crate::bt_xml::parse_bt_xml;

    /// The written tree reads back, with no registered leaves (its own models declare them),
    /// as the same document, and without warnings.
    #[test]
    fn the_written_tree_reads_back_as_the_same_document() {
        let tree = PersonSearchTree {
            start: [-10.0, 5.5],
            phases: vec![
                Phase {
                    step: Step::Wait {
                        at: [-10.0, 5.5],
                        cell: 3,
                        timeout_s: 12.25,
                    },
                    return_length_m: 0.0,
                },
                Phase {
                    step: Step::Search {
                        from: [-10.0, 5.5],
                        to: [20.125, -3.0],
                        path: CellPath {
                            cells: vec![1, 2],
                            length: 31.0,
                        },
                    },
                    return_length_m: 31.0,
                },
            ],
        };
        let xml = psbt_to_xml(&tree);
        let read = parse_bt_xml("psbt.xml", &xml, &Registry::new()).unwrap();
        assert!(read.warnings.is_empty(), "{:?}", read.warnings);
        assert_eq!(read.document, psbt_document(&tree));
        let root = &read.document.tree("PersonSearch").unwrap().root;
        let wait = root.at(&[0, 0]).unwrap();
        // Exact ties round to even, as Rust formats them.
        assert_eq!(wait.port_value("timeout_s"), Some("12.2"));
        assert_eq!(
            root.at(&[0, 1]).unwrap().port_value("to"),
            Some("20.12;-3.00")
        );
        assert_eq!(root.at(&[1]).unwrap().port_value("x"), Some("-10.00"));
    }
}
