//! Topological maps: named places and the directed edges (navigation actions) between them
//! ([Fentanes 2015] §III: `T = ⟨V, E, …⟩`).

use std::collections::HashMap;

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// A node of a topological map.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Node {
    /// Unique name (the label tasks refer to).
    pub name: String,
    /// Position `[x, y, yaw]` in the map frame, if known.
    pub pose: Option<[f64; 3]>,
}

/// A directed edge: a navigation action from one node to another.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Edge {
    /// Unique action name (e.g. `LabDoor1_LabDoor2`).
    pub id: String,
    /// Index of the source node.
    pub from: usize,
    /// Index of the target node.
    pub to: usize,
}

/// Why a topological map could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum TopoError {
    /// Two nodes with the same name.
    #[error("node {0:?} is defined twice")]
    DuplicateNode(String),
    /// Two edges with the same id.
    #[error("edge {0:?} is defined twice")]
    DuplicateEdge(String),
    /// A name that is not a node of the map.
    #[error("unknown node {name:?}{}", suggestion.as_ref().map(|s| format!(" (did you mean {s:?}?)")).unwrap_or_default())]
    UnknownNode {
        /// The name given.
        name: String,
        /// The closest node name, if any is close.
        suggestion: Option<String>,
    },
    /// An empty or otherwise invalid name.
    #[error("invalid name {0:?}: names are non-empty and contain no whitespace")]
    InvalidName(String),
}

/// A topological map: nodes and directed edges.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TopoMap {
    nodes: Vec<Node>,
    edges: Vec<Edge>,
    #[serde(skip)]
    index: HashMap<String, usize>,
}

impl TopoMap {
    /// An empty map.
    pub fn new() -> Self {
        TopoMap::default()
    }

    /// Adds a node and returns its index.
    ///
    /// # Errors
    /// A duplicate or invalid name.
    pub fn add_node(&mut self, name: &str, pose: Option<[f64; 3]>) -> Result<usize, TopoError> {
        check_name(name)?;
        if self.index.contains_key(name) {
            return Err(TopoError::DuplicateNode(name.to_string()));
        }
        self.nodes.push(Node {
            name: name.to_string(),
            pose,
        });
        self.index.insert(name.to_string(), self.nodes.len() - 1);
        Ok(self.nodes.len() - 1)
    }

    /// Index of a node, adding it (without pose) if it is new.
    ///
    /// # Errors
    /// An invalid name.
    pub fn node_or_insert(&mut self, name: &str) -> Result<usize, TopoError> {
        match self.index.get(name) {
            Some(&i) => Ok(i),
            None => self.add_node(name, None),
        }
    }

    /// Adds an edge `from → to` with action name `id` and returns its index.
    ///
    /// # Errors
    /// Unknown nodes, an invalid or duplicate id.
    pub fn add_edge(&mut self, id: &str, from: &str, to: &str) -> Result<usize, TopoError> {
        check_name(id)?;
        if self.edges.iter().any(|e| e.id == id) {
            return Err(TopoError::DuplicateEdge(id.to_string()));
        }
        let (from, to) = (self.node(from)?, self.node(to)?);
        self.edges.push(Edge {
            id: id.to_string(),
            from,
            to,
        });
        Ok(self.edges.len() - 1)
    }

    /// Index of a node by name.
    ///
    /// # Errors
    /// [`TopoError::UnknownNode`] with the closest name as a suggestion.
    pub fn node(&self, name: &str) -> Result<usize, TopoError> {
        self.index
            .get(name)
            .copied()
            .ok_or_else(|| TopoError::UnknownNode {
                name: name.to_string(),
                suggestion: self.closest(name),
            })
    }

    /// The nodes.
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// The edges.
    pub fn edges(&self) -> &[Edge] {
        &self.edges
    }

    /// Indices of the edges leaving a node.
    pub fn out_edges(&self, node: usize) -> impl Iterator<Item = usize> + '_ {
        self.edges
            .iter()
            .enumerate()
            .filter(move |(_, e)| e.from == node)
            .map(|(i, _)| i)
    }

    /// Rebuilds the name index (after deserialisation).
    pub fn reindex(&mut self) {
        self.index = self
            .nodes
            .iter()
            .enumerate()
            .map(|(i, n)| (n.name.clone(), i))
            .collect();
    }

    /// The node name closest to `name` by edit distance, if it is close (≤ 3 edits).
    fn closest(&self, name: &str) -> Option<String> {
        self.nodes
            .iter()
            .map(|n| {
                (
                    edit_distance(&n.name.to_lowercase(), &name.to_lowercase()),
                    &n.name,
                )
            })
            .filter(|(d, _)| *d <= 3)
            .min_by_key(|(d, _)| *d)
            .map(|(_, n)| n.clone())
    }
}

fn check_name(name: &str) -> Result<(), TopoError> {
    if name.is_empty() || name.chars().any(char::is_whitespace) {
        return Err(TopoError::InvalidName(name.to_string()));
    }
    Ok(())
}

/// Levenshtein distance.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut previous = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let current = row[j + 1];
            row[j + 1] = (previous + usize::from(ca != cb))
                .min(row[j] + 1)
                .min(current + 1);
            previous = current;
        }
    }
    row[b.len()]
}

/// A map from node names and `(id, from, to)` edges, for tests.
#[cfg(test)]
pub(crate) fn test_map(nodes: &[&str], edges: &[(&str, &str, &str)]) -> TopoMap {
    let mut map = TopoMap::new();
    for n in nodes {
        map.add_node(n, None).unwrap();
    }
    for (id, from, to) in edges {
        map.add_edge(id, from, to).unwrap();
    }
    map
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builds_a_map_and_suggests_names() {
        let mut map = TopoMap::new();
        map.add_node("LabDoor1", None).unwrap();
        map.add_node("LabDoor2", Some([1.0, 2.0, 0.0])).unwrap();
        map.add_edge("LabDoor1_LabDoor2", "LabDoor1", "LabDoor2")
            .unwrap();
        assert_eq!(map.out_edges(0).collect::<Vec<_>>(), vec![0]);
        assert_eq!(
            map.add_node("LabDoor1", None),
            Err(TopoError::DuplicateNode("LabDoor1".into()))
        );
        let err = map.node("labdor1").unwrap_err();
        assert_eq!(
            err.to_string(),
            "unknown node \"labdor1\" (did you mean \"LabDoor1\"?)"
        );
        assert!(map.add_edge("x", "LabDoor1", "Kitchen").is_err());
        assert!(map.add_node("two words", None).is_err());
        assert_eq!(edit_distance("kitten", "sitting"), 3);
    }
}
