//! The hooks a Groot2 client sets on a tree's nodes, and what they do to the ticks:
//! BehaviorTree.CPP 4.8.2's `Groot2Publisher` (`insertHook`, `unlockBreakpoint`, `removeHook`,
//! `enableAllHooks` and the pre-tick callback it injects into a node), without the waiting.
//!
//! A hook on a node acts before the node's tick (BehaviorTree.CPP 4.8.2 keeps every hook among
//! its pre-tick hooks and installs it as the node's pre-tick callback, whatever the position
//! the client gave): an enabled hook first notifies the clients (BREAKPOINT_REACHED on the PUB
//! socket); a replacement (`mode` 1) then gives its `desired_status` as the node's result
//! (success or failure: the node is not ticked; anything else: it is ticked); a breakpoint
//! (`mode` 0) holds the tick until a client unlocks it (BREAKPOINT_UNLOCK, with a desired
//! status or not), turns it into a replacement, disables it or removes it (then the node is
//! ticked). A hook with `once` is removed after it acted.
//!
//! This module is the table and its rules, no I/O and no clock; [`crate::publisher`] answers
//! the requests with it and holds the ticking thread where [`Hooks::check`] says so.

use std::collections::HashMap;

use chronomap_bt::Status;

use crate::protocol::{BreakpointUnlock, Hook, HookMode, HookPosition, StdUnorderedOrder};

/// A hook as the server keeps it (`Monitor::Hook` with its `ready` flag).
#[derive(Clone, Copy, Debug)]
struct Entry {
    hook: Hook,
    /// A client unlocked the breakpoint and the tick has not consumed it yet.
    ready: bool,
    /// Which hook this is: a hook inserted at position POST replaces the node's hook by a new
    /// one (BehaviorTree.CPP makes a new `Hook` object), so a tick held by the old one must
    /// not take the new one for its own.
    id: u64,
    /// How many times BehaviorTree.CPP would have woken a tick waiting on this hook
    /// (`hook->wakeup.notify_all()`): a held tick looks at the hook again only then.
    wakeups: u64,
}

/// The hooks of one tree, by node uid, in the iteration order of BehaviorTree.CPP's
/// `std::unordered_map<uint16_t, Hook::Ptr>` (HOOKS_DUMP lists them so).
#[derive(Debug)]
pub(crate) struct Hooks {
    map: HashMap<u16, Entry>,
    order: StdUnorderedOrder<u16>,
    next_id: u64,
    node_count: usize,
}

/// An enabled hook met by a tick ([`Hooks::reach`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Reached {
    /// Which hook.
    pub id: u64,
    /// Whether it holds the tick.
    pub breakpoint: bool,
}

/// What a tick held at a breakpoint does next ([`Hooks::check`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Check {
    /// Keep waiting.
    Wait,
    /// Go on: the node's result is the one [`Hooks::finish`] gives.
    Go,
    /// The hook was disabled or removed: tick the node (`SKIPPED`).
    Skip,
}

impl Hooks {
    /// No hooks, for a tree of `node_count` nodes (uids 1 to `node_count`).
    pub(crate) fn new(node_count: usize) -> Hooks {
        Hooks {
            map: HashMap::new(),
            order: StdUnorderedOrder::new(),
            next_id: 1,
            node_count,
        }
    }

    fn fresh(&mut self, hook: Hook) -> Entry {
        let id = self.next_id;
        self.next_id += 1;
        Entry {
            hook,
            ready: false,
            id,
            wakeups: 0,
        }
    }

    /// HOOK_INSERT of one hook (BehaviorTree.CPP's `InsertHook`): a hook on no node is
    /// ignored; a PRE hook on a node that has one updates it (a breakpoint turned into a
    /// replacement releases the tick it holds); otherwise the node's hook becomes a new one.
    pub(crate) fn insert(&mut self, hook: Hook) {
        if hook.uid == 0 || usize::from(hook.uid) > self.node_count {
            return;
        }
        if hook.position == HookPosition::Pre
            && let Some(entry) = self.map.get_mut(&hook.uid)
        {
            let was_breakpoint = entry.hook.mode == HookMode::Breakpoint;
            entry.hook = hook;
            if was_breakpoint && hook.mode == HookMode::Replace {
                entry.ready = true;
                entry.wakeups += 1;
            }
            return;
        }
        // `getHook(POST, uid)` looks among post-tick hooks, which BehaviorTree.CPP never
        // fills: a POST hook is always a new one, and it takes the node's place among the
        // pre-tick hooks.
        let entry = self.fresh(hook);
        self.map.insert(hook.uid, entry);
        self.order.insert(hook.uid, u64::from(hook.uid));
    }

    /// HOOK_REMOVE (`removeHook`): `false` when the node has no hook at that position ("Node
    /// ID not found"); a removed breakpoint releases the tick it holds.
    pub(crate) fn remove(&mut self, uid: u16, position: HookPosition) -> bool {
        if position != HookPosition::Pre || self.map.remove(&uid).is_none() {
            return false;
        }
        self.order.remove(&uid);
        true
    }

    /// REMOVE_ALL_HOOKS (`removeAllHooks`).
    pub(crate) fn remove_all(&mut self) {
        self.map.clear();
        self.order = StdUnorderedOrder::new();
    }

    /// BREAKPOINT_UNLOCK (`unlockBreakpoint`): sets the hook's result (success, failure, or
    /// skipped: tick the node) and `once` (or-ed); a breakpoint's tick may go on. `false` when
    /// the node has no hook at that position.
    pub(crate) fn unlock(&mut self, unlock: &BreakpointUnlock) -> bool {
        if unlock.position != HookPosition::Pre {
            return false;
        }
        let Some(entry) = self.map.get_mut(&unlock.uid) else {
            return false;
        };
        entry.hook.desired_status = unlock.desired_status;
        entry.hook.once |= unlock.remove_when_done;
        if entry.hook.mode == HookMode::Breakpoint {
            entry.ready = true;
            entry.wakeups += 1;
        }
        true
    }

    /// `enableAllHooks`: DISABLE_ALL_HOOKS, and the publisher's heartbeat (hooks disabled
    /// when the clients went silent, enabled again when one speaks). Disabled breakpoints
    /// release the ticks they hold.
    pub(crate) fn enable_all(&mut self, enable: bool) {
        for entry in self.map.values_mut() {
            entry.hook.enabled = enable;
            if !enable && entry.hook.mode == HookMode::Breakpoint {
                entry.wakeups += 1;
            }
        }
    }

    /// HOOKS_DUMP's JSON array.
    pub(crate) fn dump(&self) -> String {
        let items: Vec<String> = self
            .order
            .keys()
            .filter_map(|uid| self.map.get(uid))
            .map(|e| e.hook.to_json())
            .collect();
        format!("[{}]", items.join(","))
    }

    /// The number of hooks.
    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.map.len()
    }

    /// Before the tick of node `uid`: its hook if it has one and it is enabled (then the
    /// clients are notified, and a breakpoint holds the tick). `None`: tick the node.
    pub(crate) fn reach(&self, uid: u16) -> Option<Reached> {
        let entry = self.map.get(&uid).filter(|e| e.hook.enabled)?;
        Some(Reached {
            id: entry.id,
            breakpoint: entry.hook.mode == HookMode::Breakpoint,
        })
    }

    /// A tick held by hook `id` of node `uid` looks at it (`wakeup.wait(lk, ready ||
    /// !enabled)`): the first time (`seen` is `None`) and whenever the hook was woken since
    /// `seen`; otherwise [`Check::Wait`]. An unlocked hook's `ready` is consumed.
    pub(crate) fn check(&mut self, uid: u16, id: u64, seen: &mut Option<u64>) -> Check {
        // Removed (BehaviorTree.CPP disables a breakpoint it removes) or replaced by a new
        // hook (BehaviorTree.CPP would hold the tick for good: released here).
        let Some(entry) = self.map.get_mut(&uid).filter(|e| e.id == id) else {
            return Check::Skip;
        };
        if *seen == Some(entry.wakeups) {
            return Check::Wait;
        }
        *seen = Some(entry.wakeups);
        // The wait ends when `ready || !enabled`.
        if !entry.ready && entry.hook.enabled {
            return Check::Wait;
        }
        entry.ready = false;
        if entry.hook.enabled {
            Check::Go
        } else {
            Check::Skip
        }
    }

    /// The end of hook `id`'s act on node `uid`: the node's hook is removed if this one has
    /// `once`; the node's result (`desired_status`: a success or failure replaces the tick).
    pub(crate) fn finish(&mut self, uid: u16, id: u64) -> Option<Status> {
        let entry = *self.map.get(&uid).filter(|e| e.id == id)?;
        if entry.hook.once {
            self.map.remove(&uid);
            self.order.remove(&uid);
        }
        Some(entry.hook.desired_status)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hook(uid: u16, mode: HookMode, status: Status, once: bool) -> Hook {
        Hook {
            enabled: true,
            uid,
            mode,
            once,
            desired_status: status,
            position: HookPosition::Pre,
        }
    }

    fn unlock(uid: u16, status: Status, remove: bool) -> BreakpointUnlock {
        BreakpointUnlock {
            uid,
            position: HookPosition::Pre,
            desired_status: status,
            remove_when_done: remove,
        }
    }

    /// The act of the hook of `uid` as a tick that does not wait: `None` no hook, else the
    /// checks until go or skip (at most `rounds`), and the result.
    fn act(hooks: &mut Hooks, uid: u16) -> Option<(Check, Option<Status>)> {
        let r = hooks.reach(uid)?;
        if !r.breakpoint {
            return Some((Check::Go, hooks.finish(uid, r.id)));
        }
        let mut seen = None;
        match hooks.check(uid, r.id, &mut seen) {
            Check::Go => Some((Check::Go, hooks.finish(uid, r.id))),
            c => Some((c, None)),
        }
    }

    #[test]
    fn replacement_gives_its_status_and_once_removes_it() {
        let mut h = Hooks::new(5);
        h.insert(hook(3, HookMode::Replace, Status::Failure, false));
        h.insert(hook(4, HookMode::Replace, Status::Success, true));
        assert_eq!(act(&mut h, 3), Some((Check::Go, Some(Status::Failure))));
        assert_eq!(act(&mut h, 3), Some((Check::Go, Some(Status::Failure))));
        assert_eq!(act(&mut h, 4), Some((Check::Go, Some(Status::Success))));
        assert_eq!(act(&mut h, 4), None);
        assert_eq!(act(&mut h, 2), None);
        assert_eq!(h.len(), 1);
    }

    #[test]
    fn hooks_on_no_node_are_ignored() {
        let mut h = Hooks::new(5);
        h.insert(hook(0, HookMode::Replace, Status::Failure, false));
        h.insert(hook(6, HookMode::Replace, Status::Failure, false));
        assert_eq!(h.len(), 0);
        assert_eq!(h.dump(), "[]");
    }

    #[test]
    fn breakpoint_waits_for_unlock_and_takes_its_status() {
        let mut h = Hooks::new(5);
        h.insert(hook(2, HookMode::Breakpoint, Status::Skipped, false));
        let r = h.reach(2).unwrap();
        assert!(r.breakpoint);
        let mut seen = None;
        assert_eq!(h.check(2, r.id, &mut seen), Check::Wait);
        assert_eq!(h.check(2, r.id, &mut seen), Check::Wait);
        assert!(h.unlock(&unlock(2, Status::Success, false)));
        assert_eq!(h.check(2, r.id, &mut seen), Check::Go);
        assert_eq!(h.finish(2, r.id), Some(Status::Success));
        // Not removed: the next tick waits again (ready was consumed), with the last status.
        let mut seen = None;
        assert_eq!(h.check(2, r.id, &mut seen), Check::Wait);
        assert!(h.unlock(&unlock(2, Status::Skipped, true)));
        assert_eq!(h.check(2, r.id, &mut seen), Check::Go);
        assert_eq!(h.finish(2, r.id), Some(Status::Skipped));
        assert_eq!(h.len(), 0);
    }

    #[test]
    fn unlock_before_the_breakpoint_lets_the_next_tick_through() {
        let mut h = Hooks::new(5);
        h.insert(hook(2, HookMode::Breakpoint, Status::Skipped, false));
        assert!(h.unlock(&unlock(2, Status::Failure, false)));
        assert_eq!(act(&mut h, 2), Some((Check::Go, Some(Status::Failure))));
        assert_eq!(act(&mut h, 2), Some((Check::Wait, None)));
    }

    #[test]
    fn unlock_and_remove_of_what_is_not_there_fail() {
        let mut h = Hooks::new(5);
        h.insert(hook(2, HookMode::Breakpoint, Status::Skipped, false));
        assert!(!h.unlock(&unlock(3, Status::Success, false)));
        let mut post = unlock(2, Status::Success, false);
        post.position = HookPosition::Post;
        assert!(!h.unlock(&post));
        assert!(!h.remove(2, HookPosition::Post));
        assert!(!h.remove(3, HookPosition::Pre));
        assert!(h.remove(2, HookPosition::Pre));
        assert!(!h.remove(2, HookPosition::Pre));
    }

    #[test]
    fn removal_disabling_and_replacement_release_a_held_tick() {
        for how in 0..5 {
            let mut h = Hooks::new(5);
            h.insert(hook(2, HookMode::Breakpoint, Status::Skipped, false));
            let r = h.reach(2).unwrap();
            let mut seen = None;
            assert_eq!(h.check(2, r.id, &mut seen), Check::Wait);
            let expect = match how {
                0 => {
                    h.remove(2, HookPosition::Pre);
                    Check::Skip
                }
                1 => {
                    h.remove_all();
                    Check::Skip
                }
                2 => {
                    h.enable_all(false);
                    Check::Skip
                }
                3 => {
                    // A PRE insert of a replacement: the same hook, now giving failure.
                    h.insert(hook(2, HookMode::Replace, Status::Failure, false));
                    Check::Go
                }
                _ => {
                    // A POST insert: a new hook in its place; the held tick lets go.
                    let mut post = hook(2, HookMode::Breakpoint, Status::Skipped, false);
                    post.position = HookPosition::Post;
                    h.insert(post);
                    Check::Skip
                }
            };
            assert_eq!(h.check(2, r.id, &mut seen), expect, "case {how}");
            if expect == Check::Go {
                assert_eq!(h.finish(2, r.id), Some(Status::Failure));
            }
        }
    }

    #[test]
    fn a_disabled_hook_does_not_act_until_enabled_again() {
        let mut h = Hooks::new(5);
        h.insert(hook(2, HookMode::Replace, Status::Failure, false));
        h.enable_all(false);
        assert_eq!(act(&mut h, 2), None);
        assert_eq!(
            h.dump(),
            r#"[{"desired_status":"FAILURE","enabled":false,"mode":1,"once":false,"position":0,"uid":2}]"#
        );
        h.enable_all(true);
        assert_eq!(act(&mut h, 2), Some((Check::Go, Some(Status::Failure))));
    }

    #[test]
    fn changing_a_held_breakpoint_without_waking_it_keeps_it_held() {
        // BehaviorTree.CPP wakes a held tick only when it notifies the hook: disabling it by
        // a HOOK_INSERT with "enabled": false does not (the tick goes on at the next wake-up).
        let mut h = Hooks::new(5);
        h.insert(hook(2, HookMode::Breakpoint, Status::Skipped, false));
        let r = h.reach(2).unwrap();
        let mut seen = None;
        assert_eq!(h.check(2, r.id, &mut seen), Check::Wait);
        let mut off = hook(2, HookMode::Breakpoint, Status::Skipped, false);
        off.enabled = false;
        h.insert(off);
        assert_eq!(h.check(2, r.id, &mut seen), Check::Wait);
        h.unlock(&unlock(2, Status::Success, false));
        assert_eq!(h.check(2, r.id, &mut seen), Check::Skip);
    }

    #[test]
    fn post_hooks_take_the_place_of_the_nodes_hook_and_keep_its_order() {
        let mut h = Hooks::new(20);
        for uid in [3, 1, 2] {
            h.insert(hook(uid, HookMode::Replace, Status::Success, false));
        }
        let before = h.dump();
        let mut post = hook(1, HookMode::Replace, Status::Success, false);
        post.position = HookPosition::Post;
        h.insert(post);
        assert_eq!(
            h.dump(),
            before.replace(r#""position":0,"uid":1"#, r#""position":1,"uid":1"#)
        );
        // It acts before the tick, as every hook of BehaviorTree.CPP 4.8.2.
        assert_eq!(act(&mut h, 1), Some((Check::Go, Some(Status::Success))));
    }
}
