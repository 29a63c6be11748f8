//! A configured node: its parameters, models, topics and schedules, and one round of it.

use std::collections::{BTreeMap, HashSet, VecDeque};
use std::time::Instant;

use ros2_client::Context;
use ros2_client::Node;
use ros2_client::dds::rustdds::mio1::Poll;

use super::clock::{Pending, SIM_LATENCY_NS, Schedule, SimClock, received_ns, system_now_ns};
use super::io::{GridReader, Io, StateInput, WriterCheck};
use super::refits::Refits;
use super::throttle::{Throttle, log_due, throttle};
use super::{MAX_TAKE, NodeError, Summary};
use crate::config::NodeConfig;
use crate::msgs::{Float64, Time};
use crate::world::{StoreError, World};

/// Learns a value of a state topic with every state of it, logging what is refused (once per
/// topic and reason, whichever state refused it).
pub(super) fn learn_state(
    world: &mut World,
    throttles: &mut BTreeMap<String, Throttle>,
    input: &StateInput,
    time: f64,
    value: f64,
) {
    let topic = &input.topic;
    for &index in &input.states {
        match world.observe_state(index, time, value) {
            Ok(true) => log::trace!("{topic}: learned {value} at {time}"),
            Ok(false) => log::debug!("{topic}: {value} at {time} not learned: a day off"),
            Err(e) => throttle(throttles, topic).error(topic, || e.to_string()),
        }
    }
}

/// What a configured node holds: its checked parameters (the dynamic ones as last set), the
/// models, the subscriptions and publishers, and the state of its schedules.
pub(super) struct Configured {
    pub(super) config: NodeConfig,
    pub(super) world: World,
    pub(super) io: Io,
    pub(super) sim_clock: Option<SimClock>,
    pub(super) pending: VecDeque<Pending>,
    pub(super) check: WriterCheck,
    pub(super) throttles: BTreeMap<String, Throttle>,
    pub(super) schedules: [Schedule; 3],
    pub(super) infos_published: bool,
    pub(super) last_save: Instant,
    pub(super) waiting_for_clock_logged: bool,
    pub(super) refits: Refits,
}

impl Configured {
    /// Configures: restores the models ([`World::new`]) and opens the subscriptions and
    /// publishers.
    pub(super) fn open(
        node: &mut Node,
        config: NodeConfig,
        poll: &Poll,
    ) -> Result<Configured, NodeError> {
        let world = World::new(config.clone())?;
        let (io, inputs) = Io::open(node, &config, poll)?;
        let refits = Refits::new(config.states.len());
        Ok(Configured {
            sim_clock: config.use_sim_time.then(SimClock::default),
            config,
            world,
            io,
            pending: VecDeque::new(),
            check: WriterCheck {
                inputs,
                reported: HashSet::new(),
                wrong: HashSet::new(),
                right: HashSet::new(),
                last: None,
            },
            throttles: BTreeMap::new(),
            schedules: Default::default(),
            infos_published: false,
            last_save: Instant::now(),
            waiting_for_clock_logged: false,
            refits,
        })
    }

    /// Takes the dynamic parameters of `new` (periods, horizon, filters); what changed is
    /// published at once.
    pub(super) fn update(&mut self, new: &NodeConfig) {
        let old = &self.config;
        if new.publish_period != old.publish_period || new.horizon != old.horizon {
            self.schedules[0] = Schedule::default();
        }
        if new.map_period != old.map_period || new.horizon != old.horizon {
            self.schedules[1] = Schedule::default();
        }
        if new.edges.as_ref().map(|e| e.period) != old.edges.as_ref().map(|e| e.period)
            || new.horizon != old.horizon
        {
            self.schedules[2] = Schedule::default();
        }
        let filters = |c: &NodeConfig| c.grids.iter().map(|g| g.filter.clone()).collect::<Vec<_>>();
        if filters(new) != filters(old) {
            self.infos_published = false;
        }
        self.config = new.clone();
    }

    /// One round of an active node: take what arrived, learn it, publish what is due.
    pub(super) fn step(&mut self, context: &Context) {
        let Configured {
            config,
            world,
            io,
            sim_clock,
            pending,
            check,
            throttles,
            schedules,
            infos_published,
            last_save,
            waiting_for_clock_logged,
            refits,
        } = self;
        let inputs = &io.state_inputs;
        let grids = &io.grids;
        check.scan(context);
        // With simulated time, what was received before the cutoff is complete.
        let cutoff = system_now_ns() - SIM_LATENCY_NS;
        if let (Some(reader), Some(clock)) = (&io.clock, sim_clock.as_mut()) {
            for _ in 0..MAX_TAKE {
                match reader.take() {
                    Ok(Some((msg, info))) => {
                        if check.accepts(context, &info) {
                            let received = received_ns(&info);
                            log::trace!(
                                "{}: {} received at {received} ns",
                                config.clock_topic,
                                msg.clock.seconds()
                            );
                            clock.push(received, msg.clock.seconds());
                        }
                    }
                    Ok(None) => break,
                    Err(e) => throttle(throttles, &config.clock_topic)
                        .error(&config.clock_topic, || e.to_string()),
                }
            }
        }
        for (input, s) in inputs.iter().enumerate() {
            for _ in 0..MAX_TAKE {
                match s.reader.take() {
                    Ok(Some((value, info))) => {
                        if !check.accepts(context, &info) {
                            continue;
                        }
                        let received = received_ns(&info);
                        if sim_clock.is_some() {
                            pending.push_back(Pending {
                                input,
                                received,
                                value,
                            });
                        } else {
                            let time = received as f64 / 1e9;
                            learn_state(world, throttles, s, time, value);
                        }
                    }
                    Ok(None) => break,
                    Err(e) => throttle(throttles, &s.topic).error(&s.topic, || e),
                }
            }
        }
        if let Some(clock) = sim_clock.as_mut() {
            let mut waiting = VecDeque::with_capacity(pending.len());
            for p in pending.drain(..) {
                if p.received > cutoff {
                    waiting.push_back(p);
                    continue;
                }
                let input = &inputs[p.input];
                let topic = &input.topic;
                match clock.at(p.received) {
                    Some(time) => {
                        learn_state(world, throttles, input, time, p.value);
                    }
                    None => throttle(throttles, topic).error(topic, || {
                        "a state before the first /clock message (use_sim_time): not learned".into()
                    }),
                }
            }
            *pending = waiting;
            // Pending states of several topics are not in receive order among each other.
            let oldest = pending
                .iter()
                .map(|p| p.received)
                .min()
                .map_or(cutoff, |r| r.min(cutoff));
            clock.forget_before(oldest);
        }
        for (index, g) in grids.iter().enumerate() {
            for _ in 0..MAX_TAKE {
                let (result, info) = match &g.reader {
                    GridReader::Map(r) => match r.take() {
                        Ok(Some((msg, info))) => {
                            if !check.accepts(context, &info) {
                                continue;
                            }
                            (world.observe_map(index, &msg), info)
                        }
                        Ok(None) => break,
                        Err(e) => {
                            throttle(throttles, &g.topic).error(&g.topic, || e.to_string());
                            continue;
                        }
                    },
                    GridReader::People(r) => match r.take() {
                        Ok(Some((msg, info))) => {
                            if !check.accepts(context, &info) {
                                continue;
                            }
                            (world.observe_people(index, &msg), info)
                        }
                        Ok(None) => break,
                        Err(e) => {
                            throttle(throttles, &g.topic).error(&g.topic, || e.to_string());
                            continue;
                        }
                    },
                };
                match result {
                    Ok(()) => {
                        log::trace!("{}: learned message {}", g.topic, info.sequence_number())
                    }
                    Err(e) => throttle(throttles, &g.topic).error(&g.topic, || e.to_string()),
                }
            }
        }
        log_due(throttles, false);
        refits.step(world);
        // What was learned is durable once the journal is synced (at most `sync_period`).
        world.sync_journal(Instant::now());

        let now = match sim_clock.as_ref() {
            Some(clock) => clock.at(cutoff),
            None => Some(system_now_ns() as f64 / 1e9),
        };
        let Some(now) = now else {
            if !*waiting_for_clock_logged {
                log::info!(
                    "waiting for the first {} message (use_sim_time)",
                    config.clock_topic
                );
                *waiting_for_clock_logged = true;
            }
            return;
        };
        let target = now + config.horizon;
        let stamp = Time::from_seconds(now);
        if !*infos_published {
            for (index, g) in grids.iter().enumerate() {
                let info = world.filter_info(index, stamp).map(|mut info| {
                    // The filter's values as last set (they change at run time).
                    if let Some(f) = &config.grids[index].filter {
                        info.filter_type = f.filter_type;
                        info.base = f.base;
                        info.multiplier = f.multiplier;
                    }
                    info
                });
                if let (Some(publisher), Some(info)) = (&g.info, info)
                    && let Err(e) = publisher.publish(info)
                {
                    log::error!("{}: cannot publish the filter info: {e}", g.topic);
                }
            }
            *infos_published = true;
        }
        if let Some(edges) = &config.edges
            && schedules[2].due(now, edges.period)
        {
            match world.write_route_graph(target) {
                Ok(_) => log::debug!("wrote {} for {target}", edges.geojson.display()),
                Err(e) => log::error!("route graph: {e}"),
            }
        }
        if schedules[0].due(now, config.publish_period) {
            for (index, s) in io.states.iter().enumerate() {
                let prediction = world.state_prediction(index, target, stamp);
                let name = &config.states[index].name;
                for (publisher, data) in [
                    (&s.probability, prediction.probability),
                    (&s.entropy, prediction.entropy),
                ] {
                    if let Err(e) = publisher.publish(Float64 { data }) {
                        log::error!("states.{name}: cannot publish a prediction: {e}");
                    }
                }
                if let Some(publisher) = &s.prediction
                    && let Err(e) = publisher.publish(prediction)
                {
                    log::error!("states.{name}: cannot publish a prediction: {e}");
                }
            }
        }
        if schedules[1].due(now, config.map_period) {
            if let Err(e) = world.close_stale_bins(now) {
                log::error!("people: {e}");
            }
            for (index, g) in grids.iter().enumerate() {
                let Some(prediction) = world.predict_grid(index, target, stamp) else {
                    continue;
                };
                let cells = prediction.map.data.len();
                let handed = system_now_ns();
                match g.map.publish(prediction.map) {
                    Ok(()) => log::debug!(
                        "{}: predicted map stamped {}.{:09} handed to DDS at {:.6} ({cells} cells)",
                        g.topic,
                        stamp.sec,
                        stamp.nanosec,
                        handed as f64 / 1e9
                    ),
                    Err(e) => log::error!("{}: cannot publish the predicted map: {e}", g.topic),
                }
                if let (Some(publisher), Some(mask)) = (&g.mask, prediction.mask)
                    && let Err(e) = publisher.publish(mask)
                {
                    log::error!("{}: cannot publish the mask: {e}", g.topic);
                }
            }
        }
        if last_save.elapsed().as_secs_f64() >= config.save_period {
            *last_save = Instant::now();
            if let Err(e) = world.save(false) {
                log::error!("saving: {e}");
            }
        }
    }

    /// Learns what waits for the clock cutoff and saves (learning open people bins first).
    pub(super) fn finish(&mut self) -> Result<(), StoreError> {
        if let Some(clock) = &self.sim_clock {
            for p in self.pending.drain(..) {
                if let Some(time) = clock.at(p.received) {
                    let input = &self.io.state_inputs[p.input];
                    learn_state(&mut self.world, &mut self.throttles, input, time, p.value);
                }
            }
        }
        log_due(&mut self.throttles, true);
        self.world.save(true).map(drop)
    }

    /// What it learned.
    pub(super) fn summary(&self, save_error: Option<String>) -> Summary {
        let (learned_states, learned_grids) = self.world.learned();
        Summary {
            states: self
                .config
                .states
                .iter()
                .zip(learned_states)
                .map(|(s, l)| (s.name.clone(), l))
                .collect(),
            grids: self
                .config
                .grids
                .iter()
                .zip(learned_grids)
                .map(|(g, l)| (g.section().to_string(), g.name.clone(), l))
                .collect(),
            refused: self
                .throttles
                .iter()
                .map(|(topic, t)| (topic.clone(), t.total))
                .collect(),
            save_error,
            configured: true,
        }
    }
}
