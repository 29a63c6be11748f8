"""Drives `chronomap ros2` from a real ROS 2 stack (rclpy on Fast DDS) for tests/cli/ros2_node.rs
and tests/cli/ros2_crash.rs.

Usage: drive_node.py CHRONOMAP_BINARY PLAN.json PHASE > RESULT.json

The plan (written by the Rust test) lists phases; the driver runs one: it starts the node (the
binary, with the plan's parameter file), publishes the phase's steps, reads what the node
publishes, and stops the node with SIGINT. Each phase is a fresh process, as a restarted robot
is: no endpoint of a node that stopped is still matched. A step publishes, in this order:
/clock (simulated time), then optionally a door state (std_msgs/Bool), a value of a continuous
state (std_msgs/Float64, with the plan's `interval`), an observed map (nav_msgs/OccupancyGrid),
people (geometry_msgs/PoseArray), a message of the wrong type on a state topic and an oversized
map (`"oversized": SIDE`, a SIDE x SIDE OccupancyGrid on the map topic). Every
`flow_every` steps and at the end the driver waits until the node has published the people map
stamped with that step's clock (flow control: the node has then taken everything before it).

A phase with `"kill"` ends differently, as a crash does: after its last flow-controlled step
the driver waits `kill["wait"]` seconds (the node has acknowledged everything before by
publishing it, and its journal has had time to sync), publishes the `kill["in_flight"]` steps
without waiting for anything, and kills the node with SIGKILL at once.

The result (JSON on stdout) holds the node's stdout, stderr and exit code, what
was sent and the last messages the node published at the final clock (predicted map, mask,
people map, probability, entropy), and the topic types the ROS graph shows. With `interval` in
the plan (the continuous state's topics, and `ros_msgs`, the built chronomap_msgs:
tests/ros2/chronomap_msgs_path.py), the final messages also hold that state's stamped
prediction (chronomap_msgs/msg/Prediction) and the answer of ~/predict for it at the plan's
`times`. Only this script talks to DDS; every check is in the Rust test. Run it inside a
private network namespace.
"""

import json
import os
import signal
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import chronomap_msgs_path  # noqa: E402

# The plan names the built chronomap_msgs when it asks for the continuous state's interval
# (sudo, which may start the namespace, drops the environment).
with open(sys.argv[2], encoding="utf-8") as plan_file:
    PLAN = json.load(plan_file)
if "interval" in PLAN:
    chronomap_msgs_path.setup(PLAN["ros_msgs"])

import rclpy  # noqa: E402
from driving import EVERY, LATEST, WAIT_SECS, RosDriver  # noqa: E402
from node_interfaces import predict_at, prediction_json  # noqa: E402
from geometry_msgs.msg import Pose, PoseArray  # noqa: E402
from nav_msgs.msg import OccupancyGrid  # noqa: E402
from std_msgs.msg import Bool, Float64  # noqa: E402


def grid_json(msg):
    """An OccupancyGrid as plain JSON."""
    return {
        "stamp": [msg.header.stamp.sec, msg.header.stamp.nanosec],
        "frame_id": msg.header.frame_id,
        "load_time": [msg.info.map_load_time.sec, msg.info.map_load_time.nanosec],
        "resolution": msg.info.resolution,
        "width": msg.info.width,
        "height": msg.info.height,
        "origin": [
            msg.info.origin.position.x,
            msg.info.origin.position.y,
            msg.info.origin.position.z,
            msg.info.origin.orientation.x,
            msg.info.origin.orientation.y,
            msg.info.origin.orientation.z,
            msg.info.origin.orientation.w,
        ],
        "data": list(msg.data),
    }


class Driver(RosDriver):
    def __init__(self, plan):
        super().__init__("chronomap_test_driver")
        self.plan = plan
        topics = plan["topics"]
        n = self.node
        self.door = n.create_publisher(Bool, topics["door"], EVERY)
        self.map = n.create_publisher(OccupancyGrid, topics["map"], EVERY)
        self.people = n.create_publisher(PoseArray, topics["people"], EVERY)
        # A publisher of the wrong type on a topic the node reads as std_msgs/Bool.
        self.wrong = n.create_publisher(OccupancyGrid, topics["wrong"], EVERY)
        self.latest = {}
        outputs = {
            "map": (OccupancyGrid, topics["predicted_map"]),
            "mask": (OccupancyGrid, topics["mask"]),
            "people_map": (OccupancyGrid, topics["people_map"]),
            "probability": (Float64, topics["probability"]),
            "entropy": (Float64, topics["entropy"]),
        }
        for key, (kind, topic) in outputs.items():
            n.create_subscription(kind, topic, self.keeper(key), LATEST)
        self.interval = plan.get("interval")
        self.level = None
        if self.interval is not None:
            from chronomap_msgs.msg import Prediction
            from chronomap_msgs.srv import Predict

            self.level = n.create_publisher(Float64, self.interval["topic"], EVERY)
            n.create_subscription(
                Prediction, self.interval["prediction"], self.keeper("level"), LATEST
            )
            self.predict = n.create_client(Predict, self.interval["predict"])

    def keeper(self, key):
        def keep(msg):
            self.latest[key] = msg

        return keep

    def stamp_of(self, key):
        msg = self.latest.get(key)
        return None if msg is None else msg.header.stamp.sec

    def occupancy(self, frame, stamp):
        info = self.plan["map_info"]
        msg = OccupancyGrid()
        msg.header.stamp.sec = stamp
        msg.header.frame_id = "map"
        msg.info.resolution = info["resolution"]
        msg.info.width = info["width"]
        msg.info.height = info["height"]
        msg.info.origin.position.x = info["origin"][0]
        msg.info.origin.position.y = info["origin"][1]
        msg.info.origin.orientation.w = 1.0
        msg.data = frame
        return msg

    def publish_step(self, step, sent):
        """Publishes one step: the clock, then what the step holds."""
        t = step["clock"]
        self.publish_clock(t)
        if "door" in step:
            msg = Bool()
            msg.data = bool(step["door"])
            self.door.publish(msg)
            sent["door"] += 1
        if "level" in step:
            msg = Float64()
            msg.data = float(step["level"])
            self.level.publish(msg)
            sent["level"] = sent.get("level", 0) + 1
        if "map" in step:
            frame = self.plan["frames"][step["map"]]
            self.map.publish(self.occupancy(frame["data"], frame["time"]))
            sent["maps"] += 1
        if "people" in step:
            msg = PoseArray()
            msg.header.stamp.sec = t
            msg.header.frame_id = "map"
            for x, y in step["people"]:
                pose = Pose()
                pose.position.x = x
                pose.position.y = y
                pose.orientation.w = 1.0
                msg.poses.append(pose)
            self.people.publish(msg)
            sent["people"] += 1
        if step.get("wrong"):
            self.wrong.publish(self.occupancy(self.plan["frames"][0]["data"], t))
            sent["wrong"] += 1
        if "oversized" in step:
            # A map larger than the node accepts (max_map_cells): DDS drops it.
            side = step["oversized"]
            msg = self.occupancy([0] * (side * side), t)
            msg.info.width = side
            msg.info.height = side
            self.map.publish(msg)
            sent["oversized"] = sent.get("oversized", 0) + 1

    def crash(self, kill, process, sent, started, discovered):
        """Waits, publishes the in-flight steps and kills the node with SIGKILL."""
        settle = time.monotonic() + kill["wait"]
        while time.monotonic() < settle:
            rclpy.spin_once(self.node, timeout_sec=0.05)
        acknowledged = dict(sent)
        for step in kill["in_flight"]:
            self.publish_step(step, sent)
            rclpy.spin_once(self.node, timeout_sec=0.0)
        process.kill()
        stdout, stderr = process.communicate(timeout=WAIT_SECS)
        return {
            "returncode": process.returncode,
            "stdout": stdout,
            "stderr": stderr,
            "sent": sent,
            "acknowledged": acknowledged,
            "discovery_seconds": discovered,
            "seconds": time.monotonic() - started,
        }

    def run_phase(self, phase, binary, config):
        started = time.monotonic()
        process = subprocess.Popen(
            [binary, "ros2", "--config", config, "--json"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            return self.drive(phase, process, started)
        finally:
            if process.poll() is None:
                process.kill()
                process.wait()

    def drive(self, phase, process, started):
        steps = phase["steps"]
        first = steps[0]["clock"]
        # Discovery: repeat the first clock until the node answers with the people map (a grid
        # that exists from the start) and reads every input topic.
        deadline = time.monotonic() + WAIT_SECS
        readers = [self.door, self.map, self.people] + ([self.level] if self.level else [])
        while self.stamp_of("people_map") != first or any(
            p.get_subscription_count() == 0 for p in readers
        ):
            if time.monotonic() > deadline or process.poll() is not None:
                raise RuntimeError(
                    "the node did not answer on the ROS graph: "
                    + (process.stderr.read() if process.poll() is not None else "still running")
                )
            self.publish_clock(first)
            rclpy.spin_once(self.node, timeout_sec=0.1)
        discovered = time.monotonic() - started
        sent = {"door": 0, "maps": 0, "people": 0, "wrong": 0}
        for i, step in enumerate(steps):
            self.publish_step(step, sent)
            t = step["clock"]
            if (i + 1) % self.plan["flow_every"] == 0 or i + 1 == len(steps):
                self.spin_until(lambda: self.stamp_of("people_map") == t, f"the people map at {t}")
        if "kill" in phase:
            return self.crash(phase["kill"], process, sent, started, discovered)
        last = steps[-1]["clock"]
        self.spin_until(
            lambda: all(self.stamp_of(k) == last for k in ("map", "mask", "people_map")),
            f"the maps at {last}",
        )
        if self.level is not None:
            self.spin_until(
                lambda: "level" in self.latest and self.latest["level"].made.sec == last,
                f"the prediction of {self.interval['state']} made at {last}",
            )
        # The node publishes nothing more until the clock moves; take what is in flight.
        settle = time.monotonic() + 0.5
        while time.monotonic() < settle:
            rclpy.spin_once(self.node, timeout_sec=0.05)
        final = {
            "clock": last,
            "map": grid_json(self.latest["map"]),
            "mask": grid_json(self.latest["mask"]),
            "people_map": grid_json(self.latest["people_map"]),
            "probability": self.latest["probability"].data,
            "entropy": self.latest["entropy"].data,
        }
        if self.level is not None:
            final["level"] = prediction_json(self.latest["level"])
            final["predict"] = predict_at(
                self, self.predict, self.interval["state"], self.interval["times"]
            )
        types = {name: kinds for name, kinds in self.node.get_topic_names_and_types()}
        process.send_signal(signal.SIGINT)
        stdout, stderr = process.communicate(timeout=WAIT_SECS)
        return {
            "returncode": process.returncode,
            "stdout": stdout,
            "stderr": stderr,
            "sent": sent,
            "final": final,
            "topic_types": types,
            "discovery_seconds": discovered,
            "seconds": time.monotonic() - started,
        }


def main():
    binary, phase = sys.argv[1], int(sys.argv[3])
    rclpy.init()
    try:
        result = Driver(PLAN).run_phase(PLAN["phases"][phase], binary, PLAN["config"])
    finally:
        rclpy.shutdown()
    json.dump(result, sys.stdout)
    print(
        f"phase {phase}: {result['seconds']:.1f} s (discovery {result['discovery_seconds']:.1f} s)",
        file=sys.stderr,
    )


if __name__ == "__main__":
    main()
