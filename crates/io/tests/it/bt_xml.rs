//! BehaviorTree.CPP 4 XML: the bundled hand-written trees load with the expected structure,
//! round-trip through the canonical writer, and bad files give errors that name the line,
//! column and attribute.

use chronomap_bt::{
    BtDocument, DefinitionErrorKind, NodeCategory, NodeDef, PortDirection, Registry, Tree,
};
use chronomap_io::bt_xml::{
    BtXmlError, BtXmlErrorKind, encode_bt_xml, encode_tree_xml, parse_bt_xml, read_bt_xml,
};

use crate::common::bt_example as example;

fn load(name: &str) -> BtDocument {
    read_bt_xml(example(name), &Registry::new())
        .unwrap_or_else(|e| panic!("{e}"))
        .document
}

/// `(line, column)`, 1-based, of the first occurrence of `needle` in `text`.
fn position_of(text: &str, needle: &str) -> (u32, u32) {
    let offset = text
        .find(needle)
        .unwrap_or_else(|| panic!("{needle:?} not in the text"));
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().unwrap().chars().count() + 1;
    (line as u32, column as u32)
}

fn error(text: &str) -> BtXmlError {
    parse_bt_xml("t.xml", text, &Registry::new()).expect_err("must be rejected")
}

fn assert_at(e: &BtXmlError, text: &str, needle: &str, attribute: Option<&str>) {
    assert_eq!(
        (e.line(), e.column()),
        {
            let (l, c) = position_of(text, needle);
            (Some(l), Some(c))
        },
        "{e}"
    );
    assert_eq!(e.attribute(), attribute, "{e}");
    assert_eq!(e.file(), Some("t.xml"));
    let (l, c) = position_of(text, needle);
    assert!(
        e.to_string().starts_with(&format!("t.xml:{l}:{c}: ")),
        "{e}"
    );
}

fn wrap(body: &str) -> String {
    format!(
        "<root BTCPP_format=\"4\">\n  <BehaviorTree ID=\"Main\">\n{body}\n  </BehaviorTree>\n</root>\n"
    )
}

/// Checks every `(body, needle, attribute, ending)` row: the tree of [`wrap`]`(body)` is
/// rejected at `needle`, naming `attribute`, with a message that ends with `ending`.
fn check_wrapped_rows(rows: &[(&str, &str, Option<&str>, &str)]) {
    for &(body, needle, attribute, ending) in rows {
        let text = wrap(body);
        let e = error(&text);
        assert_at(&e, &text, needle, attribute);
        assert!(e.to_string().ends_with(ending), "{e}");
    }
}

/// Checks every `(body, needle, attribute, ending)` row: the tree of [`wrap`]`(body)` loads, and
/// strict validation refuses it at the node that starts at `needle`, naming `attribute`, with a
/// message that ends with `ending`.
fn check_strict_rows(rows: &[(&str, &str, Option<&str>, &str)]) {
    for &(body, needle, attribute, ending) in rows {
        let text = wrap(body);
        let xml = parse_bt_xml("t.xml", &text, &Registry::new()).expect("BT.CPP loads it");
        let e = chronomap_bt::validate_strict(&xml.document, &Registry::new()).unwrap_err();
        let at = e.location().and_then(|l| xml.position(l));
        assert_eq!(at, Some(position_of(&text, needle)), "{e}");
        assert_eq!(e.attribute(), attribute, "{e}");
        assert!(e.to_string().ends_with(ending), "{e}");
    }
}

// ---------------------------------------------------------------------------------------------
// The bundled trees

#[test]
fn door_example_loads_with_its_structure_ports_and_models() {
    let doc = load("door.xml");
    assert_eq!(doc.main_tree.as_deref(), Some("MainTree"));
    let ids: Vec<&str> = doc.trees.iter().map(|t| t.id.as_str()).collect();
    assert_eq!(ids, ["MainTree", "DoorClosed"]);

    let main = &doc.trees[0].root;
    assert_eq!(
        (main.category, main.id.as_str()),
        (NodeCategory::Control, "Sequence")
    );
    assert_eq!(main.name.as_deref(), Some("cross_door"));
    let fallback = &main.children[0];
    assert_eq!(fallback.id, "Fallback");
    let inverter = &fallback.children[0];
    assert_eq!(
        (inverter.category, inverter.id.as_str()),
        (NodeCategory::Decorator, "Inverter")
    );
    assert_eq!(
        inverter.children[0],
        NodeDef::condition("IsDoorClosed"),
        "explicit form"
    );
    assert_eq!(
        fallback.children[1],
        NodeDef::subtree("DoorClosed")
            .named("open_it")
            .port("door", "{door}")
    );
    assert_eq!(
        main.children[1],
        NodeDef::action("PassThroughDoor").port("door", "{door}")
    );

    let door_closed = &doc.trees[1].root;
    assert_eq!(door_closed.name.as_deref(), Some("try_to_open"));
    let children: Vec<(&str, NodeCategory, usize)> = door_closed
        .children
        .iter()
        .map(|c| (c.id.as_str(), c.category, c.children.len()))
        .collect();
    assert_eq!(
        children,
        [
            ("OpenDoor", NodeCategory::Action, 0),
            ("RetryUntilSuccessful", NodeCategory::Decorator, 1),
            ("SmashDoor", NodeCategory::Action, 0)
        ]
    );
    assert_eq!(
        door_closed.children[1].port_value("num_attempts"),
        Some("3")
    );
    assert_eq!(door_closed.children[1].children[0].id, "PickLock");

    // Declared models, then the model inferred for the explicit-form IsDoorClosed.
    let models: Vec<(&str, NodeCategory, usize)> = doc
        .node_models
        .iter()
        .map(|m| (m.id.as_str(), m.category, m.ports.len()))
        .collect();
    assert_eq!(
        models,
        [
            ("OpenDoor", NodeCategory::Action, 1),
            ("PassThroughDoor", NodeCategory::Action, 1),
            ("PickLock", NodeCategory::Action, 1),
            ("SmashDoor", NodeCategory::Action, 1),
            ("IsDoorClosed", NodeCategory::Condition, 0)
        ]
    );
    let open = &doc.node_models[0].ports[0];
    assert_eq!(
        (
            open.name.as_str(),
            open.direction,
            open.type_name.as_deref(),
            open.description.as_deref()
        ),
        (
            "door",
            PortDirection::Input,
            Some("std::string"),
            Some("Which door")
        )
    );
    assert_eq!(
        doc.node_models[3].description.as_deref(),
        Some("Last resort")
    );
}

#[test]
fn parallel_example_keeps_its_thresholds_and_infers_models_of_explicit_leaves() {
    let doc = load("parallel.xml");
    assert_eq!(doc.main_tree, None);
    let timeout = &doc.trees[0].root;
    assert_eq!(timeout.port_value("msec"), Some("30000"));
    let parallel = &timeout.children[0];
    assert_eq!(
        parallel.ports,
        [
            ("success_count".to_owned(), "2".to_owned()),
            ("failure_count".to_owned(), "1".to_owned())
        ]
    );
    let leaves: Vec<&str> = parallel.children.iter().map(|c| c.id.as_str()).collect();
    assert_eq!(leaves, ["MoveTo", "Say", "ScanForPeople"]);
    let say = doc.node_model("Say").expect("inferred");
    assert_eq!(say.ports.len(), 1);
    assert_eq!(
        (say.ports[0].name.as_str(), say.ports[0].direction),
        ("text", PortDirection::InOut)
    );
}

#[test]
fn monitor_example_instantiates_every_subtree_in_depth_first_order() {
    let doc = load("monitor.xml");
    assert_eq!(doc.trees.len(), 5);
    let (registry, _) = chronomap_bt::script::scripted_registry(&doc).unwrap();
    let tree = Tree::new(&doc, &registry).unwrap();
    let instances: Vec<(&str, &str, u16)> = tree
        .subtrees()
        .iter()
        .map(|s| (s.tree_id.as_str(), s.path.as_str(), s.root_uid))
        .collect();
    assert_eq!(
        instances,
        [
            ("Executive", "", 1),
            ("Patrol", "Patrol::9", 10),
            ("NodeRecovery", "node_monitor", 16),
            ("NavigationRecovery", "navigation_monitor", 20),
            ("LocalizationRecovery", "localization_monitor", 32)
        ]
    );
    assert_eq!(tree.nodes().len(), 41);
    // The model's default fills the absent port of MoveBackwards.
    let back = tree
        .nodes()
        .iter()
        .find(|n| n.id() == "MoveBackwards")
        .unwrap();
    assert!(back.attributes().is_empty());
    assert_eq!(back.ports(), [("distance".to_owned(), "0.3".to_owned())]);
}

#[test]
fn bundled_trees_round_trip_through_the_canonical_writer() {
    for name in ["door.xml", "parallel.xml", "monitor.xml"] {
        let doc = load(name);
        let saved = encode_bt_xml(&doc).unwrap();
        let again = parse_bt_xml("saved.xml", &saved, &Registry::new())
            .unwrap_or_else(|e| panic!("{name}: {e}\n{saved}"));
        assert_eq!(again.document, doc, "{name}");
        assert!(again.warnings.is_empty(), "{name}: {:?}", again.warnings);
        // The canonical text is a fixed point.
        assert_eq!(encode_bt_xml(&again.document).unwrap(), saved, "{name}");
    }
}

#[test]
fn canonical_form_is_compact_with_models_and_declaration() {
    let saved = encode_bt_xml(&load("door.xml")).unwrap();
    let expected_start = "\
<?xml version=\"1.0\" encoding=\"UTF-8\"?>
<root BTCPP_format=\"4\" main_tree_to_execute=\"MainTree\">
  <BehaviorTree ID=\"MainTree\">
    <Sequence name=\"cross_door\">
      <Fallback>
        <Inverter>
          <IsDoorClosed/>
        </Inverter>
        <SubTree ID=\"DoorClosed\" name=\"open_it\" door=\"{door}\"/>
      </Fallback>
      <PassThroughDoor door=\"{door}\"/>
    </Sequence>
  </BehaviorTree>
";
    assert!(saved.starts_with(expected_start), "{saved}");
    assert!(saved.contains(
        "    <Action ID=\"OpenDoor\">\n      <input_port name=\"door\" type=\"std::string\">Which door</input_port>\n    </Action>\n"
    ));
    assert!(saved.contains("    <Condition ID=\"IsDoorClosed\"/>\n"));
    assert!(saved.ends_with("  </TreeNodesModel>\n</root>\n"));
}

#[test]
fn explicit_and_compact_forms_give_the_same_document() {
    let explicit = wrap(
        r#"    <Control ID="Sequence" name="s">
      <Decorator ID="Repeat" num_cycles="2">
        <Action ID="AlwaysSuccess"/>
      </Decorator>
      <Condition ID="Check" level="{battery}"/>
    </Control>"#,
    );
    let compact = format!(
        "{}  <TreeNodesModel>\n    <Condition ID=\"Check\">\n      <inout_port name=\"level\"/>\n    </Condition>\n  </TreeNodesModel>\n</root>\n",
        wrap(
            r#"    <Sequence name="s">
      <Repeat num_cycles="2">
        <AlwaysSuccess/>
      </Repeat>
      <Check level="{battery}"/>
    </Sequence>"#
        )
        .trim_end()
        .strip_suffix("</root>")
        .unwrap()
    );
    let a = parse_bt_xml("a.xml", &explicit, &Registry::new())
        .unwrap()
        .document;
    let b = parse_bt_xml("b.xml", &compact, &Registry::new())
        .unwrap()
        .document;
    assert_eq!(a, b);
}

#[test]
fn special_characters_and_autoremap_survive_a_round_trip() {
    let text = r#"<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Sequence>
      <Action ID="Say" text="a &lt; b &amp; &quot;c&quot;&#10;next line&#9;tab"/>
      <SubTree ID="Sub" _autoremap="true" goal="here"/>
    </Sequence>
  </BehaviorTree>
  <BehaviorTree ID="Sub">
    <AlwaysSuccess name="ok"/>
  </BehaviorTree>
</root>"#;
    let doc = parse_bt_xml("t.xml", text, &Registry::new())
        .unwrap()
        .document;
    let say = &doc.trees[0].root.children[0];
    assert_eq!(
        say.port_value("text"),
        Some("a < b & \"c\"\nnext line\ttab")
    );
    let sub = &doc.trees[0].root.children[1];
    assert!(sub.autoremap);
    assert_eq!(sub.ports, [("goal".to_owned(), "here".to_owned())]);
    let again = parse_bt_xml("s.xml", &encode_bt_xml(&doc).unwrap(), &Registry::new()).unwrap();
    assert_eq!(again.document, doc);
}

#[test]
fn metadata_attributes_are_ignored_and_leniencies_are_warned_about() {
    let text = r#"<root main_tree_to_execute="Main">
  <BehaviorTree ID="Main" _fullpath="">
    <Sequence name="s" _uid="1">
      <AlwaysSuccess name="a" _uid="2"/>
    </Sequence>
  </BehaviorTree>
  <TreeNodesModel>
    <Script ID="x"/>
    <Action ID="Unused"><input_port name="p"/><metadata/></Action>
  </TreeNodesModel>
</root>"#;
    let loaded = parse_bt_xml("t.xml", text, &Registry::new()).unwrap();
    assert!(loaded.document.trees[0].root.ports.is_empty());
    assert_eq!(loaded.warnings.len(), 3, "{:?}", loaded.warnings);
    assert_eq!(
        loaded.warnings[0],
        "t.xml:1:1: <root> has no BTCPP_format attribute; read as format 4 (as BehaviorTree.CPP 4 does)"
    );
    let (l, c) = position_of(text, "<Script");
    assert_eq!(
        loaded.warnings[1],
        format!("t.xml:{l}:{c}: <TreeNodesModel>: skipped the unknown entry <Script>")
    );
    assert!(loaded.warnings[2].contains("skipped <metadata> in the model of \"Unused\""));
}

#[test]
fn runtime_tree_xml_carries_uids_fullpaths_and_models_as_for_groot2() {
    let doc = load("door.xml");
    let (registry, _) = chronomap_bt::script::scripted_registry(&doc).unwrap();
    let tree = Tree::new(&doc, &registry).unwrap();
    let xml = encode_tree_xml(&tree);
    let parsed = roxmltree_check(&xml);
    assert_eq!(parsed, 11, "one _uid per node");
    assert!(xml.contains("  <BehaviorTree ID=\"MainTree\" _fullpath=\"\">\n"));
    assert!(
        xml.contains(
            "<SubTree ID=\"DoorClosed\" _fullpath=\"open_it\" _uid=\"5\" door=\"{door}\"/>"
        )
    );
    assert!(xml.contains("  <BehaviorTree ID=\"DoorClosed\" _fullpath=\"open_it\">\n    <Fallback name=\"try_to_open\" _uid=\"6\">"));
    assert!(xml.contains(
        "<RetryUntilSuccessful name=\"RetryUntilSuccessful\" _uid=\"8\" num_attempts=\"3\">"
    ));
    assert!(
        xml.contains("<Decorator ID=\"RetryUntilSuccessful\">"),
        "models of built-ins too"
    );
    assert!(xml.contains("<Condition ID=\"IsDoorClosed\"/>"));
}

/// Counts `_uid` attributes after checking the XML is well-formed.
fn roxmltree_check(xml: &str) -> usize {
    // The io crate's own reader must accept it (metadata attributes are skipped).
    let loaded =
        parse_bt_xml("log.xml", xml, &Registry::new()).unwrap_or_else(|e| panic!("{e}\n{xml}"));
    assert_eq!(loaded.document.trees.len(), 2);
    xml.matches(" _uid=\"").count()
}

// ---------------------------------------------------------------------------------------------
// Errors name line, column and attribute

#[test]
fn unknown_node_ids_are_located() {
    let text = wrap("    <Sequence>\n      <Fly altitude=\"3\"/>\n    </Sequence>");
    let e = error(&text);
    assert_at(&e, &text, "<Fly", None);
    assert!(e.to_string().contains("unknown node ID \"Fly\""), "{e}");

    let text = wrap(
        "    <Action ID=\"AlwaysSuccess\"/>\n    <Control ID=\"Selector\"><AlwaysSuccess/></Control>",
    );
    let e = error(&text);
    assert!(
        matches!(e.kind(), BtXmlErrorKind::TreeRoot { found: 2, .. }),
        "{e}"
    );

    let text = wrap("    <Control ID=\"Selector\">\n      <AlwaysSuccess/>\n    </Control>");
    let e = error(&text);
    assert_at(&e, &text, "ID=\"Selector\"", Some("ID"));

    let text = wrap("    <EntryUpdated>\n      <AlwaysSuccess/>\n    </EntryUpdated>");
    let e = error(&text);
    assert!(
        e.to_string().ends_with(
            "\"EntryUpdated\" is a BehaviorTree.CPP node that chronomap does not implement"
        ),
        "{e}"
    );
}

#[test]
fn missing_required_attributes_and_bad_numbers_are_located() {
    // BehaviorTree.CPP loads these and throws when it ticks the node; strict validation
    // (`chronomap bt check`) finds them, at the node.
    check_strict_rows(&[
        (
            "    <Repeat>\n      <AlwaysSuccess/>\n    </Repeat>",
            "<Repeat>",
            Some("num_cycles"),
            "\"Repeat\" needs the attribute \"num_cycles\"",
        ),
        (
            "    <Parallel success_count=\"3\">\n      <AlwaysSuccess/>\n      <AlwaysSuccess/>\n    </Parallel>",
            "<Parallel",
            Some("success_count"),
            "Parallel success_count=\"3\" needs 3 children but it has 2",
        ),
    ]);
    check_wrapped_rows(&[
        (
            "    <Repeat num_cycle=\"3\">\n      <AlwaysSuccess/>\n    </Repeat>",
            "num_cycle=",
            Some("num_cycle"),
            "\"Repeat\" has no port \"num_cycle\" (its ports: num_cycles)",
        ),
        (
            "    <Sequence>\n      <Action name=\"x\"/>\n    </Sequence>",
            "<Action",
            Some("ID"),
            "<Action> needs the attribute \"ID\"",
        ),
    ]);

    let text = wrap(
        "    <RetryUntilSuccessful num_attempts=\"three\">\n      <AlwaysSuccess/>\n    </RetryUntilSuccessful>",
    );
    let e = error(&text);
    assert_at(&e, &text, "num_attempts=", Some("num_attempts"));
    assert!(matches!(
        e.kind(),
        BtXmlErrorKind::Definition(DefinitionErrorKind::BadValue { .. })
    ));

    let text = wrap("    <Timeout msec=\"1.5\">\n      <AlwaysSuccess/>\n    </Timeout>");
    assert_at(&error(&text), &text, "msec=", Some("msec"));
}

#[test]
fn wrong_child_counts_are_located() {
    check_wrapped_rows(&[
        (
            "    <Sequence>\n      <Inverter>\n        <AlwaysSuccess/>\n        <AlwaysFailure/>\n      </Inverter>\n    </Sequence>",
            "<Inverter>",
            None,
            "Decorator \"Inverter\" needs exactly 1 child, found 2",
        ),
        (
            "    <Sequence>\n      <AlwaysSuccess>\n        <AlwaysFailure/>\n      </AlwaysSuccess>\n    </Sequence>",
            "<AlwaysSuccess>",
            None,
            "Action \"AlwaysSuccess\" needs no children, found 1",
        ),
    ]);

    let text = wrap("    <Fallback/>");
    assert_at(&error(&text), &text, "<Fallback/>", None);
}

#[test]
fn format_versions_other_than_4_and_structure_errors_are_located() {
    let text = "<root BTCPP_format=\"3\" main_tree_to_execute=\"M\">\n  <BehaviorTree ID=\"M\"><AlwaysSuccess/></BehaviorTree>\n</root>";
    let e = error(text);
    assert_at(&e, text, "BTCPP_format=", Some("BTCPP_format"));
    assert!(
        e.to_string()
            .contains("only BehaviorTree.CPP format 4 is supported")
    );

    let text = "<root BTCPP_format=\"4\" main_tree_to_execute=\"Mian\">\n  <BehaviorTree ID=\"Main\"><AlwaysSuccess/></BehaviorTree>\n</root>";
    let e = error(text);
    assert_at(
        &e,
        text,
        "main_tree_to_execute=",
        Some("main_tree_to_execute"),
    );
    assert!(
        e.to_string()
            .ends_with("attribute main_tree_to_execute: there is no <BehaviorTree ID=\"Mian\">")
    );

    let text = "<root BTCPP_format=\"4\">\n  <BehaviorTree ID=\"A\"><AlwaysSuccess/></BehaviorTree>\n  <BehaviorTree ID=\"A\"><AlwaysFailure/></BehaviorTree>\n</root>";
    let e = error(text);
    // The second tree's ID attribute: line 3, after `  <BehaviorTree `.
    assert_eq!(
        (e.line(), e.column(), e.attribute()),
        (Some(3), Some(17), Some("ID")),
        "{e}"
    );

    let text = wrap("    <SubTree ID=\"Nowhere\"/>");
    assert_at(&error(&text), &text, "ID=\"Nowhere\"", Some("ID"));

    let text = "<root BTCPP_format=\"4\">\n  <include path=\"other.xml\"/>\n</root>";
    let e = error(text);
    assert_at(&e, text, "path=", Some("path"));
    assert!(e.to_string().contains("no directory"), "{e}");

    let text = "<root BTCPP_format=\"4\">\n  <BehaviourTree ID=\"A\"/>\n</root>";
    assert_at(&error(text), text, "<BehaviourTree", None);

    let text = "<bt>\n</bt>";
    assert!(
        error(text)
            .to_string()
            .starts_with("t.xml:1:1: the root element is <bt>")
    );

    let text = wrap("    <Sequence _autoremap=\"true\"><AlwaysSuccess/></Sequence>");
    assert_at(&error(&text), &text, "_autoremap", Some("_autoremap"));

    let text = "<root BTCPP_format=\"4\">\n  <BehaviorTree ID=\"A\">\n    <AlwaysSuccess>\n  </BehaviorTree>\n</root>";
    let e = error(text);
    assert!(matches!(e.kind(), BtXmlErrorKind::Xml { .. }), "{e}");
    assert_eq!(e.line(), Some(4), "{e}");

    let text = "<root BTCPP_format=\"4\">\n  <BehaviorTree ID=\"A\"><SubTree ID=\"B\"/></BehaviorTree>\n  <BehaviorTree ID=\"B\"><SubTree ID=\"A\"/></BehaviorTree>\n</root>";
    let e = error(text);
    assert!(
        e.to_string()
            .contains("subtrees are recursive: A -> B -> A"),
        "{e}"
    );
    let (l, _) = position_of(text, "<SubTree ID=\"A\"");
    assert_eq!(e.line(), Some(l));
}

#[test]
fn registered_leaves_resolve_compact_tags_and_their_ports_are_checked() {
    use chronomap_bt::{NodeModel, PortSpec, Status};
    let mut registry = Registry::new();
    registry
        .register(
            NodeModel::new(NodeCategory::Action, "Dock")
                .port(PortSpec::input("station").typed("int")),
            || -> Box<dyn chronomap_bt::LeafNode> {
                struct Dock;
                impl chronomap_bt::LeafNode for Dock {
                    fn tick(
                        &mut self,
                        _: &mut chronomap_bt::LeafContext<'_>,
                    ) -> Result<Status, chronomap_bt::LeafError> {
                        Ok(Status::Success)
                    }
                }
                Box::new(Dock)
            },
        )
        .unwrap();
    let ok = wrap("    <Dock station=\"2\"/>");
    parse_bt_xml("t.xml", &ok, &registry).unwrap();
    let bad = wrap("    <Dock station=\"two\"/>");
    let e = parse_bt_xml("t.xml", &bad, &registry).unwrap_err();
    assert_eq!(e.attribute(), Some("station"));
    // Without the registration the ID is unknown.
    assert!(matches!(
        parse_bt_xml("t.xml", &ok, &Registry::new())
            .unwrap_err()
            .kind(),
        BtXmlErrorKind::Definition(DefinitionErrorKind::UnknownNode { .. })
    ));
}

#[test]
fn documents_that_xml_cannot_express_are_refused_by_the_writer() {
    let doc = BtDocument::single(chronomap_bt::TreeDef::new(
        "Main",
        NodeDef::action("Say").port("two words", "x"),
    ));
    let e = encode_bt_xml(&doc).unwrap_err();
    assert!(matches!(e.kind(), BtXmlErrorKind::Unwritable { .. }), "{e}");
    // IDs that are not XML names are written in the explicit form.
    let doc = BtDocument::single(chronomap_bt::TreeDef::new(
        "Main",
        NodeDef::action("Open door"),
    ));
    let text = encode_bt_xml(&doc).unwrap();
    assert!(text.contains("<Action ID=\"Open door\"/>"), "{text}");
    let again = parse_bt_xml("t.xml", &text, &Registry::new())
        .unwrap()
        .document;
    assert_eq!(again.trees, doc.trees);
}

// ---------------------------------------------------------------------------------------------
// Scripting attributes, includes, node models from other files, limits

use chronomap_io::bt_xml::{
    BtReadOptions, parse_bt_xml_in, parse_node_models, read_bt_xml_with, read_node_models,
};

fn scratch(test: &str) -> std::path::PathBuf {
    chronomap_testutil::scratch!("chronomap-io-bt-xml", test)
}

fn write(dir: &std::path::Path, name: &str, text: &str) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn scripting_attributes_are_kept_in_document_order_and_written_back() {
    let text = wrap(
        r#"    <Sequence _while="battery &gt; 20">
      <AlwaysSuccess _skipIf="done" name="a" _onSuccess="count += 1" _post="n := 0"/>
      <AlwaysFailure _failureIf="x == 1" _onFailure="failed := true" _onHalted="h := 1" _successIf="y"/>
    </Sequence>"#,
    );
    let doc = parse_bt_xml("t.xml", &text, &Registry::new())
        .unwrap()
        .document;
    let root = &doc.trees[0].root;
    assert_eq!(
        root.scripts,
        [("_while".to_owned(), "battery > 20".to_owned())]
    );
    let a = &root.children[0];
    assert_eq!(
        a.scripts,
        [
            ("_skipIf".to_owned(), "done".to_owned()),
            ("_onSuccess".to_owned(), "count += 1".to_owned()),
            ("_post".to_owned(), "n := 0".to_owned()),
        ]
    );
    assert!(a.ports.is_empty());
    assert_eq!(root.children[1].scripts.len(), 4);
    let saved = encode_bt_xml(&doc).unwrap();
    assert!(
        saved.contains(
            r#"<AlwaysSuccess name="a" _skipIf="done" _onSuccess="count += 1" _post="n := 0"/>"#
        ),
        "{saved}"
    );
    let again = parse_bt_xml("s.xml", &saved, &Registry::new()).unwrap();
    assert_eq!(again.document, doc);

    let bad = BtDocument::single(chronomap_bt::TreeDef::new(
        "Main",
        NodeDef::action("AlwaysSuccess").script("_before", "x"),
    ));
    assert!(matches!(
        encode_bt_xml(&bad).unwrap_err().kind(),
        BtXmlErrorKind::Unwritable { .. }
    ));
}

#[test]
fn includes_are_relative_to_the_including_file_and_merge_trees_and_models() {
    let dir = scratch("includes");
    write(
        &dir,
        "main.xml",
        r#"<root BTCPP_format="4" main_tree_to_execute="Main">
  <include path="sub/patrol.xml"/>
  <BehaviorTree ID="Main">
    <Sequence>
      <SubTree ID="Patrol"/>
      <SubTree ID="Dock"/>
    </Sequence>
  </BehaviorTree>
</root>"#,
    );
    write(
        &dir,
        "sub/patrol.xml",
        r#"<root BTCPP_format="4" main_tree_to_execute="Patrol">
  <include path="../dock.xml"/>
  <BehaviorTree ID="Patrol">
    <GoTo where="kitchen"/>
  </BehaviorTree>
  <TreeNodesModel>
    <Action ID="GoTo"><input_port name="where"/></Action>
  </TreeNodesModel>
</root>"#,
    );
    write(
        &dir,
        "dock.xml",
        r#"<root BTCPP_format="4">
  <include path="sub/patrol.xml"/>
  <BehaviorTree ID="Dock">
    <GoTo where="dock"/>
  </BehaviorTree>
</root>"#,
    );
    // dock.xml includes patrol.xml again: that is a cycle (patrol -> dock -> patrol).
    let e = read_bt_xml(dir.join("main.xml"), &Registry::new()).unwrap_err();
    let text = e.to_string();
    assert!(
        matches!(e.kind(), BtXmlErrorKind::IncludeCycle { .. }),
        "{e}"
    );
    assert!(text.contains("dock.xml:2:12: "), "{e}");
    assert!(
        text.contains("makes an include cycle: ") && text.matches("patrol.xml").count() >= 3,
        "{e}"
    );

    // Without the cycle: Main from main.xml, Patrol and Dock from the includes; GoTo resolves
    // in every file with the model declared in sub/patrol.xml.
    write(
        &dir,
        "dock.xml",
        r#"<root BTCPP_format="4">
  <BehaviorTree ID="Dock">
    <GoTo where="dock"/>
  </BehaviorTree>
</root>"#,
    );
    let read = read_bt_xml(dir.join("main.xml"), &Registry::new()).unwrap();
    let ids: Vec<&str> = read.document.trees.iter().map(|t| t.id.as_str()).collect();
    assert_eq!(ids, ["Main", "Patrol", "Dock"]);
    assert_eq!(read.document.main_tree.as_deref(), Some("Main"));
    assert_eq!(read.files.len(), 3);
    assert!(read.file_of("Dock").unwrap().ends_with("dock.xml"));
    let location = chronomap_bt::NodeLocation {
        tree: "Dock".to_owned(),
        path: vec![],
    };
    let (file, line, column) = read.locate(&location).unwrap();
    assert!(file.ends_with("dock.xml"));
    assert_eq!((line, column), (3, 5));

    // An error inside an included file names that file.
    write(
        &dir,
        "dock.xml",
        "<root BTCPP_format=\"4\">\n  <BehaviorTree ID=\"Dock\">\n    <GoTo wher=\"dock\"/>\n  </BehaviorTree>\n</root>",
    );
    let e = read_bt_xml(dir.join("main.xml"), &Registry::new()).unwrap_err();
    assert!(e.file().unwrap().ends_with("dock.xml"), "{e}");
    assert_eq!(
        (e.line(), e.column(), e.attribute()),
        (Some(3), Some(11), Some("wher"))
    );

    // A missing file names the including file and line; ros_pkg is refused.
    write(
        &dir,
        "missing.xml",
        "<root BTCPP_format=\"4\">\n  <include path=\"nowhere.xml\"/>\n</root>",
    );
    let e = read_bt_xml(dir.join("missing.xml"), &Registry::new()).unwrap_err();
    assert!(e.file().unwrap().ends_with("missing.xml"), "{e}");
    assert_eq!(e.line(), Some(2));
    assert!(e.to_string().contains("cannot read"), "{e}");
    write(
        &dir,
        "ros.xml",
        "<root BTCPP_format=\"4\">\n  <include ros_pkg=\"nav2_bt_navigator\" path=\"behavior_trees/x.xml\"/>\n</root>",
    );
    let e = read_bt_xml(dir.join("ros.xml"), &Registry::new()).unwrap_err();
    assert_eq!(e.attribute(), Some("ros_pkg"));
    assert!(
        e.to_string().contains("give the file's path instead"),
        "{e}"
    );

    // Text with a directory resolves includes like a file there.
    let text = "<root BTCPP_format=\"4\" main_tree_to_execute=\"T\">\n  <include path=\"dock.xml\"/>\n  <BehaviorTree ID=\"T\"><AlwaysSuccess/></BehaviorTree>\n</root>";
    write(
        &dir,
        "dock.xml",
        "<root BTCPP_format=\"4\"><BehaviorTree ID=\"Dock\"><AlwaysSuccess/></BehaviorTree></root>",
    );
    let read = parse_bt_xml_in(
        "t.xml",
        text,
        &dir,
        &Registry::new(),
        &BtReadOptions::default(),
    )
    .unwrap();
    assert_eq!(read.document.trees.len(), 2);
}

#[test]
fn a_file_included_twice_is_read_once_and_limits_are_errors() {
    let dir = scratch("include_limits");
    write(
        &dir,
        "a.xml",
        "<root BTCPP_format=\"4\" main_tree_to_execute=\"A\">\n  <include path=\"b.xml\"/>\n  <include path=\"c.xml\"/>\n  <BehaviorTree ID=\"A\"><Sequence><SubTree ID=\"B\"/><SubTree ID=\"C\"/></Sequence></BehaviorTree>\n</root>",
    );
    write(
        &dir,
        "b.xml",
        "<root BTCPP_format=\"4\">\n  <include path=\"d.xml\"/>\n  <BehaviorTree ID=\"B\"><SubTree ID=\"D\"/></BehaviorTree>\n</root>",
    );
    write(
        &dir,
        "c.xml",
        "<root BTCPP_format=\"4\">\n  <include path=\"./d.xml\"/>\n  <BehaviorTree ID=\"C\"><SubTree ID=\"D\"/></BehaviorTree>\n</root>",
    );
    write(
        &dir,
        "d.xml",
        "<root BTCPP_format=\"4\"><BehaviorTree ID=\"D\"><AlwaysSuccess/></BehaviorTree></root>",
    );
    let read = read_bt_xml(dir.join("a.xml"), &Registry::new()).unwrap();
    let ids: Vec<&str> = read.document.trees.iter().map(|t| t.id.as_str()).collect();
    assert_eq!(ids, ["A", "B", "D", "C"]);

    let options = BtReadOptions {
        max_files: 2,
        ..BtReadOptions::default()
    };
    let e = read_bt_xml_with(dir.join("a.xml"), &Registry::new(), &options).unwrap_err();
    assert!(
        matches!(e.kind(), BtXmlErrorKind::TooManyFiles { limit: 2 }),
        "{e}"
    );
    let options = BtReadOptions {
        max_bytes: 300,
        ..BtReadOptions::default()
    };
    let e = read_bt_xml_with(dir.join("a.xml"), &Registry::new(), &options).unwrap_err();
    assert!(
        matches!(e.kind(), BtXmlErrorKind::TooManyBytes { limit: 300 }),
        "{e}"
    );

    // Two files with one tree ID: the second names the first.
    write(
        &dir,
        "d.xml",
        "<root BTCPP_format=\"4\"><BehaviorTree ID=\"B\"><AlwaysSuccess/></BehaviorTree></root>",
    );
    let e = read_bt_xml(dir.join("a.xml"), &Registry::new()).unwrap_err();
    assert!(e.to_string().contains("b.xml:3:3)"), "{e}");
}

#[cfg(unix)]
#[test]
fn endless_and_huge_inputs_are_bounded() {
    // A device is refused before anything is read ...
    let e = read_bt_xml("/dev/zero", &Registry::new()).unwrap_err();
    assert!(e.to_string().contains("not a regular file"), "{e}");
    // ... and a regular file larger than the limit after reading just past it (a sparse file).
    let path = std::env::temp_dir().join(format!("bt-huge-{}.xml", std::process::id()));
    let file = std::fs::File::create(&path).unwrap();
    file.set_len(chronomap_io::bt_xml::MAX_BYTES + 1).unwrap();
    let e = read_bt_xml(&path, &Registry::new()).unwrap_err();
    std::fs::remove_file(&path).unwrap();
    assert!(
        matches!(e.kind(), BtXmlErrorKind::TooManyBytes { .. }),
        "{e}"
    );
}

/// `levels` nested `Inverter`s around a leaf, one per line.
fn nested(levels: usize) -> String {
    let mut text = String::from("<root BTCPP_format=\"4\">\n<BehaviorTree ID=\"Deep\">\n");
    for _ in 0..levels {
        text.push_str("<Inverter>\n");
    }
    text.push_str("<AlwaysSuccess/>\n");
    for _ in 0..levels {
        text.push_str("</Inverter>\n");
    }
    text.push_str("</BehaviorTree>\n</root>\n");
    text
}

#[test]
fn nesting_is_bounded_with_an_error_at_the_first_node_too_deep() {
    // 999 decorators and a leaf: 1000 levels.
    let doc = parse_bt_xml("ok.xml", &nested(999), &Registry::new()).unwrap();
    assert_eq!(subtree_depth(&doc.document.trees[0].root), 1000);
    let e = parse_bt_xml("deep.xml", &nested(10_000), &Registry::new()).unwrap_err();
    assert!(
        matches!(e.kind(), BtXmlErrorKind::TooDeep { limit: 1000 }),
        "{e}"
    );
    // Line 3 holds level 1.
    assert_eq!((e.line(), e.column()), (Some(1003), Some(1)), "{e}");
    assert_eq!(
        e.to_string(),
        "deep.xml:1003:1: nodes nested deeper than 1000 levels (a limit of this reader)"
    );
}

fn subtree_depth(node: &NodeDef) -> usize {
    let mut depth = 0;
    let mut level = vec![node];
    while !level.is_empty() {
        depth += 1;
        level = level.iter().flat_map(|n| n.children.iter()).collect();
    }
    depth
}

#[test]
fn dtds_entities_and_namespaces_are_refused() {
    let laughs = r#"<?xml version="1.0"?>
<!DOCTYPE lolz [
 <!ENTITY lol "lol">
 <!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
 <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
]>
<root BTCPP_format="4"><BehaviorTree ID="A"><Action ID="Say" text="&lol3;"/></BehaviorTree></root>"#;
    let e = error(laughs);
    assert!(matches!(e.kind(), BtXmlErrorKind::Dtd), "{e}");
    assert_eq!((e.line(), e.column()), (Some(2), Some(1)));

    let text = "<root BTCPP_format=\"4\" xmlns:bt=\"urn:bt\">\n  <BehaviorTree ID=\"A\">\n    <bt:Sequence><AlwaysSuccess/></bt:Sequence>\n  </BehaviorTree>\n</root>";
    let e = error(text);
    assert_at(&e, text, "<bt:Sequence", None);
    assert!(e.to_string().contains("namespace \"urn:bt\""), "{e}");
    let text = "<root BTCPP_format=\"4\" xmlns=\"urn:bt\">\n</root>";
    assert!(matches!(
        error(text).kind(),
        BtXmlErrorKind::Namespace { .. }
    ));
    let text = wrap("    <bt:Sequence><AlwaysSuccess/></bt:Sequence>");
    assert!(matches!(error(&text).kind(), BtXmlErrorKind::Xml { .. }));
    let text = "<root BTCPP_format=\"4\" xmlns:x=\"urn:x\">\n  <BehaviorTree ID=\"A\">\n    <AlwaysSuccess x:note=\"1\"/>\n  </BehaviorTree>\n</root>";
    let e = error(text);
    assert_at(&e, text, "x:note", Some("note"));
}

#[test]
fn out_of_range_counts_and_times_are_refused_with_the_port_named() {
    // BehaviorTree.CPP loads negative counts (and gives up at once); strict validation finds
    // them. Negative times are not unsigned integers, which BehaviorTree.CPP refuses at load.
    check_strict_rows(&[
        (
            "    <RetryUntilSuccessful num_attempts=\"-5\">\n      <AlwaysSuccess/>\n    </RetryUntilSuccessful>",
            "<RetryUntilSuccessful",
            Some("num_attempts"),
            "(expected an integer of at least -1 (-1: without limit))",
        ),
        (
            "    <Repeat num_cycles=\"-3\">\n      <AlwaysSuccess/>\n    </Repeat>",
            "<Repeat",
            Some("num_cycles"),
            "(expected an integer of at least -1 (-1: without limit))",
        ),
    ]);
    check_wrapped_rows(&[
        (
            "    <Timeout msec=\"-1\">\n      <AlwaysSuccess/>\n    </Timeout>",
            "msec=",
            Some("msec"),
            "(expected a non-negative integer)",
        ),
        (
            "    <Sleep msec=\"-1\"/>",
            "msec=",
            Some("msec"),
            "(expected a non-negative integer)",
        ),
    ]);
    // -1 means without limit; a {key} is checked when ticked.
    let ok = wrap(
        "    <Sequence>\n      <Repeat num_cycles=\"-1\"><AlwaysSuccess/></Repeat>\n      <RetryUntilSuccessful num_attempts=\"{n}\"><AlwaysSuccess/></RetryUntilSuccessful>\n    </Sequence>",
    );
    parse_bt_xml("t.xml", &ok, &Registry::new()).unwrap();
}

fn nav2_models() -> Vec<chronomap_bt::NodeModel> {
    read_node_models(example("nav2/nav2_tree_nodes.xml"))
        .unwrap()
        .models
}

#[test]
fn node_models_from_another_file_check_custom_controls_decorators_and_leaves() {
    let loaded = read_node_models(example("nav2/nav2_tree_nodes.xml")).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let models = loaded.models;
    assert!(models.len() > 80, "{}", models.len());
    let find = |id: &str| models.iter().find(|m| m.id == id).unwrap();
    assert_eq!(find("PipelineSequence").category, NodeCategory::Control);
    assert_eq!(find("RateController").category, NodeCategory::Decorator);
    assert_eq!(
        find("PersistentSequence").ports[0].direction,
        PortDirection::InOut,
        "bidirectional_port"
    );
    let options = BtReadOptions::with_node_models(models.clone());
    let read = |body: &str| {
        parse_bt_xml_in(
            "t.xml",
            &wrap(body),
            std::path::Path::new("."),
            &Registry::new(),
            &options,
        )
    };
    let ok = read(
        "    <PipelineSequence>\n      <RateController hz=\"1.0\">\n        <ComputePathToPose goal=\"{goal}\" path=\"{path}\"/>\n      </RateController>\n      <FollowPath path=\"{path}\"/>\n    </PipelineSequence>",
    )
    .unwrap();
    // Only the models used join the document (and so the saved file's TreeNodesModel).
    let used: Vec<&str> = ok
        .document
        .node_models
        .iter()
        .map(|m| m.id.as_str())
        .collect();
    assert_eq!(
        used,
        [
            "PipelineSequence",
            "RateController",
            "ComputePathToPose",
            "FollowPath"
        ]
    );
    let saved = encode_bt_xml(&ok.document).unwrap();
    assert!(
        saved.contains("<input_port name=\"hz\" type=\"double\" default=\"10.0\">"),
        "{saved}"
    );
    // The saved file loads without the models file.
    parse_bt_xml("s.xml", &saved, &Registry::new()).unwrap();

    let rows: [(&str, &str); 5] = [
        (
            "    <RateController hz=\"1.0\">\n      <Wait/>\n      <Wait/>\n    </RateController>",
            "Decorator \"RateController\" needs exactly 1 child, found 2",
        ),
        (
            "    <RecoveryNode/>",
            "Control \"RecoveryNode\" needs at least 1 child, found 0",
        ),
        (
            "    <RateController hz=\"fast\">\n      <Wait/>\n    </RateController>",
            "attribute hz=\"fast\" of \"RateController\" is invalid (expected a number)",
        ),
        (
            "    <RecoveryNode retries=\"3\">\n      <Wait/>\n    </RecoveryNode>",
            "\"RecoveryNode\" has no port \"retries\" (its ports: number_of_retries)",
        ),
        (
            "    <Spin spin_distance=\"1.57\"/>",
            "\"Spin\" has no port \"spin_distance\"",
        ),
    ];
    for (body, message) in rows {
        let e = read(body).unwrap_err();
        assert!(e.to_string().contains(message), "{e}");
    }
    // Explicit-form custom nodes use the models too (no inferred model).
    let explicit = read("    <Control ID=\"RoundRobin\" wrap_around=\"maybe\">\n      <Action ID=\"Wait\"/>\n    </Control>")
        .unwrap_err();
    assert_eq!(explicit.attribute(), Some("wrap_around"));
    // Without the models the compact custom nodes are unknown.
    let e = parse_bt_xml(
        "t.xml",
        &wrap("    <PipelineSequence>\n      <Wait/>\n    </PipelineSequence>"),
        &Registry::new(),
    )
    .unwrap_err();
    assert!(
        e.to_string()
            .contains("unknown node ID \"PipelineSequence\""),
        "{e}"
    );
    // A file's own declaration wins over the models file.
    let own = format!(
        "{}  <TreeNodesModel>\n    <Action ID=\"Spin\"><input_port name=\"angle\"/></Action>\n  </TreeNodesModel>\n</root>\n",
        wrap("    <Spin angle=\"3\"/>")
            .trim_end()
            .strip_suffix("</root>")
            .unwrap()
    );
    parse_bt_xml_in(
        "t.xml",
        &own,
        std::path::Path::new("."),
        &Registry::new(),
        &options,
    )
    .unwrap();
    let _ = nav2_models;
}

#[test]
fn node_model_files_skip_trees_and_refuse_includes() {
    let loaded = parse_node_models(
        "m.xml",
        "<root BTCPP_format=\"4\">\n  <BehaviorTree ID=\"A\"><AlwaysSuccess/></BehaviorTree>\n  <TreeNodesModel><Action ID=\"Go\"/></TreeNodesModel>\n</root>",
    )
    .unwrap();
    assert_eq!(loaded.models.len(), 1);
    assert_eq!(loaded.warnings.len(), 1);
    assert!(loaded.warnings[0].starts_with("m.xml:2:3: skipped <BehaviorTree>"));
    assert!(parse_node_models("m.xml", "<root><include path=\"x.xml\"/></root>").is_err());
    assert!(parse_node_models("m.xml", "<nodes/>").is_err());
}

#[test]
fn a_tree_id_written_as_a_node_tag_gets_a_hint() {
    let text = "<root BTCPP_format=\"4\" main_tree_to_execute=\"Main\">\n  <BehaviorTree ID=\"Main\">\n    <Sequence>\n      <Talk/>\n    </Sequence>\n  </BehaviorTree>\n  <BehaviorTree ID=\"Talk\"><AlwaysSuccess/></BehaviorTree>\n</root>";
    let e = error(text);
    assert_at(&e, text, "<Talk/>", None);
    assert!(
        e.to_string().ends_with("write <SubTree ID=\"Talk\"/>"),
        "{e}"
    );
}

/// `count` siblings in one `Sequence`, optionally all on one line.
fn siblings(count: usize, one_line: bool) -> String {
    let sep = if one_line { "" } else { "\n" };
    let mut text = String::from("<root BTCPP_format=\"4\"><BehaviorTree ID=\"Wide\"><Sequence>");
    for i in 0..count {
        let _ = std::fmt::Write::write_fmt(
            &mut text,
            format_args!("{sep}<Action ID=\"Leaf{}\" n=\"{i}\"/>", i % 1000),
        );
    }
    text.push_str("</Sequence></BehaviorTree></root>");
    text
}

#[test]
fn wide_trees_and_many_attributes_read_in_linear_time() {
    // Quadratic reading took minutes here; linear reading takes well under a second each.
    for one_line in [false, true] {
        let text = siblings(100_000, one_line);
        let read = parse_bt_xml("wide.xml", &text, &Registry::new()).unwrap();
        assert_eq!(read.document.trees[0].root.children.len(), 100_000);
        assert_eq!(read.document.node_models.len(), 1000);
        let last = chronomap_bt::NodeLocation {
            tree: "Wide".to_owned(),
            path: vec![99_999],
        };
        let (line, _) = read.position(&last).unwrap();
        assert_eq!(line, if one_line { 1 } else { 100_001 });
    }
    let mut text =
        String::from("<root BTCPP_format=\"4\"><BehaviorTree ID=\"A\"><Action ID=\"Big\"");
    for i in 0..5_000 {
        let _ = std::fmt::Write::write_fmt(&mut text, format_args!(" p{i}=\"{i}\""));
    }
    text.push_str("/></BehaviorTree></root>");
    let read = parse_bt_xml("big.xml", &text, &Registry::new()).unwrap();
    assert_eq!(read.document.trees[0].root.ports.len(), 5_000);
    assert_eq!(read.document.node_models[0].ports.len(), 5_000);
    // The parser checks attributes pairwise for duplicates: beyond 10,000 on one element the
    // file is refused before it is parsed.
    let mut text = String::from(
        "<root BTCPP_format=\"4\">\n<!-- a=1 b=2 -->\n<BehaviorTree ID=\"A\">\n  <Action ID=\"Big\"",
    );
    for i in 0..200_000 {
        let _ = std::fmt::Write::write_fmt(&mut text, format_args!(" p{i}=\"a=b\""));
    }
    text.push_str("/></BehaviorTree></root>");
    let e = parse_bt_xml("crowded.xml", &text, &Registry::new()).unwrap_err();
    assert_eq!(
        e.to_string(),
        "crowded.xml:4:3: an element with more than 10000 attributes (a limit of this reader)"
    );
}

#[test]
fn script_nodes_and_conditions_read_in_compact_form_and_run() {
    let text = wrap(
        r#"    <Sequence>
      <Script code="count := 0"/>
      <ScriptCondition code="count == 0"/>
      <AlwaysSuccess _skipIf="count &gt; 3" _onSuccess="count += 1"/>
      <AlwaysFailure _skipIf="count == 1"/>
    </Sequence>"#,
    );
    let doc = parse_bt_xml("t.xml", &text, &Registry::new())
        .unwrap()
        .document;
    let children = &doc.trees[0].root.children;
    assert_eq!(
        (children[0].category, children[1].category),
        (NodeCategory::Action, NodeCategory::Condition)
    );
    let mut tree = Tree::new(&doc, &Registry::new()).unwrap();
    // The failure is skipped because _onSuccess counted the success.
    assert_eq!(
        tree.tick_once(std::time::Duration::ZERO).unwrap(),
        chronomap_bt::Status::Success
    );
    assert_eq!(
        tree.blackboard().get("count").map(ToString::to_string),
        Some("1".to_owned())
    );
}

#[test]
fn namespace_declarations_and_attribute_pairs_are_bounded_before_parsing() {
    // 9,000 namespace declarations, and 10,000 elements that declare one more: the parser
    // copied the 9,000 to each (over two minutes); now refused at the 65th declaration.
    let mut text = String::from("<root BTCPP_format=\"4\"\n");
    for i in 0..9_000 {
        let _ = std::fmt::Write::write_fmt(&mut text, format_args!(" xmlns:p{i}=\"u\""));
    }
    text.push_str("><BehaviorTree ID=\"A\"><Sequence>");
    text.push_str(&"<AlwaysSuccess xmlns:q=\"v\"/>".repeat(10_000));
    text.push_str("</Sequence></BehaviorTree></root>");
    let e = parse_bt_xml("ns.xml", &text, &Registry::new()).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!(
            "ns.xml:2:{}: more than 64 namespace declarations (xmlns) in one file (a limit of \
             this reader)",
            position_of(&text, "xmlns:p64").1
        )
    );
    // A few are read as before (and refused where used).
    let text = "<root BTCPP_format=\"4\" xmlns:x=\"urn:x\">\n  <BehaviorTree ID=\"A\">\n    <AlwaysSuccess x:note=\"1\"/>\n  </BehaviorTree>\n</root>";
    assert!(matches!(
        error(text).kind(),
        BtXmlErrorKind::Namespace { .. }
    ));

    // 100 elements of 9,000 attributes: the parser compares an element's attributes pairwise
    // (18 s); now the document is refused at the element whose pairs pass 50 million.
    let mut text = String::from("<root BTCPP_format=\"4\"><TreeNodesModel>\n");
    let attributes: String = (0..9_000).map(|i| format!(" a{i}=\"\"")).collect();
    for i in 0..100 {
        let _ = std::fmt::Write::write_fmt(
            &mut text,
            format_args!("<Action ID=\"X{i}\"{attributes}/>\n"),
        );
    }
    text.push_str("</TreeNodesModel><BehaviorTree ID=\"A\"><AlwaysSuccess/></BehaviorTree></root>");
    let e = parse_bt_xml("pairs.xml", &text, &Registry::new()).unwrap_err();
    assert!(
        matches!(
            e.kind(),
            BtXmlErrorKind::TooManyAttributePairs { limit: 50_000_000 }
        ),
        "{e}"
    );
    assert_eq!((e.line(), e.column()), (Some(3), Some(1)));
}

#[test]
fn a_model_with_many_ports_used_by_many_nodes_is_checked_in_linear_time() {
    // One model of 20,000 ports and 20,000 nodes using it: validation copied and indexed the
    // model's ports once per node (minutes); now once.
    let mut text = String::from("<root BTCPP_format=\"4\"><TreeNodesModel><Action ID=\"Big\">\n");
    for i in 0..20_000 {
        let _ = std::fmt::Write::write_fmt(
            &mut text,
            format_args!("<input_port name=\"p{i}\" default=\"{i}\"/>\n"),
        );
    }
    text.push_str("</Action></TreeNodesModel>\n<BehaviorTree ID=\"A\"><Sequence>\n");
    text.push_str(&"<Big p0=\"1\"/>\n".repeat(20_000));
    text.push_str("<Big p20000=\"1\"/>\n</Sequence></BehaviorTree></root>");
    let e = parse_bt_xml("t.xml", &text, &Registry::new()).unwrap_err();
    assert_at(&e, &text, "p20000=", Some("p20000"));
    assert_eq!(e.line(), Some(40_004));
}
