//! The README stays true: its library example is `examples/door.rs` (which `cargo test`
//! compiles), and it shows the two fresh-machine commands that CI runs.

#[test]
fn readme_example_is_the_compiled_example() {
    let readme = include_str!("../../README.md");
    let example = include_str!("../../examples/door.rs");
    let body = example
        .split("// README:BEGIN\n")
        .nth(1)
        .and_then(|rest| rest.split("    // README:END").next())
        .expect("markers in examples/door.rs");
    for line in body.lines() {
        let line = line.strip_prefix("    ").unwrap_or(line);
        assert!(
            readme.contains(line),
            "README lacks the example line {line:?}"
        );
    }
}

#[test]
fn readme_shows_the_two_commands_and_ci_runs_the_test_one() {
    let readme = include_str!("../../README.md");
    assert!(readme.contains("cargo run --release -- demo"));
    assert!(readme.contains("cargo test --workspace"));
    let ci = include_str!("../../.ci/run");
    assert!(ci.contains("cargo test --workspace"));
}
