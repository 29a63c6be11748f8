//! A topological map as the service holds it: its edge models, where its nodes are drawn
//! (computed once at start) and the time span the models learned from.

use std::fmt;

use chronomap_core::TemporalModel;
use chronomap_topo::edges::EdgeModels;
use chronomap_topo::layout::stress_layout;
use chronomap_topo::map::TopoMap;

/// Distance between neighbours in a computed layout: positions are then in edge lengths, not
/// metres.
pub const COMPUTED_EDGE_LENGTH: f64 = 1.0;

/// Most missing nodes an error names one by one.
const NAMED_MISSING: usize = 10;

/// Where the positions of a map's nodes come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PositionSource {
    /// A layout file gave every node a position (metres).
    File,
    /// The edge models' own map has a pose for every node (metres).
    Model,
    /// Neither: stress majorization of hop distances
    /// ([`stress_layout`] with [`COMPUTED_EDGE_LENGTH`]), not metric.
    Computed,
}

impl PositionSource {
    /// `file`, `model` or `computed`, as `GET /v1/topo/{name}` says.
    pub fn as_str(self) -> &'static str {
        match self {
            PositionSource::File => "file",
            PositionSource::Model => "model",
            PositionSource::Computed => "computed",
        }
    }
}

/// A layout file that does not place every node of the map.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MissingPositions {
    /// The layout file, as given.
    pub file: String,
    /// Nodes of the map without a (non-synthetic, finite) position in the file, in map order.
    pub missing: Vec<String>,
    /// Nodes of the map.
    pub nodes: usize,
}

impl fmt::Display for MissingPositions {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let named: Vec<&str> = self
            .missing
            .iter()
            .take(NAMED_MISSING)
            .map(String::as_str)
            .collect();
        write!(
            f,
            "{}: no position for {} of the {} nodes of the map: {}",
            self.file,
            self.missing.len(),
            self.nodes,
            named.join(", ")
        )?;
        if self.missing.len() > NAMED_MISSING {
            write!(f, " and {} more", self.missing.len() - NAMED_MISSING)?;
        }
        Ok(())
    }
}

impl std::error::Error for MissingPositions {}

/// A topological map served read-only.
#[derive(Debug)]
pub struct ServedTopo {
    models: EdgeModels,
    source: PositionSource,
    layout_file: Option<String>,
    positions: Vec<[f64; 2]>,
    span: (Option<f64>, Option<f64>),
}

impl ServedTopo {
    /// Serves `models` with the poses of their own map if every node has one, else with a
    /// computed layout.
    pub fn new(models: EdgeModels) -> Self {
        let map = models.map();
        let (source, positions) = match map
            .nodes()
            .iter()
            .map(|n| n.pose.map(|p| [p[0], p[1]]))
            .collect::<Option<Vec<_>>>()
        {
            Some(positions) if !map.nodes().is_empty() => (PositionSource::Model, positions),
            _ => (
                PositionSource::Computed,
                stress_layout(map, COMPUTED_EDGE_LENGTH),
            ),
        };
        ServedTopo::with(models, source, None, positions)
    }

    /// Serves `models` with the node positions of `layout`, read from `file` (a tmap2 map or
    /// a Nav2 route graph): every node of the models' map must have a position there (by
    /// name; synthetic positions do not count); other nodes of the file are ignored.
    ///
    /// # Errors
    /// The nodes without a position, naming `file`.
    pub fn with_layout(
        models: EdgeModels,
        file: &str,
        layout: &TopoMap,
    ) -> Result<Self, MissingPositions> {
        let map = models.map();
        let mut positions = Vec::with_capacity(map.nodes().len());
        let mut missing = Vec::new();
        for node in map.nodes() {
            let pose = layout
                .node(&node.name)
                .ok()
                .and_then(|i| layout.nodes()[i].pose)
                .filter(|p| p[0].is_finite() && p[1].is_finite());
            match pose {
                Some(p) => positions.push([p[0], p[1]]),
                None => missing.push(node.name.clone()),
            }
        }
        if !missing.is_empty() {
            return Err(MissingPositions {
                file: file.to_owned(),
                missing,
                nodes: map.nodes().len(),
            });
        }
        Ok(ServedTopo::with(
            models,
            PositionSource::File,
            Some(file.to_owned()),
            positions,
        ))
    }

    fn with(
        models: EdgeModels,
        source: PositionSource,
        layout_file: Option<String>,
        positions: Vec<[f64; 2]>,
    ) -> Self {
        let span = training_span(&models);
        ServedTopo {
            models,
            source,
            layout_file,
            positions,
            span,
        }
    }

    /// The edge models.
    pub fn models(&self) -> &EdgeModels {
        &self.models
    }

    /// Where the positions come from.
    pub fn source(&self) -> PositionSource {
        self.source
    }

    /// The layout file, if one gave the positions.
    pub fn layout_file(&self) -> Option<&str> {
        self.layout_file.as_deref()
    }

    /// `[x, y]` of every node, index-aligned with the map's nodes.
    pub fn positions(&self) -> &[[f64; 2]] {
        &self.positions
    }

    /// First and last time of the attempts the models learned from (see [`training_span`]).
    pub fn span(&self) -> (Option<f64>, Option<f64>) {
        self.span
    }
}

/// The time span of the attempts `models` learned from: the first is the earliest
/// observation of any edge's success or duration model (an edge with too few attempts for a
/// model keeps no times, so with such edges the true first attempt may be earlier); the last
/// is [`EdgeModels::last_time`], the latest attempt of any edge.
pub fn training_span(models: &EdgeModels) -> (Option<f64>, Option<f64>) {
    let first = (0..models.map().edges().len())
        .flat_map(|e| {
            let edge = models.edge(e);
            [edge.success_model(), edge.duration_model()]
        })
        .flatten()
        .map(|m| m.span())
        .filter(|s| s.count > 0)
        .map(|s| s.first)
        .min_by(f64::total_cmp);
    (first, models.last_time())
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_topo::edges::{Attempt, EdgeModelConfig};

    fn models(poses: bool) -> EdgeModels {
        let mut map = TopoMap::new();
        for (i, name) in ["A", "B", "C"].iter().enumerate() {
            map.add_node(name, poses.then_some([i as f64, 2.0 * i as f64, 0.0]))
                .unwrap();
        }
        map.add_edge("A_B", "A", "B").unwrap();
        map.add_edge("B_C", "B", "C").unwrap();
        let attempts = |t0: f64| -> Vec<Attempt> {
            (0..20)
                .map(|k| Attempt {
                    time: t0 + 600.0 * f64::from(k),
                    duration_secs: 30.0,
                    success: k % 3 != 0,
                })
                .collect()
        };
        let config = EdgeModelConfig {
            min_attempts: 5,
            ..EdgeModelConfig::default()
        };
        EdgeModels::fit(map, &[attempts(1000.0), attempts(400.0)], config).unwrap()
    }

    #[test]
    fn positions_come_from_the_model_a_file_or_a_layout() {
        let served = ServedTopo::new(models(true));
        assert_eq!(served.source(), PositionSource::Model);
        assert_eq!(served.positions(), [[0.0, 0.0], [1.0, 2.0], [2.0, 4.0]]);
        assert_eq!(served.span(), (Some(400.0), Some(1000.0 + 600.0 * 19.0)));

        let bare = models(false);
        let served = ServedTopo::new(bare.clone());
        assert_eq!(served.source(), PositionSource::Computed);
        assert_eq!(
            served.positions(),
            stress_layout(bare.map(), COMPUTED_EDGE_LENGTH)
        );

        // A file with extra nodes, one of them synthetic.
        let mut layout = TopoMap::new();
        layout.add_node("C", Some([5.0, 6.0, 1.0])).unwrap();
        layout.add_node("Z", None).unwrap();
        layout.add_node("A", Some([1.0, 2.0, 0.0])).unwrap();
        layout.add_node("B", Some([3.0, 4.0, 0.0])).unwrap();
        let served = ServedTopo::with_layout(bare.clone(), "lab.geojson", &layout).unwrap();
        assert_eq!(served.source(), PositionSource::File);
        assert_eq!(served.layout_file(), Some("lab.geojson"));
        assert_eq!(served.positions(), [[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]]);

        let mut partial = TopoMap::new();
        partial.add_node("B", Some([3.0, 4.0, 0.0])).unwrap();
        partial.add_node("C", None).unwrap();
        let err = ServedTopo::with_layout(bare, "lab.yaml", &partial).unwrap_err();
        assert_eq!(
            err.to_string(),
            "lab.yaml: no position for 2 of the 3 nodes of the map: A, C"
        );
    }

    #[test]
    fn a_long_list_of_missing_nodes_is_cut_after_ten() {
        let err = MissingPositions {
            file: "f.yaml".into(),
            missing: (0..13).map(|i| format!("N{i}")).collect(),
            nodes: 20,
        };
        assert_eq!(
            err.to_string(),
            "f.yaml: no position for 13 of the 20 nodes of the map: \
             N0, N1, N2, N3, N4, N5, N6, N7, N8, N9 and 3 more"
        );
    }
}
