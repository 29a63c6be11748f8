//! What the cases share: a small reader of BehaviorTree.CPP 4 XML (enough for the trees of its
//! gtests: elements, attributes with the five predefined entities, comments) that builds [`NodeDef`]s — the crate
//! cannot use `chronomap-io`'s reader, which depends on it — the test leaves of the gtests'
//! `RegisterTestTick` (`TestA` … `TestD` count their ticks and succeed), and a runner with an
//! injected clock that advances 10 ms per tick.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use chronomap_bt::{
    BtDocument, NodeCategory, NodeDef, Registry, Status, Tree, TreeDef, Value, builtin_model,
};

/// One XML element.
struct Element {
    tag: String,
    attributes: Vec<(String, String)>,
    children: Vec<Element>,
}

struct Reader<'a> {
    text: &'a str,
    pos: usize,
}

impl<'a> Reader<'a> {
    fn rest(&self) -> &'a str {
        &self.text[self.pos..]
    }

    fn skip_space_and_comments(&mut self) {
        loop {
            let trimmed = self.rest().trim_start();
            self.pos = self.text.len() - trimmed.len();
            if trimmed.starts_with("<!--") {
                let end = trimmed.find("-->").expect("unterminated comment");
                self.pos += end + 3;
            } else if trimmed.starts_with("<?") {
                let end = trimmed.find("?>").expect("unterminated declaration");
                self.pos += end + 2;
            } else if !trimmed.starts_with('<') && !trimmed.is_empty() {
                // Text content: ignored.
                let end = trimmed.find('<').unwrap_or(trimmed.len());
                self.pos += end;
            } else {
                return;
            }
        }
    }

    fn name(&mut self) -> String {
        let rest = self.rest();
        let end = rest
            .find(|c: char| c.is_whitespace() || c == '/' || c == '>' || c == '=')
            .unwrap_or(rest.len());
        let name = rest[..end].to_owned();
        self.pos += end;
        name
    }

    fn element(&mut self) -> Element {
        self.skip_space_and_comments();
        assert!(
            self.rest().starts_with('<'),
            "expected an element at {}",
            self.pos
        );
        self.pos += 1;
        let tag = self.name();
        let mut attributes = Vec::new();
        loop {
            let trimmed = self.rest().trim_start();
            self.pos = self.text.len() - trimmed.len();
            if trimmed.starts_with("/>") {
                self.pos += 2;
                return Element {
                    tag,
                    attributes,
                    children: Vec::new(),
                };
            }
            if trimmed.starts_with('>') {
                self.pos += 1;
                break;
            }
            let name = self.name();
            let trimmed = self.rest().trim_start();
            assert!(trimmed.starts_with('='), "attribute {name} without value");
            let trimmed = trimmed[1..].trim_start();
            let quote = trimmed.chars().next().expect("attribute value");
            let body = &trimmed[1..];
            let end = body.find(quote).expect("unterminated attribute value");
            let value = body[..end]
                .replace("&lt;", "<")
                .replace("&gt;", ">")
                .replace("&quot;", "\"")
                .replace("&apos;", "'")
                .replace("&amp;", "&");
            attributes.push((name, value));
            self.pos = self.text.len() - body.len() + end + 1;
        }
        let mut children = Vec::new();
        loop {
            self.skip_space_and_comments();
            if self.rest().starts_with("</") {
                let end = self.rest().find('>').expect("unterminated end tag");
                self.pos += end + 1;
                return Element {
                    tag,
                    attributes,
                    children,
                };
            }
            children.push(self.element());
        }
    }
}

fn node(element: &Element, registry: &Registry) -> NodeDef {
    let attribute = |name: &str| {
        element
            .attributes
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.clone())
    };
    let (category, id, explicit) = match element.tag.as_str() {
        "SubTree" => (
            NodeCategory::SubTree,
            attribute("ID").expect("SubTree ID"),
            true,
        ),
        tag => match NodeCategory::from_tag(tag) {
            Some(category) => (category, attribute("ID").expect("explicit ID"), true),
            None => {
                let category = builtin_model(tag)
                    .map(|m| m.category)
                    .or_else(|| registry.model(tag).map(|m| m.category))
                    .unwrap_or_else(|| panic!("unknown node {tag}"));
                (category, tag.to_owned(), false)
            }
        },
    };
    let mut def = NodeDef::new(category, &id);
    for (name, value) in &element.attributes {
        match name.as_str() {
            "ID" if explicit => {}
            "name" => def.name = Some(value.clone()),
            "_autoremap" => def.autoremap = value == "true" || value == "1",
            n if n.starts_with('_') => def.scripts.push((name.clone(), value.clone())),
            _ => def.ports.push((name.clone(), value.clone())),
        }
    }
    def.children = element.children.iter().map(|c| node(c, registry)).collect();
    def
}

/// A document from BehaviorTree.CPP 4 XML; leaf categories come from `registry`.
pub fn document(xml: &str, registry: &Registry) -> BtDocument {
    let root = Reader { text: xml, pos: 0 }.element();
    assert_eq!(root.tag, "root");
    let main_tree = root
        .attributes
        .iter()
        .find(|(n, _)| n == "main_tree_to_execute")
        .map(|(_, v)| v.clone());
    let mut trees = Vec::new();
    for (k, element) in root.children.iter().enumerate() {
        if element.tag != "BehaviorTree" {
            continue;
        }
        let id = element
            .attributes
            .iter()
            .find(|(n, _)| n == "ID")
            .map_or_else(|| format!("Tree{k}"), |(_, v)| v.clone());
        assert_eq!(element.children.len(), 1, "a tree has one root");
        trees.push(TreeDef::new(&id, node(&element.children[0], registry)));
    }
    let main_tree = main_tree.or_else(|| trees.first().map(|t| t.id.clone()));
    BtDocument {
        main_tree,
        trees,
        node_models: Vec::new(),
    }
}

/// The test leaves of the gtests and the registry they are in.
pub struct Fixture {
    pub registry: Registry,
    counters: Arc<[AtomicUsize; 4]>,
}

impl Fixture {
    /// `TestA` … `TestD` (count, succeed), `KeepRunning` (always running), `AsyncSuccess` /
    /// `AsyncFailure` (running on the first tick of an execution, then success / failure).
    pub fn new() -> Fixture {
        let mut registry = Registry::new();
        let counters: Arc<[AtomicUsize; 4]> = Arc::new(Default::default());
        for (k, id) in ["TestA", "TestB", "TestC", "TestD"].into_iter().enumerate() {
            let counters = Arc::clone(&counters);
            registry
                .register_action_fn(id, move |_| {
                    counters[k].fetch_add(1, Ordering::SeqCst);
                    Ok(Status::Success)
                })
                .unwrap();
        }
        registry
            .register_action_fn("KeepRunning", |_| Ok(Status::Running))
            .unwrap();
        for (id, result) in [
            ("AsyncSuccess", Status::Success),
            ("AsyncFailure", Status::Failure),
        ] {
            registry
                .register_action_fn(id, move |ctx| {
                    Ok(if ctx.status() == Status::Running {
                        result
                    } else {
                        Status::Running
                    })
                })
                .unwrap();
        }
        Fixture { registry, counters }
    }

    /// How many times `TestA` (0), `TestB` (1), … were ticked.
    pub fn count(&self, k: usize) -> usize {
        self.counters[k].load(Ordering::SeqCst)
    }

    /// All four counters.
    pub fn counts(&self) -> [usize; 4] {
        [self.count(0), self.count(1), self.count(2), self.count(3)]
    }

    /// Registers an action whose `n`-th tick (from 1, over the whole test) returns
    /// `outcome(n)`.
    pub fn sequence_action(
        &mut self,
        id: &str,
        outcome: impl Fn(usize) -> Status + Send + Sync + 'static,
    ) -> Arc<AtomicUsize> {
        let ticks = Arc::new(AtomicUsize::new(0));
        let seen = Arc::clone(&ticks);
        self.registry
            .register_action_fn(id, move |_| {
                let n = seen.fetch_add(1, Ordering::SeqCst) + 1;
                Ok(outcome(n))
            })
            .unwrap();
        ticks
    }

    /// The tree of `xml` (its main tree), ready to run.
    pub fn run(&self, xml: &str) -> Run {
        let doc = document(xml, &self.registry);
        Run {
            tree: Tree::new(&doc, &self.registry).unwrap_or_else(|e| panic!("{e}")),
            now: Duration::ZERO,
        }
    }

    /// The error strict validation gives for the tree of `xml` (what `chronomap bt check`
    /// reports before anything runs). Where BehaviorTree.CPP only throws when it ticks the
    /// node, the tree still loads: the error of the first tick is checked with
    /// [`Fixture::tick_error`].
    pub fn refuse(&self, xml: &str) -> chronomap_bt::DefinitionError {
        let doc = document(xml, &self.registry);
        chronomap_bt::validate_strict(&doc, &self.registry).expect_err("the tree should be refused")
    }

    /// The error of the first tick of the tree of `xml`, which loads.
    pub fn tick_error(&self, xml: &str) -> chronomap_bt::TickError {
        let mut run = self.run(xml);
        run.tree
            .tick_once(Duration::from_millis(10))
            .expect_err("the first tick should fail")
    }
}

/// A tree and its clock.
pub struct Run {
    pub tree: Tree,
    pub now: Duration,
}

impl Run {
    /// One `tickOnce`, 10 ms after the previous one.
    pub fn tick(&mut self) -> Status {
        self.now += Duration::from_millis(10);
        self.tree
            .tick_once(self.now)
            .unwrap_or_else(|e| panic!("{e}"))
    }

    /// `tickWhileRunning`: ticks while the root returns running (at most 10 000 ticks).
    pub fn tick_while_running(&mut self) -> Status {
        for _ in 0..10_000 {
            let status = self.tick();
            if status != Status::Running {
                return status;
            }
        }
        panic!("still running after 10 000 ticks");
    }

    /// `haltTree`.
    pub fn halt(&mut self) {
        self.tree.halt(self.now);
    }

    /// Sets a root blackboard entry.
    pub fn set(&mut self, key: &str, value: impl Into<Value>) {
        self.tree.blackboard_mut().set(key, value).unwrap();
    }

    /// A root blackboard entry.
    pub fn get(&self, key: &str) -> Option<Value> {
        self.tree.blackboard().get(key).cloned()
    }

    /// The status of the node named `name`.
    pub fn status_of(&self, name: &str) -> Status {
        self.tree
            .nodes()
            .iter()
            .find(|n| n.name() == name)
            .unwrap_or_else(|| panic!("no node {name}"))
            .status()
    }
}

/// `<root BTCPP_format="4"><BehaviorTree ID="MainTree">body</BehaviorTree></root>`.
pub fn main_tree(body: &str) -> String {
    format!(r#"<root BTCPP_format="4"><BehaviorTree ID="MainTree">{body}</BehaviorTree></root>"#)
}
