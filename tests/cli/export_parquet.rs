//! `chronomap export parquet` on real data: a store holding the bundled greg door (96,480
//! observations, Lincoln 2016) as the models of a small fleet, exported and read back by
//! pyarrow and DuckDB as oracles, whose per-namespace counts, sums, time ranges and column
//! types must be what this test computes from the source data.
//!
//! The fleet: `robot1/door` (the door as given), `robot1/door-copy` (the same door in the
//! range [0, 100], values × 100, so its predictions have a value), `robot2/door` (junk, then
//! removed and created again, then the second half of the door: only what follows its last
//! creation is exported), and `robot3/door` (created, observed, removed: not exported).
//!
//! pyarrow runs when `CHRONOMAP_PYARROW_PYTHON` names a Python interpreter that imports
//! `pyarrow` (`.ci/run` sets it up, with `duckdb`); without it the test checks the summary
//! only and says how to enable the comparison, unless `CHRONOMAP_REQUIRE_PYARROW=1`, when it
//! fails. The PostgreSQL variant runs as the other service tests do (`CHRONOMAP_POSTGRES`).

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use chronomap_core::TemporalModel;
use chronomap_serve::log::{LogRecord, encode_group};
use chronomap_serve::registry::{ModelConfig, Registry};
use chronomap_serve::store::{RedbStore, Store};
use serde_json::Value;

use crate::common::{
    assert_mentions, chronomap, error, greg_training, json, oracle_python, scratch, usage_error,
};

/// Observations per commit group of the fleet's log.
const GROUP: usize = 5000;
/// 2016-01-04T00:00Z, the first greg observation.
const FROM: f64 = 1_451_865_600.0;
/// The prediction grid: two weeks, hourly (337 times).
const TO: f64 = FROM + 14.0 * 86_400.0;
const STEP: f64 = 3600.0;
const POINTS: usize = 337;

/// The fleet's log (commit groups) and what an export of it must hold.
struct Fleet {
    groups: Vec<Vec<LogRecord>>,
    /// Per namespace: rows, sum of values, first and last time.
    expected: BTreeMap<&'static str, (usize, f64, f64, f64)>,
    /// The models at the end of the log.
    registry: Registry,
}

fn observe(id: &str, times: &[f64], values: impl Iterator<Item = f64>) -> LogRecord {
    LogRecord::Observe {
        id: id.into(),
        times: times.to_vec(),
        values: values.collect(),
    }
}

fn fleet() -> Fleet {
    let door = greg_training();
    let (times, values) = (&door.times, &door.values);
    let n = times.len();
    assert_eq!(n, 96_480, "the bundled greg training data");
    let half = n / 2;
    let create = |id: &str, range| LogRecord::Create {
        id: id.into(),
        config: ModelConfig::parse(None, range).unwrap(),
    };
    let mut groups = vec![vec![
        create("robot1/door", None),
        create("robot1/door-copy", Some([0.0, 100.0])),
        create("robot2/door", None),
        create("robot3/door", None),
    ]];
    // robot2 and robot3 first see junk (the door inverted), which must not be exported.
    groups.push(vec![
        observe(
            "robot2/door",
            &times[..1000],
            values[..1000].iter().map(|v| 1.0 - v),
        ),
        observe(
            "robot3/door",
            &times[..2000],
            values[..2000].iter().copied(),
        ),
    ]);
    for start in (0..n).step_by(GROUP) {
        let end = (start + GROUP).min(n);
        let (t, v) = (&times[start..end], &values[start..end]);
        let mut group = vec![
            observe("robot1/door", t, v.iter().copied()),
            observe("robot1/door-copy", t, v.iter().map(|v| v * 100.0)),
        ];
        if start <= half && half < end {
            // robot2 starts again in the middle of this group's records.
            group.push(LogRecord::Remove {
                id: "robot2/door".into(),
            });
            group.push(create("robot2/door", None));
            group.push(observe(
                "robot2/door",
                &times[half..end],
                values[half..end].iter().copied(),
            ));
        } else if start > half {
            group.push(observe("robot2/door", t, v.iter().copied()));
        }
        if start == 10 * GROUP {
            group.push(LogRecord::Remove {
                id: "robot3/door".into(),
            });
        }
        groups.push(group);
    }
    let sum = |v: &[f64]| v.iter().sum::<f64>();
    let expected = BTreeMap::from([
        (
            "robot1",
            (2 * n, sum(values) * 101.0, times[0], times[n - 1]),
        ),
        (
            "robot2",
            (n - half, sum(&values[half..]), times[half], times[n - 1]),
        ),
    ]);
    let mut registry = Registry::new();
    for record in groups.iter().flatten() {
        registry.apply(record).unwrap();
    }
    assert_eq!(
        registry.ids(),
        ["robot1/door", "robot1/door-copy", "robot2/door"]
    );
    Fleet {
        groups,
        expected,
        registry,
    }
}

fn append_all(store: &dyn Store, groups: &[Vec<LogRecord>]) {
    for (i, records) in groups.iter().enumerate() {
        let seq = i as u64 + 1;
        store.append(seq, &encode_group(seq, records)).unwrap();
    }
}

/// A redb store of the fleet in `dir/data`; the data directory.
fn redb_fleet(dir: &Path, fleet: &Fleet) -> String {
    let data = dir.join("data");
    std::fs::create_dir_all(&data).unwrap();
    let store = RedbStore::open(data.join("chronomap.redb")).unwrap();
    append_all(&store, &fleet.groups);
    data.display().to_string()
}

fn grid_args() -> [String; 6] {
    [
        "--from".into(),
        "2016-01-04T00:00Z".into(),
        "--to".into(),
        TO.to_string(),
        "--step".into(),
        STEP.to_string(),
    ]
}

/// `export parquet` with `source` flags into `out`: its JSON summary, checked against `fleet`.
fn export(source: &[&str], out: &Path, fleet: &Fleet) -> Value {
    let out_arg = out.display().to_string();
    let mut args = vec!["export", "parquet", "-o", &out_arg, "--json"];
    args.extend_from_slice(source);
    let grid = grid_args();
    args.extend(grid.iter().map(String::as_str));
    let summary = json(&chronomap(&args));
    let rows: usize = fleet.expected.values().map(|e| e.0).sum();
    assert_eq!(summary["observations"]["rows"], rows, "{summary}");
    assert_eq!(summary["models"], 3);
    assert_eq!(summary["last_seq"], fleet.groups.len());
    assert_eq!(summary["predictions"]["times"], POINTS);
    assert_eq!(summary["predictions"]["rows"], 3 * POINTS);
    for table in ["observations", "predictions"] {
        let bytes = std::fs::metadata(out.join(format!("{table}.parquet")))
            .unwrap()
            .len();
        assert_eq!(summary[table]["bytes"], bytes);
    }
    summary
}

/// Reads both tables with pyarrow (and DuckDB when it is installed): per namespace and per
/// model, rows, sums, time ranges, and the column types.
const ORACLE: &str = r#"
import json, sys
import pyarrow as pa, pyarrow.compute as pc, pyarrow.parquet as pq
out = {}
for name in ("observations", "predictions"):
    path = f"{sys.argv[1]}/{name}.parquet"
    table = pq.read_table(path)
    table = table.append_column("time_us", pc.cast(table["time"], pa.int64()))
    value = "value"
    aggregates = [("time_s", "count"), (value, "count"), (value, "sum"), ("time_s", "min"),
                  ("time_s", "max"), ("time_us", "min"), ("time_us", "max")]
    if name == "predictions":
        aggregates += [("probability", "sum"), ("probability", "min"), ("probability", "max")]
    result = {"types": {f.name: [str(f.type), f.nullable] for f in table.schema if f.name != "time_us"},
              "rows": table.num_rows,
              "row_groups": pq.ParquetFile(path).num_row_groups}
    for key in ("namespace", "model_id"):
        rows = table.group_by(key).aggregate(aggregates).to_pylist()
        result[key] = {r.pop(key): r for r in rows}
    out[name] = result
try:
    import duckdb
except ImportError:
    out["duckdb"] = None
else:
    query = """SELECT namespace, count(*), sum(value), min(time_s), max(time_s),
                      epoch_us(min(time)), epoch_us(max(time)), any_value(typeof(time))
               FROM read_parquet(?) GROUP BY namespace ORDER BY namespace"""
    rows = duckdb.execute(query, [f"{sys.argv[1]}/observations.parquet"]).fetchall()
    out["duckdb"] = {r[0]: list(r[1:]) for r in rows}
print(json.dumps(out))
"#;

/// What the oracle read, or `None` when it is not installed (skipped as `oracle_python` says).
fn read_back(out: &Path) -> Option<Value> {
    let python = oracle_python(
        "PYARROW",
        "export_parquet",
        "pyarrow",
        "set CHRONOMAP_PYARROW_PYTHON to a Python with pyarrow (and duckdb); .ci/run does",
    )?;
    let output = Command::new(&python)
        .args(["-c", ORACLE])
        .arg(out)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {python}: {e}"));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "the pyarrow oracle failed:\n{stderr}"
    );
    Some(serde_json::from_slice(&output.stdout).unwrap())
}

/// The oracle's reading of `out` against what the fleet must give.
fn check_read_back(read: &Value, fleet: &Fleet) {
    let observations = &read["observations"];
    let types: BTreeMap<&str, (&str, bool)> = [
        ("namespace", ("string", false)),
        ("model_id", ("string", false)),
        ("time", ("timestamp[us, tz=UTC]", false)),
        ("time_s", ("double", false)),
        ("value", ("double", false)),
        ("seq", ("int64", false)),
    ]
    .into();
    let read_types = |table: &Value| -> BTreeMap<String, (String, bool)> {
        table["types"]
            .as_object()
            .unwrap()
            .iter()
            .map(|(k, v)| {
                let name = v[0].as_str().unwrap().to_owned();
                (k.clone(), (name, v[1].as_bool().unwrap()))
            })
            .collect()
    };
    let expect = |types: BTreeMap<&str, (&str, bool)>| -> BTreeMap<String, (String, bool)> {
        types
            .into_iter()
            .map(|(k, (t, n))| (k.to_owned(), (t.to_owned(), n)))
            .collect()
    };
    assert_eq!(read_types(observations), expect(types.clone()));
    let mut prediction_types = types;
    prediction_types.remove("seq");
    prediction_types.insert("probability", ("double", false));
    prediction_types.insert("value", ("double", true));
    assert_eq!(read_types(&read["predictions"]), expect(prediction_types));

    let namespaces = observations["namespace"].as_object().unwrap();
    assert_eq!(namespaces.len(), fleet.expected.len(), "{namespaces:?}");
    for (namespace, &(rows, sum, first, last)) in &fleet.expected {
        let got = &namespaces[*namespace];
        assert_eq!(got["time_s_count"], rows, "{namespace}");
        assert_eq!(got["value_count"], rows, "{namespace}");
        // Values are 0, 1 and 100: every sum is exact.
        assert_eq!(got["value_sum"].as_f64().unwrap(), sum, "{namespace}");
        assert_eq!(got["time_s_min"].as_f64().unwrap(), first, "{namespace}");
        assert_eq!(got["time_s_max"].as_f64().unwrap(), last, "{namespace}");
        assert_eq!(got["time_us_min"], (first * 1e6) as i64, "{namespace}");
        assert_eq!(got["time_us_max"], (last * 1e6) as i64, "{namespace}");
        if let Some(duckdb) = read["duckdb"].as_object() {
            let row = duckdb[*namespace].as_array().unwrap();
            assert_eq!(row[0], rows, "duckdb {namespace}");
            assert_eq!(row[1].as_f64().unwrap(), sum, "duckdb {namespace}");
            assert_eq!(row[2].as_f64().unwrap(), first);
            assert_eq!(row[3].as_f64().unwrap(), last);
            assert_eq!(row[4], (first * 1e6) as i64);
            assert_eq!(row[5], (last * 1e6) as i64);
            assert_eq!(row[6], "TIMESTAMP WITH TIME ZONE");
        }
    }
    assert!(
        read["duckdb"].is_object()
            || std::env::var("CHRONOMAP_REQUIRE_PYARROW").as_deref() != Ok("1"),
        "CHRONOMAP_REQUIRE_PYARROW=1 but duckdb is not installed beside pyarrow"
    );

    // Predictions: each model's, on the grid, as its model (replayed here) gives them.
    let grid: Vec<f64> = (0..POINTS).map(|k| FROM + k as f64 * STEP).collect();
    let models = read["predictions"]["model_id"].as_object().unwrap();
    assert_eq!(models.len(), 3);
    for id in fleet.registry.ids() {
        let entry = fleet.registry.get(id).unwrap();
        let p = entry.model.predict_many(&grid);
        let got = &models[id];
        assert_eq!(got["time_s_count"], POINTS, "{id}");
        assert_eq!(got["time_s_min"].as_f64().unwrap(), FROM);
        assert_eq!(got["time_s_max"].as_f64().unwrap(), TO);
        let sum: f64 = p.iter().sum();
        let read_sum = got["probability_sum"].as_f64().unwrap();
        assert!(
            (read_sum - sum).abs() <= 1e-9 * sum,
            "{id}: {read_sum} vs {sum}"
        );
        let min = p.iter().copied().fold(f64::INFINITY, f64::min);
        let max = p.iter().copied().fold(0.0, f64::max);
        assert_eq!(got["probability_min"].as_f64().unwrap(), min, "{id}");
        assert_eq!(got["probability_max"].as_f64().unwrap(), max, "{id}");
        assert!(min >= 0.0 && max <= 1.0 && max > min, "{id}: {min}..{max}");
        if id == "robot1/door-copy" {
            assert_eq!(got["value_count"], POINTS);
            let value_sum = got["value_sum"].as_f64().unwrap();
            assert!((value_sum - 100.0 * sum).abs() <= 1e-9 * value_sum, "{id}");
        } else {
            assert_eq!(
                got["value_count"], 0,
                "{id}: a model without a range has null values"
            );
        }
    }
}

#[test]
fn a_fleet_history_exported_from_redb_reads_back_in_pyarrow_and_duckdb() {
    let dir = scratch("export_parquet_redb");
    let fleet = fleet();
    let data = redb_fleet(&dir, &fleet);
    let out = dir.join("out");
    let summary = export(&["--data", &data], &out, &fleet);
    assert_eq!(summary["observations"]["row_groups"], 1);
    if let Some(read) = read_back(&out) {
        check_read_back(&read, &fleet);
        assert_eq!(
            read["observations"]["rows"],
            summary["observations"]["rows"]
        );
    }

    // One robot, observations only: the same rows of its namespace, nothing of the others.
    let robot1 = dir.join("robot1");
    let robot1_arg = robot1.display().to_string();
    let summary = json(&chronomap(&[
        "export",
        "parquet",
        "--data",
        &data,
        "--prefix",
        "robot1/",
        "--no-predictions",
        "-o",
        &robot1_arg,
        "--json",
    ]));
    assert_eq!(summary["models"], 2);
    assert_eq!(summary["observations"]["rows"], fleet.expected["robot1"].0);
    assert!(summary["predictions"].is_null());
    assert!(!robot1.join("predictions.parquet").exists());

    // The text summary names both files and the rate.
    let text = crate::common::stdout(&chronomap(&[
        "export",
        "parquet",
        "--data",
        &data,
        "--no-predictions",
        "--force",
        "-o",
        &robot1_arg,
    ]));
    assert_mentions(
        &text,
        &[
            "observations.parquet: 241200 observations",
            "rows/s",
            "3 of 3 models",
        ],
    );
}

#[test]
fn a_fleet_history_exported_from_postgres_beside_its_owner_reads_back() {
    use chronomap_serve::store::PostgresStore;
    let Some(crate::service::Backend::Postgres(config, schema)) =
        crate::service::postgres_backend("export")
    else {
        return;
    };
    let dir = scratch("export_parquet_postgres");
    let fleet = fleet();
    // The owner's connection holds the schema's lock throughout, as a running service does.
    let owner = PostgresStore::connect(&config, &schema).unwrap();
    append_all(&owner, &fleet.groups);
    let out = dir.join("out");
    let summary = export(
        &["--postgres", &config, "--postgres-schema", &schema],
        &out,
        &fleet,
    );
    assert_mentions(summary["store"].as_str().unwrap(), &[&schema, "read-only"]);
    if let Some(read) = read_back(&out) {
        check_read_back(&read, &fleet);
    }
}

#[test]
fn refusals_name_the_store_or_file_and_write_nothing() {
    let dir = scratch("export_parquet_refusals");
    let out = dir.join("out");
    let out_arg = out.display().to_string();
    let grid = grid_args();
    let run = |data: &str, extra: &[&str]| {
        let mut args = vec!["export", "parquet", "--data", data, "-o", &out_arg];
        args.extend(grid.iter().map(String::as_str));
        args.extend_from_slice(extra);
        chronomap(&args)
    };

    // No store: nothing is created, neither the store nor the output.
    let missing = dir.join("missing").display().to_string();
    assert_mentions(
        &error(&run(&missing, &[])),
        &["missing/chronomap.redb: no store", "chronomap serve --data"],
    );
    assert!(!dir.join("missing").exists() && !out.exists());

    // A small store: one door, 3 groups.
    let data_dir = dir.join("data");
    std::fs::create_dir_all(&data_dir).unwrap();
    let door = greg_training();
    let groups = vec![
        vec![LogRecord::Create {
            id: "door".into(),
            config: ModelConfig::parse(None, None).unwrap(),
        }],
        vec![observe(
            "door",
            &door.times[..500],
            door.values[..500].iter().copied(),
        )],
        vec![observe(
            "door",
            &door.times[500..900],
            door.values[500..900].iter().copied(),
        )],
    ];
    let data = data_dir.display().to_string();
    {
        let store = RedbStore::open(data_dir.join("chronomap.redb")).unwrap();
        append_all(&store, &groups);
        // While a process (a service) holds the store, it cannot be exported.
        assert_mentions(
            &error(&run(&data, &[])),
            &[
                "the store is in use",
                "chronomap serve --data",
                "--postgres",
            ],
        );
    }
    assert!(!out.exists());

    // Bad grids and flags are usage errors (exit 2).
    let to_before = ["--from", "100", "--to", "50"];
    let mut args = vec!["export", "parquet", "--data", &data, "-o", &out_arg];
    args.extend(to_before);
    assert_mentions(
        &usage_error(&chronomap(&args)),
        &["--to 50 is before --from 100"],
    );
    let mut args = vec!["export", "parquet", "--data", &data, "-o", &out_arg];
    args.extend(["--from", "0", "--to", "1e9", "--step", "1"]);
    assert_mentions(
        &usage_error(&chronomap(&args)),
        &["1 models × 1000000001 times", "at most 100000000"],
    );
    let mut args = vec!["export", "parquet", "--data", &data, "-o", &out_arg];
    args.extend(["--from", "0", "--to", "1e18", "--step", "1"]);
    assert_mentions(&usage_error(&chronomap(&args)), &["makes 1e18 times"]);
    assert_mentions(
        &usage_error(&chronomap(&[
            "export", "parquet", "--data", &data, "-o", &out_arg,
        ])),
        &["--from"],
    );
    assert_mentions(&usage_error(&run(&data, &["--step", "0"])), &["--step"]);
    assert!(!out.exists());

    // Existing outputs are kept unless --force.
    let first = json(&run(&data, &["--json"]));
    assert_eq!(first["observations"]["rows"], 900);
    let before = std::fs::read(out.join("observations.parquet")).unwrap();
    assert_mentions(
        &error(&run(&data, &[])),
        &["observations.parquet: exists already", "--force"],
    );
    assert_eq!(
        std::fs::read(out.join("observations.parquet")).unwrap(),
        before
    );
    let again = json(&run(&data, &["--force", "--json"]));
    assert_eq!(again["observations"]["rows"], 900);
    assert_eq!(
        std::fs::read_dir(&out).unwrap().count(),
        2,
        "no temporary file is left"
    );

    // A damaged log entry: refused with the check's report, and nothing replaced.
    {
        let store = RedbStore::open(data_dir.join("chronomap.redb")).unwrap();
        let mut bytes = encode_group(
            4,
            &[observe(
                "door",
                &door.times[900..910],
                door.values[900..910].iter().copied(),
            )],
        );
        *bytes.last_mut().unwrap() ^= 0x01;
        store.append(4, &bytes).unwrap();
    }
    assert_mentions(
        &error(&run(&data, &["--force"])),
        &[
            "the store is damaged",
            "log entry 4: checksum mismatch",
            "--salvage",
        ],
    );
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 2);
}
