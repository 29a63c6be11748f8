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

    let text = wrap("    <IfThenElse>\n      <AlwaysSuccess/>\n    </IfThenElse>");
    let e = error(&text);
    assert!(
        e.to_string().ends_with(
            "\"IfThenElse\" is a BehaviorTree.CPP node that chronomap does not implement"
        ),
        "{e}"
    );
}

#[test]
fn missing_required_attributes_and_bad_numbers_are_located() {
    check_wrapped_rows(&[
        (
            "    <Repeat>\n      <AlwaysSuccess/>\n    </Repeat>",
            "<Repeat>",
            Some("num_cycles"),
            "\"Repeat\" needs the attribute \"num_cycles\"",
        ),
        (
            "    <Parallel success_count=\"3\">\n      <AlwaysSuccess/>\n      <AlwaysSuccess/>\n    </Parallel>",
            "success_count=",
            Some("success_count"),
            "Parallel success_count=\"3\" needs 3 children but it has 2",
        ),
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
    assert_at(&e, text, "<include", None);

    let text = "<root BTCPP_format=\"4\">\n  <BehaviourTree ID=\"A\"/>\n</root>";
    assert_at(&error(text), text, "<BehaviourTree", None);

    let text = "<bt>\n</bt>";
    assert!(
        error(text)
            .to_string()
            .starts_with("t.xml:1:1: the root element is <bt>")
    );

    let text = wrap("    <AlwaysSuccess _skipIf=\"battery &lt; 10\"/>");
    let e = error(&text);
    assert_at(&e, &text, "_skipIf", Some("_skipIf"));
    assert!(e.to_string().contains("scripting"));

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
