use super::*;

fn s(x: u64) -> Duration {
    Duration::from_secs(x)
}

/// A fault at `at` seconds.
fn f(at: u64, kind: FaultKind) -> Fault {
    Fault::new(s(at), kind)
}

/// A scenario with certain recoveries (p = 1) unless a fault has `fails > 0`.
fn run(seconds: u64, faults: Vec<Fault>) -> SimReport {
    let mut config = SimConfig::new(s(seconds), 7, faults);
    config.p_fix = Some(1.0);
    simulate(&config, &arbiter_document()).unwrap()
}

/// (start s, end s, leaf, outcome, success by the one-minute rule)
fn rows(report: &SimReport) -> Vec<(u64, u64, &str, Outcome, bool)> {
    report
        .interventions
        .iter()
        .map(|r| {
            (
                r.start.as_secs(),
                r.end.as_secs(),
                r.leaf.as_str(),
                r.outcome,
                r.success,
            )
        })
        .collect()
}

#[test]
fn a_failed_first_recovery_escalates_and_counts_as_failure() {
    // Localization lost at 100 s: the status monitor is in error at once; the slow rotation
    // (20 s) does not fix it, so the fallback restarts the localization at 120 s (30 s).
    let r = run(
        300,
        vec![Fault {
            fails: 1,
            ..f(100, FaultKind::LocalizationLost)
        }],
    );
    assert_eq!(
        rows(&r),
        vec![
            (100, 120, "SlowRotate", Outcome::NotFixed, false),
            (120, 150, "RestartLocalization", Outcome::Fixed, true),
        ]
    );
    // The patrol is blocked from tick 100 to tick 150 and resumes at 151: it moved during
    // (0, 99] and (150, 300], 249 s of 300.
    assert!((r.moving_h * 3600.0 - 249.0).abs() < 1e-9);
    assert!((r.autonomy - 249.0 / 300.0).abs() < 1e-12);
    assert_eq!(r.reactions.len(), 2);
    assert_eq!(r.reactions[0].reaction, "Slow rotate");
    assert_eq!((r.reactions[0].count, r.reactions[0].successes), (1, 0));
    assert!(r.unrequested.is_empty());
}

#[test]
fn a_recovery_repeated_30_s_later_counts_the_first_as_failure() {
    // Both wait-and-retry runs fix their fault, but the fault is back 30 s after the first:
    // §5.3.2 counts the first as a failure.
    let r = run(
        300,
        vec![
            f(100, FaultKind::NavigationFailure),
            f(130, FaultKind::NavigationFailure),
        ],
    );
    assert_eq!(
        rows(&r),
        vec![
            (100, 110, "WaitAndRetry", Outcome::Fixed, false),
            (130, 140, "WaitAndRetry", Outcome::Fixed, true),
        ]
    );
    assert_eq!(r.reactions[0].count, 2);
    assert_eq!(r.reactions[0].successes, 1);
    // 70 s later instead: both succeed.
    let r = run(
        300,
        vec![
            f(100, FaultKind::NavigationFailure),
            f(170, FaultKind::NavigationFailure),
        ],
    );
    assert!(r.interventions.iter().all(|i| i.success));
}

#[test]
fn navigation_escalates_to_the_supervisor_in_table_order() {
    let r = run(
        400,
        vec![Fault {
            fails: 2,
            ..f(100, FaultKind::NavigationFailure)
        }],
    );
    assert_eq!(
        rows(&r),
        vec![
            (100, 110, "WaitAndRetry", Outcome::NotFixed, false),
            (110, 118, "MoveBackwards", Outcome::NotFixed, false),
            (118, 178, "AskSupervisorTeleoperation", Outcome::Fixed, true),
        ]
    );
    assert_eq!(r.interventions[2].step, 3);
    // Asked for by the robot: not an unrequested intervention.
    assert!(r.unrequested.is_empty());
    assert_eq!(r.tsl_h.len(), 1);
}

#[test]
fn a_higher_priority_monitor_halts_a_running_recovery() {
    // The camera node crashes at 105 s while the robot rotates (100-120 s). Its last heartbeat
    // is at 104 s; the age exceeds 4 s at 109 s: the node monitor has priority, the rotation is
    // halted. After the restart (10 s) the localization recovery starts over.
    let r = run(
        300,
        vec![
            f(100, FaultKind::LocalizationLost),
            Fault {
                target: "camera".into(),
                ..f(105, FaultKind::NodeCrash)
            },
        ],
    );
    assert_eq!(
        rows(&r),
        vec![
            (100, 109, "SlowRotate", Outcome::Halted, false),
            (109, 119, "RestartNode", Outcome::Fixed, true),
            (120, 140, "SlowRotate", Outcome::Fixed, true),
        ]
    );
    assert_eq!(r.interventions[1].category, Category::Ros);
}

#[test]
fn simultaneous_errors_are_recovered_by_priority() {
    // Navigation comes before localization in the arbiter.
    let r = run(
        300,
        vec![
            f(100, FaultKind::LocalizationLost),
            f(100, FaultKind::NavigationFailure),
        ],
    );
    assert_eq!(
        rows(&r),
        vec![
            (100, 110, "WaitAndRetry", Outcome::Fixed, true),
            (111, 131, "SlowRotate", Outcome::Fixed, true),
        ]
    );
    // Swapping the two monitors in the tree swaps the order: the tree decides.
    let mut doc = arbiter_document();
    let recoveries = &mut doc.trees[0].root.children[1].children;
    recoveries.swap(2, 3);
    let mut config = SimConfig::new(
        s(300),
        7,
        vec![
            f(100, FaultKind::LocalizationLost),
            f(100, FaultKind::NavigationFailure),
        ],
    );
    config.p_fix = Some(1.0);
    let r = simulate(&config, &doc).unwrap();
    assert_eq!(
        rows(&r),
        vec![
            (100, 120, "SlowRotate", Outcome::Fixed, true),
            (121, 131, "WaitAndRetry", Outcome::Fixed, true),
        ]
    );
}

#[test]
fn resources_send_one_message_per_episode_without_blocking() {
    let r = run(
        300,
        vec![
            Fault {
                lasts: s(30),
                ..f(100, FaultKind::CpuOverload)
            },
            f(110, FaultKind::CpuOverload),
            Fault {
                lasts: s(10),
                ..f(200, FaultKind::CpuOverload)
            },
        ],
    );
    assert!(r.interventions.is_empty());
    let times: Vec<f64> = r.messages.iter().map(|m| m.0).collect();
    // The overload of 110 s is a duplicate of the active one and ignored.
    assert_eq!(times, vec![100.0, 200.0]);
    assert_eq!(r.messages[0].1, "CPU, RAM, NTP or network out of band");
    assert!((r.moving_h * 3600.0 - 300.0).abs() < 1e-9);
}

#[test]
fn an_unnoticed_fault_ends_with_an_unrequested_intervention() {
    // Stuck from 100 s; last motion at 99 s; the supervisor comes 600 s later.
    let r = run(1000, vec![f(100, FaultKind::Stuck)]);
    assert!(r.interventions.is_empty());
    assert_eq!(r.unrequested, vec![699.0]);
    let h = |x: f64| x / 3600.0;
    assert_eq!(r.tsl_h, vec![h(699.0), h(301.0)]);
    assert!((r.tsl_max_h - h(699.0)).abs() < 1e-12);
    assert!((r.tsl_mean_h - h(500.0)).abs() < 1e-12);
    assert!((r.moving_h * 3600.0 - 400.0).abs() < 1e-9);
}

#[test]
fn random_runs_are_deterministic_per_seed() {
    let hours = Duration::from_secs(8 * 3600);
    let a = random_faults(3, hours);
    assert_eq!(a, random_faults(3, hours));
    assert_ne!(a, random_faults(4, hours));
    assert!(a.windows(2).all(|w| w[0].at <= w[1].at));
    let config = SimConfig::new(hours, 3, a);
    let r1 = simulate(&config, &arbiter_document()).unwrap();
    let r2 = simulate(&config, &arbiter_document()).unwrap();
    assert_eq!(r1, r2);
    assert!(!r1.interventions.is_empty());
    let n: usize = r1.reactions.iter().map(|x| x.count).sum();
    assert_eq!(n, r1.interventions.len());
    assert!(r1.autonomy > 0.0 && r1.autonomy < 1.0);
}

#[test]
fn faults_built_in_code_have_the_defaults_of_a_fault_file() {
    let fault = f(3605, FaultKind::TopicSlow);
    assert_eq!((fault.at, fault.fails, fault.lasts), (s(3605), 0, s(120)));
    assert!(fault.target.is_empty());
    assert_eq!(FaultKind::TopicSlow.targets(), ["/scan"]);
    assert_eq!(
        FaultKind::NodeCrash.targets(),
        ["localization", "move_base", "camera"]
    );
    assert!(FaultKind::Stuck.targets().is_empty());
}

#[test]
fn bad_configurations_and_trees_are_errors() {
    let mut config = SimConfig::new(s(10), 1, Vec::new());
    config.tick = Duration::ZERO;
    assert!(matches!(
        simulate(&config, &arbiter_document()),
        Err(SimError::Config(_))
    ));
    config.tick = s(1);
    config.p_fix = Some(1.5);
    assert!(matches!(
        simulate(&config, &arbiter_document()),
        Err(SimError::Config(_))
    ));
    config.p_fix = None;
    let doc = BtDocument::single(TreeDef::new("T", NodeDef::action("Teleport")));
    assert!(matches!(
        simulate(&config, &doc),
        Err(SimError::Definition(_))
    ));
    let doc = BtDocument::single(TreeDef::new(
        "T",
        NodeDef::condition("MonitorError").port("monitor", "battery"),
    ));
    let err = simulate(&config, &doc).unwrap_err();
    assert!(err.to_string().contains("battery"), "{err}");
}
