//! ROS 2 command-line arguments, `--ros-args ...`, as rcl parses them (`rcl/arguments.h`), so
//! that `ros2 run` and launch files (`launch_ros` `Node(...)`) start the node as any ROS 2
//! node:
//!
//! | argument | meaning |
//! |---|---|
//! | `-r`/`--remap [NODE:]FROM:=TO` | rename a topic or service (`rostopic://`/`rosservice://` prefixes narrow it); `__node:=NAME` (or `__name`) and `__ns:=/NS` rename the node |
//! | `-p`/`--param [NODE:]NAME:=VALUE` | a parameter; the value is YAML (`1` integer, `1.0` double, `true`/`yes`/`on` bool, `[a, b]` array, `'1'` string); dotted names for nested parameters (`states.door.model:=hist:24`) |
//! | `--params-file FILE` | a parameter file; every entry whose node name matches (`/**`, `/*/name`, `name`, `/ns/name`) applies |
//! | `--log-level [LOGGER:=]LEVEL` | `debug`, `info`, `warn`, `error`, `fatal` (any case) |
//! | `--enable-`/`--disable-` `rosout-logs`, `stdout-logs`, `external-lib-logs` | where log lines go |
//! | `-e`/`--enclave`, `--log-config-file` | refused: this node has no DDS security and no external logging configuration |
//! | `--` | ends the ROS arguments |
//!
//! Parameters and parameter files apply in the order given (a later one wins), remap rules in
//! the order given (the first that matches a name wins), as in rcl. Anything else inside
//! `--ros-args` is an error that names the argument. This module only parses; applying the
//! parameters is [`crate::params`], the remaps are applied when the node resolves its names
//! ([`RosArgs::remap`]).
//!
//! ```
//! use chronomap_ros2::ros_args::RosArgs;
//!
//! let args = RosArgs::parse(["--ros-args", "-r", "__ns:=/robot1", "-r", "/door:=/front_door",
//!     "-p", "horizon:=600.0"])?;
//! assert_eq!(args.node_identity("chronomap", "/"), ("/robot1".to_string(), "chronomap".to_string()));
//! assert_eq!(args.remap("/door", false, "/robot1", "chronomap")?, "/front_door");
//! assert!(RosArgs::parse(["--ros-args", "--bogus"]).unwrap_err().to_string().contains("--bogus"));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::fmt;
use std::path::PathBuf;

use crate::config::resolve_topic;

/// Arguments that rcl would refuse: which and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RosArgsError {
    /// The argument (with its flag: `-r a`).
    pub argument: String,
    /// Why.
    pub message: String,
}

impl fmt::Display for RosArgsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "--ros-args: `{}`: {}", self.argument, self.message)
    }
}

impl std::error::Error for RosArgsError {}

/// What a remap rule renames.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RemapKind {
    /// `__node:=NAME` (or `__name:=NAME`): the node's name.
    NodeName,
    /// `__ns:=/NS`: the node's namespace.
    Namespace,
    /// `FROM:=TO`: a topic or service name.
    Name {
        /// Applies to topics.
        topics: bool,
        /// Applies to services.
        services: bool,
    },
}

/// One `-r` rule.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Remap {
    /// The node the rule is for (`NODE:` prefix), or every node.
    pub node: Option<String>,
    /// What it renames.
    pub kind: RemapKind,
    /// The name matched (`FROM`; empty for the node name and namespace).
    pub from: String,
    /// The replacement.
    pub to: String,
    /// The argument as given (`-r /door:=/front_door`).
    pub argument: String,
}

/// A source of parameters, in command-line order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ParamArg {
    /// `-p [NODE:]NAME:=VALUE`.
    Override {
        /// The node it is for (`NODE:` prefix), or every node.
        node: Option<String>,
        /// The parameter (`states.door.model`).
        name: String,
        /// The value, as YAML text.
        value: String,
        /// The argument as given.
        argument: String,
    },
    /// `--params-file FILE`.
    File(PathBuf),
}

/// Severity of `--log-level`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Severity {
    /// `debug`.
    Debug,
    /// `info`.
    Info,
    /// `warn`.
    Warn,
    /// `error`.
    Error,
    /// `fatal` (the node logs errors at most: fatal shows nothing but fatal lines).
    Fatal,
}

/// One `--log-level` argument.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LogLevel {
    /// The logger it is for (`LOGGER:=`), or the default level.
    pub logger: Option<String>,
    /// The least severe level logged.
    pub severity: Severity,
}

/// The ROS arguments of a command line.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RosArgs {
    /// `-r` rules in order.
    pub remaps: Vec<Remap>,
    /// `-p` and `--params-file` in order.
    pub params: Vec<ParamArg>,
    /// `--log-level` in order.
    pub log_levels: Vec<LogLevel>,
    /// `--enable-rosout-logs` / `--disable-rosout-logs` (the last given).
    pub rosout_logs: Option<bool>,
    /// `--enable-stdout-logs` / `--disable-stdout-logs`.
    pub stdout_logs: Option<bool>,
    /// `--enable-external-lib-logs` / `--disable-external-lib-logs`.
    pub external_lib_logs: Option<bool>,
    /// Arguments outside `--ros-args ... --` (the program's own).
    pub other: Vec<String>,
}

/// A ROS name token: a letter or `_`, then letters, digits and `_`.
fn is_token(s: &str) -> bool {
    let mut chars = s.chars();
    matches!(chars.next(), Some(c) if c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// A topic or service name of a rule: `/a/b`, `a/b`, `~/a`, `~`.
fn is_name(s: &str) -> bool {
    let rest = if let Some(r) = s.strip_prefix("~/") {
        r
    } else if s == "~" {
        return true;
    } else if let Some(r) = s.strip_prefix('/') {
        r
    } else {
        s
    };
    !rest.is_empty() && rest.split('/').all(is_token)
}

impl RosArgs {
    /// Parses a command line: the arguments between `--ros-args` and `--` (or the end) are ROS
    /// arguments; there may be several such sections; the others are kept in
    /// [`RosArgs::other`].
    ///
    /// # Errors
    /// The first argument rcl would refuse, named.
    pub fn parse<I, S>(args: I) -> Result<RosArgs, RosArgsError>
    where
        I: IntoIterator<Item = S>,
        S: AsRef<str>,
    {
        let args: Vec<String> = args.into_iter().map(|a| a.as_ref().to_string()).collect();
        let mut out = RosArgs::default();
        let mut ros = false;
        let mut i = 0;
        while i < args.len() {
            let arg = args[i].as_str();
            i += 1;
            if arg == "--ros-args" {
                ros = true;
                continue;
            }
            if !ros {
                out.other.push(arg.to_string());
                continue;
            }
            if arg == "--" {
                ros = false;
                continue;
            }
            let mut value = |what: &str| -> Result<String, RosArgsError> {
                match args.get(i) {
                    Some(v) => {
                        i += 1;
                        Ok(v.clone())
                    }
                    None => Err(RosArgsError {
                        argument: arg.to_string(),
                        message: format!("{what} must follow"),
                    }),
                }
            };
            match arg {
                "-r" | "--remap" => {
                    let rule = value("a remap rule (FROM:=TO)")?;
                    out.remaps.push(parse_remap(arg, &rule)?);
                }
                "-p" | "--param" => {
                    let rule = value("a parameter (NAME:=VALUE)")?;
                    out.params.push(parse_param(arg, &rule)?);
                }
                "--params-file" => {
                    let file = value("a parameter file")?;
                    out.params.push(ParamArg::File(PathBuf::from(file)));
                }
                "--log-level" => {
                    let level = value("a log level (debug, info, warn, error, fatal)")?;
                    out.log_levels.push(parse_log_level(arg, &level)?);
                }
                "-e" | "--enclave" => {
                    let enclave = value("an enclave")?;
                    return Err(RosArgsError {
                        argument: format!("{arg} {enclave}"),
                        message: "this node has no DDS security (SROS 2 enclaves): run it \
                                  without an enclave, on a network you trust"
                            .into(),
                    });
                }
                "--log-config-file" => {
                    let file = value("a file")?;
                    return Err(RosArgsError {
                        argument: format!("{arg} {file}"),
                        message: "external logging configuration is not supported: the node \
                                  logs to stderr and /rosout (choose with --log-level and \
                                  --disable-stdout-logs / --disable-rosout-logs)"
                            .into(),
                    });
                }
                _ => {
                    let toggle = arg
                        .strip_prefix("--enable-")
                        .map(|s| (s, true))
                        .or_else(|| arg.strip_prefix("--disable-").map(|s| (s, false)));
                    match toggle {
                        Some(("rosout-logs", on)) => out.rosout_logs = Some(on),
                        Some(("stdout-logs", on)) => out.stdout_logs = Some(on),
                        Some(("external-lib-logs", on)) => out.external_lib_logs = Some(on),
                        _ => {
                            return Err(RosArgsError {
                                argument: arg.to_string(),
                                message: "not a ROS argument (-r/--remap, -p/--param, \
                                          --params-file, --log-level, --enable-/--disable-\
                                          rosout-logs, stdout-logs, external-lib-logs; `--` \
                                          ends them)"
                                    .into(),
                            });
                        }
                    }
                }
            }
        }
        Ok(out)
    }

    /// Namespace and name of a node called `name` in `namespace` after the `__ns` and
    /// `__node` rules (the first rule of each kind for this node wins).
    pub fn node_identity(&self, name: &str, namespace: &str) -> (String, String) {
        let for_node = |r: &&Remap| r.node.as_deref().is_none_or(|n| n == name);
        let new_name = self
            .remaps
            .iter()
            .filter(for_node)
            .find(|r| r.kind == RemapKind::NodeName)
            .map_or(name, |r| r.to.as_str());
        let new_namespace = self
            .remaps
            .iter()
            .filter(for_node)
            .find(|r| r.kind == RemapKind::Namespace)
            .map_or(namespace, |r| r.to.as_str());
        (new_namespace.to_string(), new_name.to_string())
    }

    /// The fully qualified topic (or, with `service`, service) `name` of the node `node` in
    /// `namespace` after the remap rules: the first rule for this node whose `FROM`, expanded
    /// as the node expands names, equals `name` gives its `TO`, expanded the same way.
    ///
    /// # Errors
    /// A `TO` that does not expand to a valid name (`~/x` of a node whose name makes it
    /// invalid), named with its rule.
    pub fn remap(
        &self,
        name: &str,
        service: bool,
        namespace: &str,
        node: &str,
    ) -> Result<String, RosArgsError> {
        let node_fqn = if namespace == "/" {
            format!("/{node}")
        } else {
            format!("{namespace}/{node}")
        };
        for rule in &self.remaps {
            let RemapKind::Name { topics, services } = rule.kind else {
                continue;
            };
            if (service && !services) || (!service && !topics) {
                continue;
            }
            if rule.node.as_deref().is_some_and(|n| n != node) {
                continue;
            }
            let expand = |n: &str| {
                let n = if n == "~" {
                    node_fqn.clone()
                } else {
                    n.to_string()
                };
                resolve_topic(&n, namespace, &node_fqn).map_err(|message| RosArgsError {
                    argument: rule.argument.clone(),
                    message,
                })
            };
            if expand(&rule.from)? == name {
                return expand(&rule.to);
            }
        }
        Ok(name.to_string())
    }

    /// The least severe level logged by the logger `logger` (the node's: `robot1.chronomap`):
    /// the last `--log-level LOGGER:=LEVEL` for it, else the last `--log-level LEVEL`.
    pub fn severity(&self, logger: &str) -> Option<Severity> {
        self.log_levels
            .iter()
            .rev()
            .find(|l| l.logger.as_deref() == Some(logger))
            .or_else(|| self.log_levels.iter().rev().find(|l| l.logger.is_none()))
            .map(|l| l.severity)
    }
}

/// `NODE:` before a rule, when the text before the first `:` (not of `:=`) is a token.
fn node_prefix(rule: &str) -> (Option<&str>, &str) {
    let assign = rule.find(":=").unwrap_or(rule.len());
    match rule[..assign].find(':') {
        Some(colon) if !rule[..colon].contains('/') && !rule[..colon].is_empty() => {
            let (node, rest) = (&rule[..colon], &rule[colon + 1..]);
            // `rostopic://` is a scheme, not a node.
            if rest.starts_with("//") {
                (None, rule)
            } else {
                (Some(node), rest)
            }
        }
        _ => (None, rule),
    }
}

fn parse_remap(flag: &str, rule: &str) -> Result<Remap, RosArgsError> {
    let argument = format!("{flag} {rule}");
    let error = |message: String| RosArgsError {
        argument: argument.clone(),
        message,
    };
    let (node, rest) = node_prefix(rule);
    if let Some(n) = node
        && !is_token(n)
    {
        return Err(error(format!("{n:?} is not a node name")));
    }
    let Some((from, to)) = rest.split_once(":=") else {
        return Err(error("not a remap rule (expected FROM:=TO)".into()));
    };
    if to.contains(":=") {
        return Err(error("more than one `:=`".into()));
    }
    let (kind, from) = match from {
        "__node" | "__name" => {
            if !is_token(to) {
                return Err(error(format!(
                    "{to:?} is not a node name (a letter or '_', then letters, digits and '_')"
                )));
            }
            (RemapKind::NodeName, "")
        }
        "__ns" => {
            let ok = to == "/"
                || to
                    .strip_prefix('/')
                    .is_some_and(|r| r.split('/').all(is_token));
            if !ok {
                return Err(error(format!(
                    "{to:?} is not a fully qualified namespace (`/` or `/a/b`)"
                )));
            }
            (RemapKind::Namespace, "")
        }
        _ => {
            let (topics, services, from) = if let Some(f) = from.strip_prefix("rostopic://") {
                (true, false, f)
            } else if let Some(f) = from.strip_prefix("rosservice://") {
                (false, true, f)
            } else {
                (true, true, from)
            };
            if from.contains('*') {
                return Err(error(
                    "wildcards are not supported in remap rules (as in rcl)".into(),
                ));
            }
            if !is_name(from) {
                return Err(error(format!("{from:?} is not a topic or service name")));
            }
            if !is_name(to) {
                return Err(error(format!("{to:?} is not a topic or service name")));
            }
            (RemapKind::Name { topics, services }, from)
        }
    };
    Ok(Remap {
        node: node.map(str::to_string),
        kind,
        from: from.to_string(),
        to: to.to_string(),
        argument,
    })
}

fn parse_param(flag: &str, rule: &str) -> Result<ParamArg, RosArgsError> {
    let argument = format!("{flag} {rule}");
    let error = |message: String| RosArgsError {
        argument: argument.clone(),
        message,
    };
    let (node, rest) = node_prefix(rule);
    let Some((name, value)) = rest.split_once(":=") else {
        return Err(error("not a parameter (expected NAME:=VALUE)".into()));
    };
    if let Some(n) = node
        && !is_token(n)
    {
        return Err(error(format!("{n:?} is not a node name")));
    }
    if name.is_empty() || !name.split('.').all(is_token) {
        return Err(error(format!(
            "{name:?} is not a parameter name (tokens separated by single dots: states.door.model)"
        )));
    }
    if value.is_empty() {
        return Err(error("no value after `:=`".into()));
    }
    Ok(ParamArg::Override {
        node: node.map(str::to_string),
        name: name.to_string(),
        value: value.to_string(),
        argument,
    })
}

fn parse_log_level(flag: &str, text: &str) -> Result<LogLevel, RosArgsError> {
    let (logger, level) = match text.split_once(":=") {
        Some((logger, level)) => (Some(logger.to_string()), level),
        None => (None, text),
    };
    let severity = match level.to_ascii_lowercase().as_str() {
        "debug" => Severity::Debug,
        "info" => Severity::Info,
        "warn" => Severity::Warn,
        "error" => Severity::Error,
        "fatal" => Severity::Fatal,
        _ => {
            return Err(RosArgsError {
                argument: format!("{flag} {text}"),
                message: format!("{level:?} is not a severity (debug, info, warn, error, fatal)"),
            });
        }
    };
    if logger.as_deref() == Some("") {
        return Err(RosArgsError {
            argument: format!("{flag} {text}"),
            message: "an empty logger name".into(),
        });
    }
    Ok(LogLevel { logger, severity })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(args: &[&str]) -> RosArgs {
        RosArgs::parse(args).unwrap_or_else(|e| panic!("{args:?}: {e}"))
    }

    fn error(args: &[&str]) -> String {
        RosArgs::parse(args).unwrap_err().to_string()
    }

    /// The arguments a launch_ros `Node(name=..., namespace=..., parameters=[file, dict],
    /// remappings=[...])` passes, in its order.
    #[test]
    fn what_launch_ros_passes_is_read_in_order() {
        let args = parse(&[
            "--ros-args",
            "-r",
            "__node:=office_model",
            "-r",
            "__ns:=/robot1",
            "--params-file",
            "/tmp/launch_params_x",
            "-p",
            "states.door.model:=hist:24",
            "-r",
            "/door:=/front_door",
            "--log-level",
            "DEBUG",
        ]);
        assert_eq!(
            args.node_identity("chronomap", "/"),
            ("/robot1".to_string(), "office_model".to_string())
        );
        assert_eq!(
            args.params,
            vec![
                ParamArg::File("/tmp/launch_params_x".into()),
                ParamArg::Override {
                    node: None,
                    name: "states.door.model".into(),
                    value: "hist:24".into(),
                    argument: "-p states.door.model:=hist:24".into(),
                }
            ]
        );
        assert_eq!(args.severity("robot1.office_model"), Some(Severity::Debug));
        assert!(args.other.is_empty());
    }

    /// Topic remaps as rclpy 9.1.2 applies them (probed: a publisher's `topic_name`).
    #[test]
    fn remaps_expand_like_rcl_and_the_first_match_wins() {
        let args = parse(&[
            "--ros-args",
            "-r",
            "/a:=/b",
            "-r",
            "c:=d",
            "-r",
            "~/x:=y",
            "-r",
            "/a:=/never",
            "-r",
            "/b:=/c",
        ]);
        let remap = |name: &str, ns: &str| args.remap(name, false, ns, "probe").unwrap();
        // Node /probe: "/a" -> /b (not /c: rules do not chain), "c" and "/c" -> /d, "~/x" -> /y.
        assert_eq!(remap("/a", "/"), "/b");
        assert_eq!(remap("/c", "/"), "/d");
        assert_eq!(remap("/probe/x", "/"), "/y");
        assert_eq!(remap("/x", "/"), "/x");
        // Node /robot/probe: "c" means /robot/c, "y" /robot/y.
        assert_eq!(remap("/robot/c", "/robot"), "/robot/d");
        assert_eq!(remap("/robot/probe/x", "/robot"), "/robot/y");
        assert_eq!(remap("/robot/a", "/robot"), "/robot/a");
        // `~` in TO is the node's name.
        let private = parse(&["--ros-args", "-r", "/a:=~/q"]);
        assert_eq!(
            private.remap("/a", false, "/", "probe").unwrap(),
            "/probe/q"
        );
    }

    #[test]
    fn rules_for_one_node_match_its_final_name_and_schemes_narrow_them() {
        let args = parse(&[
            "--ros-args",
            "-r",
            "__node:=n3",
            "-r",
            "probe:/a:=/b",
            "-r",
            "n3:/c:=/d",
            "-r",
            "rosservice:///e:=/f",
            "-r",
            "rostopic:///g:=/h",
        ]);
        // rclpy: __node:=n3 makes the node /n3; `probe:` rules no longer apply, `n3:` ones do.
        let (ns, name) = args.node_identity("probe", "/");
        assert_eq!((ns.as_str(), name.as_str()), ("/", "n3"));
        assert_eq!(args.remap("/a", false, "/", "n3").unwrap(), "/a");
        assert_eq!(args.remap("/c", false, "/", "n3").unwrap(), "/d");
        assert_eq!(args.remap("/e", false, "/", "n3").unwrap(), "/e");
        assert_eq!(args.remap("/e", true, "/", "n3").unwrap(), "/f");
        assert_eq!(args.remap("/g", false, "/", "n3").unwrap(), "/h");
        assert_eq!(args.remap("/g", true, "/", "n3").unwrap(), "/g");
        // Node renames for another node do not apply; the first of each kind wins.
        let other = parse(&[
            "--ros-args",
            "-r",
            "other:__node:=x",
            "-r",
            "__ns:=/x/y",
            "-r",
            "__node:=p2",
            "-r",
            "__name:=p3",
        ]);
        assert_eq!(
            other.node_identity("probe", "/"),
            ("/x/y".to_string(), "p2".to_string())
        );
    }

    #[test]
    fn sections_end_at_the_double_dash_and_may_repeat() {
        let args = parse(&[
            "a",
            "--ros-args",
            "-p",
            "x:=1",
            "--",
            "b",
            "--ros-args",
            "-p",
            "y:=2",
            "--disable-rosout-logs",
            "--enable-stdout-logs",
        ]);
        assert_eq!(args.other, ["a", "b"]);
        assert_eq!(args.params.len(), 2);
        assert_eq!(
            (args.rosout_logs, args.stdout_logs, args.external_lib_logs),
            (Some(false), Some(true), None)
        );
        let node_param = parse(&[
            "--ros-args",
            "-p",
            "chronomap:horizon:=5",
            "--param",
            "x:=a:b",
        ]);
        assert_eq!(
            node_param.params,
            vec![
                ParamArg::Override {
                    node: Some("chronomap".into()),
                    name: "horizon".into(),
                    value: "5".into(),
                    argument: "-p chronomap:horizon:=5".into()
                },
                ParamArg::Override {
                    node: None,
                    name: "x".into(),
                    value: "a:b".into(),
                    argument: "--param x:=a:b".into()
                }
            ]
        );
        let levels = parse(&[
            "--ros-args",
            "--log-level",
            "warn",
            "--log-level",
            "chronomap:=Debug",
        ]);
        assert_eq!(levels.severity("chronomap"), Some(Severity::Debug));
        assert_eq!(levels.severity("other"), Some(Severity::Warn));
        assert_eq!(parse(&["--ros-args"]).severity("chronomap"), None);
    }

    /// What rclpy 9.1.2 refuses is refused, naming the argument.
    #[test]
    fn what_rcl_refuses_is_an_error_naming_the_argument() {
        let cases: &[(&[&str], &str)] = &[
            (&["--ros-args", "--bogus"], "`--bogus`: not a ROS argument"),
            (
                &["--ros-args", "-r"],
                "`-r`: a remap rule (FROM:=TO) must follow",
            ),
            (&["--ros-args", "-r", "a"], "`-r a`: not a remap rule"),
            (
                &["--ros-args", "-r", "a:=b:=c"],
                "`-r a:=b:=c`: more than one",
            ),
            (
                &["--ros-args", "-r", "1a:=b"],
                "`-r 1a:=b`: \"1a\" is not a topic",
            ),
            (&["--ros-args", "-r", "/a:=/b/"], "\"/b/\" is not a topic"),
            (
                &["--ros-args", "-r", "/a/*:=/b"],
                "wildcards are not supported",
            ),
            (
                &["--ros-args", "-r", "__ns:=robot"],
                "`-r __ns:=robot`: \"robot\" is not a fully qualified namespace",
            ),
            (
                &["--ros-args", "-r", "__node:=bad-name"],
                "\"bad-name\" is not a node name",
            ),
            (
                &["--ros-args", "-p", "x"],
                "`-p x`: not a parameter (expected NAME:=VALUE)",
            ),
            (
                &["--ros-args", "-p", "x:="],
                "`-p x:=`: no value after `:=`",
            ),
            (
                &["--ros-args", "-p", "x.:=1"],
                "\"x.\" is not a parameter name",
            ),
            (
                &["--ros-args", "-p", "x..y:=1"],
                "\"x..y\" is not a parameter name",
            ),
            (
                &["--ros-args", "--params-file"],
                "`--params-file`: a parameter file must follow",
            ),
            (
                &["--ros-args", "--log-level", "bogus"],
                "`--log-level bogus`: \"bogus\" is not a severity",
            ),
            (
                &["--ros-args", "-e", "/x"],
                "`-e /x`: this node has no DDS security",
            ),
            (
                &["--ros-args", "--log-config-file", "c"],
                "external logging configuration is not supported",
            ),
        ];
        for (args, expected) in cases {
            let message = error(args);
            assert!(message.contains(expected), "{args:?}: {message}");
            assert!(message.starts_with("--ros-args: `"), "{message}");
        }
    }
}
