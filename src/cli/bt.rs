//! Flags of `chronomap bt` and `chronomap monitor`.

#[allow(unused_imports)]
use super::*;

pub(super) const BT_HELP_CHECK: &str = "\
Examples:
  chronomap bt check tests/data/bt/door.xml
  chronomap bt check tests/data/bt/nav2/follow_point.xml --nodes tests/data/bt/nav2/nav2_tree_nodes.xml

Reads BehaviorTree.CPP 4 XML (<root BTCPP_format=\"4\">): built-in nodes, <SubTree>, scripting
attributes (_skipIf, _onSuccess, ...), <include path=\"...\"/> (relative to the including file),
and custom nodes declared in <TreeNodesModel>, in a --nodes file (such as Nav2's
nav2_tree_nodes.xml) or written as <Action ID=\"...\"/> / <Condition ID=\"...\"/>. Declared
custom controls and decorators are checked for their children and ports. Prints the tree to
execute with the uids that `bt run` and .btlog files use (depth first, subtrees expanded).
Errors name the file, line, column and attribute. With -o, the saved file's <TreeNodesModel>
declares every custom node the trees use, so that Groot2 shows their ports.";

pub(super) const BT_HELP_RUN: &str = "\
Example:
  chronomap bt run tests/data/bt/door.xml --script tests/data/bt/door.script --btlog door.btlog

Example with Nav2's nodes, stubs for leaves no script drives:
  chronomap bt run tests/data/bt/nav2/follow_point.xml --nodes tests/data/bt/nav2/nav2_tree_nodes.xml \\
    --stub-all SUCCESS --stub FollowPath=RUNNING:2 --ticks 10

The script gives the outcome of leaves (by instance name: the name attribute, or the ID) per
tick; an outcome holds until changed:
  # comment
  tick 1: IsDoorClosed=success, OpenDoor=failure, PickLock=running
  tick 2: PickLock=failure
  tick 4 @ 1000: PickLock=success
Ticks run from 1 to the last tick of the script (one root tick each, as BehaviorTree.CPP's
tickExactlyOnce) and stop when the root succeeds or fails. `@ MS` sets a tick's time in
milliseconds; other ticks come --tick-ms after the previous one. The trace lists every status
change of every tick; --btlog writes them as a Groot2 log (times from 0).

Stubs stand in for nodes that are declared but not implemented (--stub ID=BEHAVIOUR, by node
ID, repeatable): for actions and conditions SUCCESS, FAILURE or RUNNING:n (running n ticks, then
success; actions only); for custom controls SEQUENCE (ticks its children as a Sequence), for
decorators PASS (returns its child's status), and NAV2 for Nav2's PipelineSequence,
RecoveryNode, RoundRobin, RateController and GoalUpdater, which run as Nav2 runs them (the
default for those IDs when no --stub names them). --stub-all BEHAVIOUR stubs every leaf whose ID
and instance names the script does not mention. Without --script the run takes --ticks ticks
(default 100) and stops when the root completes.";

/// `chronomap bt ...`.
#[derive(Debug, Subcommand)]
pub enum BtCommand {
    /// Load and check a BehaviorTree.CPP 4 XML file and print the tree with node uids.
    #[command(after_help = BT_HELP_CHECK)]
    Check(BtCheckArgs),
    /// Tick a tree whose leaves follow a script of outcomes and print every status change.
    #[command(after_help = BT_HELP_RUN)]
    Run(BtRunArgs),
    /// Analyse a tree as a stochastic behavior tree: p_s,T(t), p_f,T(t) and mean times.
    #[command(after_help = BT_HELP_ANALYSE)]
    Analyse(BtAnalyseArgs),
}

pub(super) const BT_HELP_ANALYSE: &str = "\
Example:
  chronomap bt analyse tests/data/bt/door.xml --params tests/data/bt/door_sbt.csv --t-max 120

[Stüde 2024] §5.2.2: every action ends in success with probability p_s after an Exp(mu) time,
else in failure after an Exp(nu) time; a condition holds with probability p_s and takes no
time. The parameters file is CSV with a header, one row per leaf (instance name, or ID for
every instance of it); conditions leave mu and nu empty, p_f is optional (= 1 - p_s):
  node,p_s,p_f,mu,nu
  IsDoorClosed,0.7,,,
  OpenDoor,0.4,0.6,0.1,0.5
Supported: Sequence, SequenceWithMemory, Fallback, Inverter, ForceSuccess, ForceFailure,
RetryUntilSuccessful and Repeat with a literal count, SubTree, AlwaysSuccess, AlwaysFailure,
SetBlackboard. Prints p_s,T(t) and p_f,T(t) (eq. 5.1) at --steps times up to --t-max (default:
three times the longer mean time), the eventual probabilities and the exact mean times to
success and failure (1/mu_T, 1/nu_T).";

/// `chronomap bt analyse`.
#[derive(Debug, Args)]
pub struct BtAnalyseArgs {
    /// The XML file.
    pub file: PathBuf,
    /// The leaves' parameters: CSV `node,p_s,p_f,mu,nu` (see below).
    #[arg(long)]
    pub params: PathBuf,
    /// The tree to analyse (default: main_tree_to_execute, or the only tree).
    #[arg(long)]
    pub tree: Option<String>,
    /// Last time of the table, seconds after the tree starts (a positive number).
    #[arg(long, value_parser = parse_positive)]
    pub t_max: Option<f64>,
    /// Number of intervals of the time table (at least 1).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..))]
    pub steps: u32,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Draw p_s,T(t) and p_f,T(t) into a PNG file.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Node models of custom nodes from another file: a root element with a TreeNodesModel,
    /// such as Nav2's nav2_tree_nodes.xml (repeatable; the tree file's own models come first).
    #[arg(long = "nodes", value_name = "FILE")]
    pub nodes: Vec<PathBuf>,
}

/// `chronomap bt check`.
#[derive(Debug, Args)]
pub struct BtCheckArgs {
    /// The XML file.
    pub file: PathBuf,
    /// The tree to print (default: main_tree_to_execute, or the only tree).
    #[arg(long)]
    pub tree: Option<String>,
    /// Also write the file in the canonical BehaviorTree.CPP 4 form (compact nodes, node
    /// models); `--save` is an old spelling.
    #[arg(short, long, alias = "save")]
    pub output: Option<PathBuf>,
    /// Print the tree as one JSON object (nodes depth first with uids, as in the table).
    #[arg(long)]
    pub json: bool,
    /// Node models of custom nodes from another file: a root element with a TreeNodesModel,
    /// such as Nav2's nav2_tree_nodes.xml (repeatable; the tree file's own models come first).
    #[arg(long = "nodes", value_name = "FILE")]
    pub nodes: Vec<PathBuf>,
}

/// `chronomap bt run`.
#[derive(Debug, Args)]
pub struct BtRunArgs {
    /// The XML file.
    pub file: PathBuf,
    /// The outcomes of the leaves, tick by tick (see below).
    #[arg(long)]
    pub script: Option<PathBuf>,
    /// Ticks to run without a script (default 100).
    #[arg(long, conflicts_with = "script", value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    pub ticks: Option<u64>,
    /// A stand-in for a declared node without implementation: ID=SUCCESS, FAILURE or RUNNING:n
    /// (leaves), ID=SEQUENCE (controls), ID=PASS (decorators), ID=NAV2 (see below; repeatable).
    #[arg(long = "stub", value_name = "ID=BEHAVIOUR", value_parser = parse_stub)]
    pub stubs: Vec<StubSpec>,
    /// Stub every leaf the script does not mention: SUCCESS, FAILURE or RUNNING:n.
    #[arg(long, value_name = "BEHAVIOUR", value_parser = parse_leaf_stub)]
    pub stub_all: Option<StubBehaviour>,
    /// An enum value for scripts and Switch cases, as BehaviorTree.CPP's
    /// registerScriptingEnum: NAME=INTEGER, e.g. --enum RED=1 (repeatable).
    #[arg(long = "enum", value_name = "NAME=VALUE", value_parser = parse_enum)]
    pub enums: Vec<(String, i64)>,
    /// The tree to run (default: main_tree_to_execute, or the only tree).
    #[arg(long)]
    pub tree: Option<String>,
    /// Milliseconds between ticks whose time the script does not give.
    #[arg(long, default_value_t = 100)]
    pub tick_ms: u64,
    /// Write the status changes as a Groot2 execution log (must end in .btlog).
    #[arg(long)]
    pub btlog: Option<PathBuf>,
    /// Print the run as one JSON object (every tick with its transitions).
    #[arg(long)]
    pub json: bool,
    /// Node models of custom nodes from another file: a root element with a TreeNodesModel,
    /// such as Nav2's nav2_tree_nodes.xml (repeatable; the tree file's own models come first).
    #[arg(long = "nodes", value_name = "FILE")]
    pub nodes: Vec<PathBuf>,
    /// Serve the run to Groot2 (and other clients of its protocol, such as btview) while it
    /// runs: ZeroMQ requests on PORT, notifications on PORT + 1, as BehaviorTree.CPP's
    /// Groot2Publisher.
    #[arg(long, value_name = "PORT", value_parser = clap::value_parser!(u16).range(1..=65534))]
    pub groot2: Option<u16>,
    /// Wall-clock milliseconds to wait before each tick (the run's own times stay the
    /// script's), so that a client can follow the run (default: 500 with --groot2, else 0).
    #[arg(long, value_name = "MS", value_parser = clap::value_parser!(u64).range(0..=3_600_000))]
    pub tick_period: Option<u64>,
    /// With --groot2: seconds to keep answering after the last tick.
    #[arg(long, value_name = "SECS", requires = "groot2", value_parser = clap::value_parser!(u64).range(0..=86_400))]
    pub linger: Option<u64>,
    /// With --groot2: milliseconds without a request from any client after which its hooks
    /// are disabled and a tick held at a breakpoint goes on (BehaviorTree.CPP's
    /// max_heartbeat_delay; default 5000).
    #[arg(long, value_name = "MS", requires = "groot2", value_parser = clap::value_parser!(u64).range(10..=86_400_000))]
    pub groot2_heartbeat: Option<u64>,
}

/// What a `--stub` makes of a node, and `--stub ID=BEHAVIOUR`.
pub use chronomap_app_bt::bt::{StubBehaviour, StubSpec};

/// `SUCCESS`, `FAILURE`, `RUNNING:n`, `SEQUENCE`, `PASS` or `NAV2` (any case).
fn parse_stub_behaviour(text: &str) -> Result<StubBehaviour, String> {
    let upper = text.trim().to_ascii_uppercase();
    Ok(match upper.as_str() {
        "SUCCESS" => StubBehaviour::Success,
        "FAILURE" => StubBehaviour::Failure,
        "SEQUENCE" => StubBehaviour::Sequence,
        "PASS" => StubBehaviour::Pass,
        "NAV2" => StubBehaviour::Nav2,
        other => match other.strip_prefix("RUNNING:") {
            Some(n) => StubBehaviour::Running(n.trim().parse().map_err(|_| {
                format!("{text:?}: RUNNING:n needs a number of ticks n (0 to 4294967295)")
            })?),
            None => {
                return Err(format!(
                    "{text:?}: expected SUCCESS, FAILURE or RUNNING:n (leaves), SEQUENCE \
                     (controls), PASS (decorators) or NAV2"
                ));
            }
        },
    })
}

/// `--stub ID=BEHAVIOUR`.
fn parse_stub(text: &str) -> Result<StubSpec, String> {
    let (id, behaviour) = text
        .split_once('=')
        .ok_or_else(|| format!("{text:?}: expected ID=BEHAVIOUR, e.g. FollowPath=RUNNING:3"))?;
    let id = id.trim();
    if id.is_empty() {
        return Err(format!("{text:?}: the node ID before '=' is empty"));
    }
    Ok(StubSpec {
        id: id.to_owned(),
        behaviour: parse_stub_behaviour(behaviour)?,
    })
}

/// `--enum NAME=VALUE`: a name that scripts can use (letters, digits and `_`, not starting
/// with a digit) and an integer.
fn parse_enum(text: &str) -> Result<(String, i64), String> {
    let (name, value) = text
        .split_once('=')
        .ok_or_else(|| format!("{text:?}: expected NAME=VALUE, e.g. RED=1"))?;
    let name = name.trim();
    let valid = name
        .chars()
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    if !valid {
        return Err(format!(
            "{text:?}: {name:?} is not a name scripts can use (letters, digits and _, \
             not starting with a digit)"
        ));
    }
    let value = value
        .trim()
        .parse()
        .map_err(|_| format!("{text:?}: the value must be an integer"))?;
    Ok((name.to_owned(), value))
}

/// `--stub-all`: a leaf behaviour.
fn parse_leaf_stub(text: &str) -> Result<StubBehaviour, String> {
    let behaviour = parse_stub_behaviour(text)?;
    if !behaviour.is_leaf() {
        return Err(format!(
            "{text:?}: --stub-all takes SUCCESS, FAILURE or RUNNING:n"
        ));
    }
    Ok(behaviour)
}

pub(super) const MONITOR_HELP_SIM: &str = "\
Examples:
  chronomap monitor sim --hours 8 --seed 1
  chronomap monitor sim --hours 1 --faults faults.txt --certain

A fault file has one fault a line: TIME KIND [TARGET] [fails=N] [for=SECONDS], TIME in seconds
or h:mm:ss, KIND node_crash (TARGET localization, move_base or camera), topic_slow (/scan),
cpu_overload, localization_lost, navigation_failure or stuck; fails=N makes the first N
recoveries on it fail, for= sets a CPU overload's length (120 s). Without --faults, faults are
drawn at random from the seed. A recovery counts as successful if no recovery of the same
category starts within one minute ([Stüde 2024] §5.3.2); TSL is the time between supervisor
interventions the robot did not request.";

/// `chronomap monitor ...`.
#[derive(Debug, Subcommand)]
pub enum MonitorCommand {
    /// Simulate a patrol with injected faults; print every recovery and the metrics of
    /// Tables 5.2 and 5.3.
    #[command(after_help = MONITOR_HELP_SIM)]
    Sim(MonitorSimArgs),
}

/// `chronomap monitor sim`.
#[derive(Debug, Args)]
pub struct MonitorSimArgs {
    /// Simulated hours.
    #[arg(long, default_value_t = 8.0)]
    pub hours: f64,
    /// Seed of the random faults and recovery outcomes.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Faults to inject instead of random ones (see below).
    #[arg(long)]
    pub faults: Option<PathBuf>,
    /// Every recovery fixes its fault (unless the fault says fails=N) instead of Table 5.3's
    /// success rates.
    #[arg(long)]
    pub certain: bool,
    /// The arbiter tree (BehaviorTree.CPP 4 XML with the simulation's leaves; default: the
    /// built-in one, tests/data/bt/monitor_arbiter.xml).
    #[arg(long)]
    pub arbiter: Option<PathBuf>,
    /// Print JSON instead of tables.
    #[arg(long)]
    pub json: bool,
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn stub_specs_parse_and_bad_ones_are_usage_errors() {
        assert_eq!(
            parse_stub("FollowPath=running:3").unwrap(),
            StubSpec {
                id: "FollowPath".to_owned(),
                behaviour: StubBehaviour::Running(3)
            }
        );
        assert_eq!(
            parse_stub(" Spin = FAILURE").unwrap().behaviour,
            StubBehaviour::Failure
        );
        assert_eq!(
            parse_stub("PipelineSequence=nav2").unwrap().behaviour,
            StubBehaviour::Nav2
        );
        for bad in [
            "FollowPath",
            "=SUCCESS",
            "X=RUNNING:",
            "X=RUNNING:-1",
            "X=maybe",
        ] {
            assert!(parse_stub(bad).is_err(), "{bad}");
        }
        assert!(parse_leaf_stub("SEQUENCE").is_err());
        let err = Cli::try_parse_from(["chronomap", "bt", "run", "t.xml", "--stub", "X=maybe"])
            .unwrap_err();
        assert_eq!(err.exit_code(), 2);
    }

    #[test]
    fn the_command_line_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn eval_parses_the_acceptance_call() {
        let cli = Cli::try_parse_from([
            "chronomap",
            "eval",
            "--train",
            "training_data.txt",
            "--test",
            "test_times_1.txt,test_data_1.txt",
            "--test",
            "test_times_2.txt,test_data_2.txt",
            "--models",
            "mean,hist:24,fremen:2,fremen:4,fremen:auto,pergam:2,stm,auto",
            "--json",
        ])
        .unwrap();
        let Command::Eval(args) = cli.command else {
            panic!("not eval")
        };
        assert_eq!(args.tests.len(), 2);
        assert_eq!(model_specs(&args.models).len(), 8);
        assert!(args.json);
        assert!(Cli::try_parse_from(["chronomap", "eval", "--train", "a", "--test", "x"]).is_err());
        assert!(
            Cli::try_parse_from([
                "chronomap",
                "eval",
                "--train",
                "a",
                "--test",
                "x,y",
                "--models",
                "fremen:q"
            ])
            .is_err()
        );
    }
}
