//! Bounds: deep trees are refused before anything recurses, the deepest allowed tree ticks and
//! halts without overflowing the stack, wide trees instantiate in linear time, out-of-range
//! ports and bad scripts are definition errors naming the node and the attribute.

use std::time::{Duration, Instant};

use chronomap_bt::{
    BtDocument, DefinitionErrorKind, MAX_DEPTH, NodeDef, Registry, Status, Tree, TreeDef,
};

fn doc(root: NodeDef) -> BtDocument {
    BtDocument::single(TreeDef::new("Main", root))
}

/// `levels` nodes: a chain of inverters around `AlwaysSuccess`.
fn inverter_chain(levels: usize) -> NodeDef {
    let mut node = NodeDef::action("AlwaysSuccess");
    for _ in 1..levels {
        node = NodeDef::decorator("Inverter").child(node);
    }
    node
}

#[test]
fn a_chain_of_10000_inverters_is_refused_not_a_stack_overflow() {
    let e = Tree::new(&doc(inverter_chain(10_000)), &Registry::new()).unwrap_err();
    assert_eq!(*e.kind(), DefinitionErrorKind::TooDeep { max: MAX_DEPTH });
    let text = e.to_string();
    assert!(
        text.contains("tree nesting deeper than 1000 levels"),
        "{text}"
    );
    assert_eq!(e.location().unwrap().path.len(), MAX_DEPTH);
    // The description is dropped iteratively enough for this depth (NodeDef's own Drop).
}

#[test]
fn the_deepest_allowed_tree_ticks_and_halts() {
    // MAX_DEPTH levels: 999 inverters (an odd number: failure) around AlwaysSuccess.
    let mut tree = Tree::new(&doc(inverter_chain(MAX_DEPTH)), &Registry::new()).unwrap();
    assert_eq!(tree.tick_once(Duration::ZERO).unwrap(), Status::Failure);
    tree.halt(Duration::ZERO);
    assert!(Tree::new(&doc(inverter_chain(MAX_DEPTH + 1)), &Registry::new()).is_err());
}

#[test]
fn subtrees_count_towards_the_depth() {
    // Each tree is shallow, but nesting them through SubTree nodes exceeds the limit.
    let mut trees = Vec::new();
    let per_tree = 100;
    let count = MAX_DEPTH / per_tree + 1;
    for k in 0..count {
        let mut node = if k + 1 == count {
            NodeDef::action("AlwaysSuccess")
        } else {
            NodeDef::subtree(&format!("T{}", k + 1))
        };
        for _ in 1..per_tree {
            node = NodeDef::decorator("ForceSuccess").child(node);
        }
        trees.push(TreeDef::new(&format!("T{k}"), node));
    }
    let doc = BtDocument {
        main_tree: Some("T0".into()),
        trees,
        node_models: Vec::new(),
    };
    let e = Tree::new(&doc, &Registry::new()).unwrap_err();
    assert_eq!(*e.kind(), DefinitionErrorKind::TooDeep { max: MAX_DEPTH });
}

#[test]
fn wide_trees_instantiate_and_tick_in_linear_time() {
    // uids are 16-bit (Groot2), so 65 000 siblings is about the widest tree there is.
    let n = 65_000;
    let mut root = NodeDef::control("Sequence");
    root.children = (0..n).map(|_| NodeDef::action("AlwaysSuccess")).collect();
    let doc = doc(root);
    let start = Instant::now();
    let mut tree = Tree::new(&doc, &Registry::new()).unwrap();
    assert_eq!(tree.tick_once(Duration::ZERO).unwrap(), Status::Success);
    let elapsed = start.elapsed();
    // Generous: a quadratic scan of siblings would take minutes; linear takes milliseconds
    // in release and well under a second in a debug build.
    assert!(elapsed < Duration::from_secs(20), "{elapsed:?}");

    let mut root = NodeDef::control("Sequence");
    root.children = (0..100_000)
        .map(|_| NodeDef::action("AlwaysSuccess"))
        .collect();
    let e = Tree::new(
        &BtDocument::single(TreeDef::new("Main", root)),
        &Registry::new(),
    )
    .unwrap_err();
    assert_eq!(*e.kind(), DefinitionErrorKind::TooManyNodes);
}

/// What strict validation (`chronomap bt check`) says of `root`; the tree still loads, as
/// BehaviorTree.CPP loads it (it refuses such values only when it ticks the node, or never).
#[track_caller]
fn refused(root: NodeDef, attribute: &str) -> String {
    let doc = doc(root);
    let e = chronomap_bt::validate_strict(&doc, &Registry::new()).unwrap_err();
    assert_eq!(e.attribute(), Some(attribute), "{e}");
    Tree::new(&doc, &Registry::new()).unwrap();
    e.to_string()
}

#[test]
fn out_of_range_ports_are_refused_with_the_port_named() {
    let child = || NodeDef::action("AlwaysSuccess");
    let text = refused(
        NodeDef::decorator("RetryUntilSuccessful")
            .port("num_attempts", "-5")
            .child(child()),
        "num_attempts",
    );
    assert!(text.contains("num_attempts"), "{text}");
    refused(
        NodeDef::decorator("Repeat")
            .port("num_cycles", "-3")
            .child(child()),
        "num_cycles",
    );
    // Negative times are not unsigned integers: BehaviorTree.CPP refuses them when it loads
    // the tree, and so does instantiation here.
    for (root, port) in [
        (
            NodeDef::decorator("Timeout")
                .port("msec", "-1")
                .child(child()),
            "msec",
        ),
        (
            NodeDef::decorator("Delay")
                .port("delay_msec", "-10")
                .child(child()),
            "delay_msec",
        ),
        (NodeDef::action("Sleep").port("msec", "-1"), "msec"),
    ] {
        let e = Tree::new(&doc(root), &Registry::new()).unwrap_err();
        assert_eq!(e.attribute(), Some(port), "{e}");
    }
    refused(
        NodeDef::control("ParallelAll")
            .port("max_failures", "3")
            .child(child())
            .child(child()),
        "max_failures",
    );
    refused(
        NodeDef::decorator("LoopInt")
            .port("queue", "1;2")
            .port("if_empty", "MAYBE")
            .child(child()),
        "if_empty",
    );
    // -1 is "forever" and stays allowed.
    assert!(
        Tree::new(
            &doc(NodeDef::decorator("Repeat")
                .port("num_cycles", "-1")
                .child(child())),
            &Registry::new()
        )
        .is_ok()
    );
}

#[test]
fn wrong_numbers_of_children_are_refused() {
    let leaf = || NodeDef::action("AlwaysSuccess");
    for (id, children) in [
        ("IfThenElse", 1),
        ("IfThenElse", 4),
        ("WhileDoElse", 1),
        ("Switch2", 2),
        ("TryCatch", 1),
    ] {
        let mut node = NodeDef::control(id);
        node.children = (0..children).map(|_| leaf()).collect();
        let doc = doc(node);
        let e = chronomap_bt::validate_strict(&doc, &Registry::new()).unwrap_err();
        assert!(
            matches!(e.kind(), DefinitionErrorKind::WrongChildren { .. }),
            "{id} with {children}: {e}"
        );
        // BehaviorTree.CPP loads these and throws at the first tick (TryCatch, of 4.9, when
        // it parses the tree).
        match Tree::new(&doc, &Registry::new()) {
            Ok(mut tree) => {
                let e = tree.tick_once(Duration::ZERO).unwrap_err();
                assert!(e.to_string().contains("children"), "{id}: {e}");
            }
            Err(e) => assert_eq!(id, "TryCatch", "{e}"),
        }
    }
}

#[test]
fn script_syntax_errors_name_the_node_and_the_attribute() {
    let e = Tree::new(
        &doc(NodeDef::action("Script")
            .named("init")
            .port("code", "A := ")),
        &Registry::new(),
    )
    .unwrap_err();
    assert_eq!(e.attribute(), Some("code"));
    assert!(
        matches!(e.kind(), DefinitionErrorKind::BadScript { .. }),
        "{e}"
    );

    let e = Tree::new(
        &doc(NodeDef::action("AlwaysSuccess").script("_skipIf", "A ==")),
        &Registry::new(),
    )
    .unwrap_err();
    assert_eq!(e.attribute(), Some("_skipIf"));
    let text = e.to_string();
    assert!(
        text.contains("AlwaysSuccess") && text.contains("syntax error"),
        "{text}"
    );

    let e = Tree::new(
        &doc(NodeDef::action("AlwaysSuccess").script("_onStart", "A := 1")),
        &Registry::new(),
    )
    .unwrap_err();
    assert_eq!(e.attribute(), Some("_onStart"));

    let deep = format!("{}1{}", "(".repeat(5000), ")".repeat(5000));
    let e = Tree::new(
        &doc(NodeDef::condition("ScriptCondition").port("code", &deep)),
        &Registry::new(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("nested deeper"), "{e}");
}

#[test]
fn validation_alone_finds_what_instantiation_would_refuse() {
    // `chronomap bt check` validates without instantiating: a script that does not parse, an
    // unknown `_` attribute, a wrong number of children and an out-of-range built-in port are
    // found there too, at the node and attribute concerned.
    let registry = Registry::new();
    let check = |root: NodeDef| {
        chronomap_bt::validate_strict(&doc(NodeDef::control("Sequence").child(root)), &registry)
            .unwrap_err()
    };
    let e = check(NodeDef::action("AlwaysSuccess").script("_skipIf", "A :="));
    assert!(
        matches!(e.kind(), DefinitionErrorKind::BadScript { attribute, .. } if attribute == "_skipIf"),
        "{e}"
    );
    assert_eq!(e.attribute(), Some("_skipIf"));
    assert_eq!(e.location().map(|l| l.path.clone()), Some(vec![0]));
    let e = check(NodeDef::action("Script").port("code", "x := (1 + "));
    assert_eq!(e.attribute(), Some("code"), "{e}");
    let e = check(NodeDef::action("AlwaysSuccess").script("_onTick", "x := 1"));
    assert_eq!(e.attribute(), Some("_onTick"), "{e}");
    let e = check(NodeDef::control("IfThenElse").child(NodeDef::action("AlwaysSuccess")));
    assert!(
        matches!(
            e.kind(),
            DefinitionErrorKind::WrongChildren { found: 1, .. }
        ),
        "{e}"
    );
    let e = check(
        NodeDef::decorator("Delay")
            .port("delay_msec", "-5")
            .child(NodeDef::action("AlwaysSuccess")),
    );
    assert_eq!(e.attribute(), Some("delay_msec"), "{e}");
}

/// A document of `count` trees, each the `SubTree` of the next (the last a leaf).
fn subtree_chain(count: usize) -> BtDocument {
    let trees = (0..count)
        .map(|i| {
            let root = if i + 1 < count {
                NodeDef::subtree(&format!("T{}", i + 1))
            } else {
                NodeDef::action("AlwaysSuccess")
            };
            TreeDef::new(&format!("T{i}"), root)
        })
        .collect();
    BtDocument {
        main_tree: Some("T0".to_owned()),
        trees,
        node_models: Vec::new(),
    }
}

#[test]
fn a_chain_of_100000_subtrees_is_validated_without_recursion_in_linear_time() {
    // The search for recursive subtrees recursed once per tree of a chain (a stack overflow
    // here) and searched the chain for each tree (quadratic).
    let doc = subtree_chain(100_000);
    chronomap_bt::validate(&doc, &Registry::new()).unwrap();
    // Instantiating it is refused at the depth limit, in the tree where it is passed.
    let e = Tree::new(&doc, &Registry::new()).unwrap_err();
    assert_eq!(*e.kind(), DefinitionErrorKind::TooDeep { max: MAX_DEPTH });
    assert_eq!(e.location().unwrap().tree, "T1000");
    // A cycle at its end is found, with the whole chain.
    let mut doc = doc;
    let last = doc.trees.len() - 1;
    doc.trees[last].root = NodeDef::subtree("T50000");
    let e = chronomap_bt::validate(&doc, &Registry::new()).unwrap_err();
    let DefinitionErrorKind::RecursiveSubTree { chain } = e.kind() else {
        panic!("{e}");
    };
    assert_eq!(chain.len(), 50_001);
    assert_eq!(
        (chain[0].as_str(), chain[50_000].as_str()),
        ("T50000", "T50000")
    );
}

#[test]
fn a_description_100000_deep_is_validated_and_refused_without_recursion() {
    // Validation walked descriptions recursively (a stack overflow at this depth).
    let mut doc = doc(inverter_chain(100_000));
    chronomap_bt::validate(&doc, &Registry::new()).unwrap();
    let e = Tree::new(&doc, &Registry::new()).unwrap_err();
    assert_eq!(*e.kind(), DefinitionErrorKind::TooDeep { max: MAX_DEPTH });
    assert_eq!(e.location().unwrap().path.len(), MAX_DEPTH);
    // Dropping a `NodeDef` recurses: take the chain apart from the top.
    let mut node = std::mem::replace(&mut doc.trees[0].root, NodeDef::action("AlwaysSuccess"));
    while let Some(child) = node.children.pop() {
        node = child;
    }
}

#[test]
fn many_models_and_a_model_with_many_ports_cost_their_size_once() {
    // 50,000 declared actions used once each, and one action with 50,000 ports with defaults
    // used by 50,000 nodes: each model was copied (or searched for) once per node using it,
    // and every node held a copy of every default (2.5 billion).
    use chronomap_bt::script::scripted_registry;
    use chronomap_bt::{NodeCategory, NodeModel, PortSpec};
    let count = 50_000;
    let mut models: Vec<NodeModel> = (0..count)
        .map(|i| NodeModel::new(NodeCategory::Action, &format!("A{i}")))
        .collect();
    let mut big = NodeModel::new(NodeCategory::Action, "Big");
    for i in 0..count {
        let mut port = PortSpec::input(&format!("p{i}"));
        port.default = Some(i.to_string());
        big.ports.push(port);
    }
    models.push(big);
    for uses in [
        (0..count)
            .map(|i| NodeDef::action(&format!("A{i}")))
            .collect::<Vec<_>>(),
        (0..count)
            .map(|_| NodeDef::action("Big").port("p7", "{x}"))
            .collect(),
    ] {
        let mut root = NodeDef::control("Sequence");
        root.children = uses;
        let doc = BtDocument {
            main_tree: Some("Main".to_owned()),
            trees: vec![TreeDef::new("Main", root)],
            node_models: models.clone(),
        };
        let (registry, _) = scripted_registry(&doc).unwrap();
        let tree = Tree::new(&doc, &registry).unwrap();
        assert_eq!(tree.nodes().len(), count + 1);
        let ports = tree.node(2).unwrap().ports();
        if tree.node(2).unwrap().id() == "Big" {
            assert_eq!(ports.len(), count);
            assert_eq!(ports[0], ("p7".to_owned(), "{x}".to_owned()));
            assert_eq!(ports[1], ("p0".to_owned(), "0".to_owned()));
        }
    }
}
