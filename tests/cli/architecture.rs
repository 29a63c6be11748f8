//! The layers of ARCHITECTURE.md hold: every crate of the workspace sits in exactly one layer of
//! its "Layers" table, and every dependency of a crate (not its dev-dependencies) points to a
//! strictly lower layer, so data flow one way, observations → models → predictions → decisions,
//! and the faces sit on top. Read from `cargo metadata`, the source of truth cargo builds from,
//! so neither the drawing nor a `Cargo.toml` can drift alone.

use std::collections::BTreeMap;
use std::process::Command;

use serde_json::Value;

/// The layers table of ARCHITECTURE.md: crate name → (layer number, layer name). Rows are
/// `| N | name | `crate`, `crate` |` under the heading `## Layers`.
fn layers() -> BTreeMap<String, (u32, String)> {
    let doc = include_str!("../../ARCHITECTURE.md");
    let section = doc
        .split("\n## Layers\n")
        .nth(1)
        .expect("ARCHITECTURE.md has a `## Layers` section")
        .split("\n## ")
        .next()
        .unwrap();
    let mut layers = BTreeMap::new();
    for row in section.lines().filter(|l| l.starts_with('|')) {
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        let Ok(number) = cells[1].parse::<u32>() else {
            continue; // the header and its rule
        };
        for name in cells[3].split('`').skip(1).step_by(2) {
            let previous = layers.insert(name.to_string(), (number, cells[2].to_string()));
            assert!(
                previous.is_none(),
                "{name} is in two layers of ARCHITECTURE.md"
            );
        }
    }
    layers
}

/// Each workspace package and the workspace packages it depends on (normal and build
/// dependencies; dev-dependencies only build tests).
fn dependencies() -> BTreeMap<String, Vec<String>> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "cargo metadata: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let metadata: Value = serde_json::from_slice(&out.stdout).unwrap();
    let packages = metadata["packages"].as_array().unwrap();
    let members: Vec<&str> = packages
        .iter()
        .map(|p| p["name"].as_str().unwrap())
        .collect();
    packages
        .iter()
        .map(|p| {
            let deps = p["dependencies"]
                .as_array()
                .unwrap()
                .iter()
                .filter(|d| d["kind"].as_str() != Some("dev"))
                .map(|d| d["name"].as_str().unwrap())
                .filter(|name| members.contains(name))
                .map(str::to_string)
                .collect();
            (p["name"].as_str().unwrap().to_string(), deps)
        })
        .collect()
}

#[test]
fn every_crate_is_in_one_layer_and_depends_only_on_lower_layers() {
    let layers = layers();
    let dependencies = dependencies();
    for name in dependencies.keys() {
        assert!(
            layers.contains_key(name),
            "{name} is in no layer of ARCHITECTURE.md's `## Layers` table"
        );
    }
    for name in layers.keys() {
        assert!(
            dependencies.contains_key(name),
            "ARCHITECTURE.md's layers name {name}, which is not a workspace crate"
        );
    }
    let mut upward = Vec::new();
    for (name, deps) in &dependencies {
        let (layer, layer_name) = &layers[name];
        for dep in deps {
            let (dep_layer, dep_layer_name) = &layers[dep];
            if dep_layer >= layer {
                upward.push(format!(
                    "{name} (layer {layer}, {layer_name}) depends on {dep} (layer {dep_layer}, \
                     {dep_layer_name})"
                ));
            }
        }
    }
    assert!(
        upward.is_empty(),
        "dependencies that do not point down a layer:\n{}",
        upward.join("\n")
    );
}

/// The test helpers are only ever a dev-dependency, and the layers really are layers: the known
/// faces sit above the application layer, which sits above every domain.
#[test]
fn the_faces_sit_on_the_application_layer_and_test_helpers_build_only_tests() {
    let layers = layers();
    let dependencies = dependencies();
    for (name, deps) in &dependencies {
        assert!(
            !deps.iter().any(|d| d == "chronomap-testutil"),
            "{name} depends on chronomap-testutil outside its tests"
        );
    }
    let app = layers["chronomap-app"].0;
    for face in [
        "chronomap",
        "chronomap-serve",
        "chronomap-ros2",
        "chronomap-python",
    ] {
        assert!(layers[face].0 > app, "{face} is not above chronomap-app");
    }
    for domain in [
        "chronomap-core",
        "chronomap-grid",
        "chronomap-topo",
        "chronomap-io",
    ] {
        assert!(
            layers[domain].0 < app,
            "{domain} is not below chronomap-app"
        );
    }
}
