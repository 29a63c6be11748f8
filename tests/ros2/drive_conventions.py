"""Drives `chronomap ros2` as ROS 2 tools drive any node, for tests/cli/ros2_conventions.rs.

Usage: drive_conventions.py CHRONOMAP_BINARY PLAN.json MODE > RESULT.json

MODE `parameters`: the plan's command line starts the node (ROS arguments: remaps, parameter
files, -p); the driver reads the ROS graph, lists, gets, describes and sets parameters through
the `rcl_interfaces` services with rclpy's `AsyncParameterClient` (what `ros2 param` does),
records when the predictions arrive before and after `publish_period` is set, what
`/parameter_events` and `/rosout` carry, and stops the node with SIGINT.

MODE `lifecycle`: the node runs `--managed`; the driver asks an rclpy `LifecycleNode` (the
reference, rcl_lifecycle) and the node for their states, transitions and transition graph, then
drives the node through the plan's `change_state` requests, recording after each the answer,
the state, the `transition_event`s and how many predictions arrived.

The result (JSON on stdout) holds what was observed and the node's stdout, stderr and exit
code; every check is in the Rust test. Run it inside a private network namespace.
"""

import json
import signal
import subprocess
import sys
import time

import rclpy
from lifecycle_msgs.msg import TransitionEvent
from lifecycle_msgs.srv import (
    ChangeState,
    GetAvailableStates,
    GetAvailableTransitions,
    GetState,
)
from rcl_interfaces.msg import Log, ParameterEvent, ParameterType
from rclpy.lifecycle import LifecycleNode
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Bool, Float64

WAIT_SECS = 20.0


def value_json(v):
    """An rcl_interfaces/msg/ParameterValue as [type, value]."""
    field = {
        ParameterType.PARAMETER_NOT_SET: None,
        ParameterType.PARAMETER_BOOL: "bool_value",
        ParameterType.PARAMETER_INTEGER: "integer_value",
        ParameterType.PARAMETER_DOUBLE: "double_value",
        ParameterType.PARAMETER_STRING: "string_value",
        ParameterType.PARAMETER_DOUBLE_ARRAY: "double_array_value",
        ParameterType.PARAMETER_INTEGER_ARRAY: "integer_array_value",
        ParameterType.PARAMETER_STRING_ARRAY: "string_array_value",
    }[v.type]
    value = None if field is None else getattr(v, field)
    if hasattr(value, "tolist"):
        value = value.tolist()
    elif isinstance(value, (list, tuple)) or type(value).__name__ == "array":
        value = list(value)
    return [v.type, value]


def parameter(name, value):
    """An rclpy Parameter of the type of `value` (as `ros2 param set` types its text)."""
    kinds = {bool: Parameter.Type.BOOL, int: Parameter.Type.INTEGER,
             float: Parameter.Type.DOUBLE, str: Parameter.Type.STRING}
    return Parameter(name, kinds[type(value)], value)


class Driver:
    def __init__(self, plan, binary):
        self.plan = plan
        self.node = Node("conventions_driver")
        self.process = subprocess.Popen(
            [binary] + plan["command"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=plan.get("cwd"),
        )
        self.arrivals = []
        every = QoSProfile(
            depth=1000,
            history=HistoryPolicy.KEEP_LAST,
            reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.VOLATILE,
        )
        self.every = every
        self.node.create_subscription(
            Float64, plan["probability"], lambda m: self.arrivals.append(time.monotonic()), every
        )
        self.door = self.node.create_publisher(Bool, plan["door"], every)
        self.clients = {}

    def spin(self, seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            rclpy.spin_once(self.node, timeout_sec=0.02)

    def wait(self, future, what):
        deadline = time.monotonic() + WAIT_SECS
        while not future.done():
            if time.monotonic() > deadline:
                raise RuntimeError(f"timed out waiting for {what}")
            if self.process.poll() is not None:
                raise RuntimeError(f"the node ended while waiting for {what}: {self.process.stderr.read()}")
            rclpy.spin_once(self.node, timeout_sec=0.02)
        return future.result()

    def until(self, condition, what):
        deadline = time.monotonic() + WAIT_SECS
        while not condition():
            if time.monotonic() > deadline:
                raise RuntimeError(f"timed out waiting for {what}")
            if self.process.poll() is not None:
                raise RuntimeError(f"the node ended while waiting for {what}: {self.process.stderr.read()}")
            rclpy.spin_once(self.node, timeout_sec=0.02)

    def publish_doors(self, count):
        for k in range(count):
            self.door.publish(Bool(data=k % 3 == 0))
            self.spin(0.01)

    def stop(self):
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
        stdout, stderr = self.process.communicate(timeout=WAIT_SECS)
        return {"returncode": self.process.returncode, "stdout": stdout, "stderr": stderr}

    def intervals(self, seconds):
        """Times between predictions arriving within `seconds` from now."""
        start = len(self.arrivals)
        self.spin(seconds)
        times = self.arrivals[start:]
        return [b - a for a, b in zip(times, times[1:])]

    def parameters(self):
        plan = self.plan
        events, logs = [], []
        self.node.create_subscription(
            ParameterEvent, "/parameter_events", events.append, self.every
        )
        self.node.create_subscription(Log, "/rosout", logs.append, self.every)
        client = AsyncParameterClient(self.node, plan["node"])
        if not client.wait_for_services(timeout_sec=WAIT_SECS):
            raise RuntimeError("the parameter services did not appear")
        self.until(lambda: self.door.get_subscription_count() > 0, "the node reading the door")
        self.until(lambda: len(self.arrivals) > 0, "a first prediction")
        graph = {
            "nodes": sorted(
                ns.rstrip("/") + "/" + name for name, ns in self.node.get_node_names_and_namespaces()
            ),
            "topics": {name: kinds for name, kinds in self.node.get_topic_names_and_types()},
        }
        names = self.wait(client.list_parameters(), "list_parameters").result.names
        got = self.wait(client.get_parameters(plan["get"]), "get_parameters").values
        described = self.wait(client.describe_parameters(plan["get"]), "describe_parameters")
        self.publish_doors(30)
        before = self.intervals(2.5)
        set_ok = self.wait(
            client.set_parameters([parameter(n, v) for n, v in plan["set"]]), "set_parameters"
        ).results
        after = self.intervals(2.5)
        refused = self.wait(
            client.set_parameters([parameter(n, v) for n, v in plan["refused"]]),
            "set_parameters (refused)",
        ).results
        atomic = self.wait(
            client.set_parameters_atomically([parameter(n, v) for n, v in plan["atomic"]]),
            "set_parameters_atomically",
        ).result
        got_after = self.wait(client.get_parameters(plan["get"]), "get_parameters").values
        self.spin(0.5)
        return {
            "graph": graph,
            "list": list(names),
            "get": [value_json(v) for v in got],
            "describe": [
                {"name": d.name, "type": d.type, "read_only": d.read_only,
                 "description": d.description}
                for d in described.descriptors
            ],
            "intervals_before": before,
            "set": [[r.successful, r.reason] for r in set_ok],
            "intervals_after": after,
            "refused": [[r.successful, r.reason] for r in refused],
            "atomic": [atomic.successful, atomic.reason],
            "get_after": [value_json(v) for v in got_after],
            "parameter_events": [
                {"node": e.node,
                 "changed": [[p.name, value_json(p.value)] for p in e.changed_parameters],
                 "new": [[p.name, value_json(p.value)] for p in e.new_parameters]}
                for e in events
            ],
            "rosout": [
                {"name": m.name, "level": m.level, "msg": m.msg, "file": m.file,
                 "function": m.function, "line": m.line}
                for m in logs if m.name != "conventions_driver"
            ],
        }

    def call(self, srv, name, request):
        client = self.clients.get(name)
        if client is None:
            client = self.node.create_client(srv, name)
            if not client.wait_for_service(timeout_sec=WAIT_SECS):
                raise RuntimeError(f"{name} did not appear")
            self.clients[name] = client
        return self.wait(client.call_async(request), name)

    def machine(self, node):
        """States, transitions and graph of a lifecycle node, as plain JSON."""
        def transitions(r):
            return [[t.transition.id, t.transition.label, t.start_state.id, t.goal_state.id]
                    for t in r.available_transitions]
        return {
            "state": self.call(GetState, f"{node}/get_state", GetState.Request()).current_state.id,
            "states": [[s.id, s.label] for s in self.call(
                GetAvailableStates, f"{node}/get_available_states", GetAvailableStates.Request()
            ).available_states],
            "transitions": transitions(self.call(
                GetAvailableTransitions, f"{node}/get_available_transitions",
                GetAvailableTransitions.Request())),
            "graph": transitions(self.call(
                GetAvailableTransitions, f"{node}/get_transition_graph",
                GetAvailableTransitions.Request())),
        }

    def lifecycle(self):
        plan = self.plan
        node = plan["node"]
        reference = LifecycleNode("reference_lifecycle")
        executor = rclpy.executors.SingleThreadedExecutor()
        executor.add_node(reference)
        # The reference answers from its own executor; the driver's node spins in `wait`.
        import threading
        stop = threading.Event()
        spinner = threading.Thread(
            target=lambda: [executor.spin_once(timeout_sec=0.05) for _ in iter(stop.is_set, True)]
        )
        spinner.start()
        try:
            expected = self.machine("/reference_lifecycle")
        finally:
            stop.set()
            spinner.join()
        events = []
        self.node.create_subscription(
            TransitionEvent, f"{node}/transition_event", events.append, self.every
        )
        actual = self.machine(node)
        steps = []
        parameters = None
        for step in plan["steps"]:
            if "set" in step:
                if parameters is None:
                    parameters = AsyncParameterClient(self.node, node)
                    parameters.wait_for_services(timeout_sec=WAIT_SECS)
                r = self.wait(parameters.set_parameters([parameter(n, v) for n, v in step["set"]]),
                              "set_parameters").results
                steps.append({"set": [[x.successful, x.reason] for x in r]})
                continue
            seen = len(events)
            request = ChangeState.Request()
            request.transition.id = step.get("id", 0)
            request.transition.label = step.get("label", "")
            success = self.call(ChangeState, f"{node}/change_state", request).success
            state = self.call(GetState, f"{node}/get_state", GetState.Request()).current_state.id
            if state in (2, 3):
                # The subscription of a node just configured is discovered before doors are sent.
                self.until(lambda: self.door.get_subscription_count() > 0, "the door subscription")
            self.spin(0.1)
            publishers = self.node.count_publishers(plan["probability"])
            self.publish_doors(10)
            start = len(self.arrivals)
            self.spin(plan["window"])
            steps.append({
                "request": [request.transition.id, request.transition.label],
                "success": success,
                "state": state,
                "events": [[e.transition.id, e.transition.label, e.start_state.id,
                            e.goal_state.id, e.timestamp > 0] for e in events[seen:]],
                "predictions": len(self.arrivals) - start,
                "publishers": publishers,
            })
        return {"expected": expected, "actual": actual, "steps": steps}


def main():
    binary, plan_file, mode = sys.argv[1], sys.argv[2], sys.argv[3]
    with open(plan_file, encoding="utf-8") as f:
        plan = json.load(f)
    rclpy.init()
    started = time.monotonic()
    driver = Driver(plan, binary)
    try:
        result = driver.parameters() if mode == "parameters" else driver.lifecycle()
        result["node"] = driver.stop()
    finally:
        if driver.process.poll() is None:
            driver.process.kill()
            driver.process.wait()
        rclpy.shutdown()
    json.dump(result, sys.stdout)
    print(f"{mode}: {time.monotonic() - started:.1f} s", file=sys.stderr)


if __name__ == "__main__":
    main()
