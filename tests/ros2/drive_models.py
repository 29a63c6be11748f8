"""Drives `chronomap ros2` from rclpy (Fast DDS) for tests/cli/ros2_models.rs: two models of one
state topic, the stamped predictions (chronomap_msgs/msg/Prediction), and the node's services
~/refit and ~/save (std_srvs/srv/Trigger) and ~/predict (chronomap_msgs/srv/Predict).

Usage: drive_models.py CHRONOMAP_BINARY PLAN.json > RESULT.json

The plan (written by the Rust test) names the parameter file, the steps (a /clock value, a door
state and a value of the continuous state `level` on /level each), the states (the first two
the door's, then the level's), the times to ask ~/predict for, and `flow_every`: every so many
steps the driver waits for the first state's stamped prediction made at that step's clock (the
node has then learned everything before it). After the steps it reads the last predictions,
asks for a refit and waits until the refitted model predicts something else than 0.5, asks
~/predict, asks ~/save, moves the clock once more to see the refitted model's stamped
prediction, and stops the node with SIGINT. Every check is in the Rust test. Run it inside a
private network namespace with CHRONOMAP_ROS_MSGS set (tests/ros2/chronomap_msgs_path.py).
"""

import json
import os
import signal
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import chronomap_msgs_path  # noqa: E402

# The plan names the built chronomap_msgs (sudo, which may start the namespace, drops the
# environment).
with open(sys.argv[2], encoding="utf-8") as plan_file:
    PLAN = json.load(plan_file)
chronomap_msgs_path.setup(PLAN["ros_msgs"])

import rclpy  # noqa: E402
from chronomap_msgs.msg import Prediction  # noqa: E402
from chronomap_msgs.srv import Predict  # noqa: E402
from driving import EVERY, LATEST, WAIT_SECS, RosDriver  # noqa: E402
from node_interfaces import call, predict_at, prediction_json  # noqa: E402
from std_msgs.msg import Bool, Float64  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402


class Driver(RosDriver):
    def __init__(self, plan):
        super().__init__("chronomap_models_driver")
        self.plan = plan
        n = self.node
        self.door = n.create_publisher(Bool, "/door", EVERY)
        self.level = n.create_publisher(Float64, "/level", EVERY)
        self.latest = {}
        for name in plan["states"]:
            n.create_subscription(
                Prediction, f"/chronomap/{name}/prediction", self.keeper(name), LATEST
            )
        self.predict = n.create_client(Predict, "/chronomap/predict")
        self.save = n.create_client(Trigger, "/chronomap/save")
        self.refit = n.create_client(Trigger, "/chronomap/refit")

    def keeper(self, name):
        def keep(msg):
            self.latest[name] = msg

        return keep

    def made(self, name):
        msg = self.latest.get(name)
        return None if msg is None else msg.made.sec

    def call(self, client, request, what):
        return call(self, client, request, what)

    def predict_at(self, name, times):
        return predict_at(self, self.predict, name, times)

    def run(self, binary):
        started = time.monotonic()
        process = subprocess.Popen(
            [binary, "ros2", "--config", self.plan["config"], "--json"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            return self.drive(process, started)
        finally:
            if process.poll() is None:
                process.kill()
                process.wait()

    def drive(self, process, started):
        steps = self.plan["steps"]
        first_state, refitted = self.plan["states"][:2]
        first = steps[0]["clock"]
        deadline = time.monotonic() + WAIT_SECS
        while self.made(first_state) != first or self.door.get_subscription_count() == 0:
            if time.monotonic() > deadline or process.poll() is not None:
                raise RuntimeError(
                    "the node did not answer on the ROS graph: "
                    + (process.stderr.read() if process.poll() is not None else "still running")
                )
            self.publish_clock(first)
            rclpy.spin_once(self.node, timeout_sec=0.1)
        for i, step in enumerate(steps):
            t = step["clock"]
            self.publish_clock(t)
            msg = Bool()
            msg.data = bool(step["door"])
            self.door.publish(msg)
            level = Float64()
            level.data = float(step["level"])
            self.level.publish(level)
            if (i + 1) % self.plan["flow_every"] == 0 or i + 1 == len(steps):
                self.spin_until(lambda: self.made(first_state) == t, f"a prediction made at {t}")
        last = steps[-1]["clock"]
        for name in self.plan["states"][1:]:
            self.spin_until(lambda: self.made(name) == last, f"{name}'s prediction at {last}")
        before = {name: prediction_json(self.latest[name]) for name in self.plan["states"]}
        refit = self.call(self.refit, Trigger.Request(), "~/refit")
        probe = [last + self.plan["horizon"]]
        deadline = time.monotonic() + WAIT_SECS
        while self.predict_at(refitted, probe)["probability"] == [0.5]:
            if time.monotonic() > deadline:
                raise RuntimeError(f"{refitted} still predicts 0.5 {WAIT_SECS} s after ~/refit")
            time.sleep(0.1)
        answers = {
            name: self.predict_at(name, self.plan["times"]) for name in self.plan["states"]
        }
        answers["unknown"] = self.predict_at("window", self.plan["times"])
        save = self.call(self.save, Trigger.Request(), "~/save")
        # The clock moves on: the refitted model's stamped prediction.
        after_clock = last + 2
        self.publish_clock(after_clock)
        self.spin_until(
            lambda: self.made(refitted) == after_clock, f"{refitted}'s prediction at {after_clock}"
        )
        after = prediction_json(self.latest[refitted])
        process.send_signal(signal.SIGINT)
        stdout, stderr = process.communicate(timeout=WAIT_SECS)
        return {
            "returncode": process.returncode,
            "stdout": stdout,
            "stderr": stderr,
            "before_refit": before,
            "refit": {"success": refit.success, "message": refit.message},
            "answers": answers,
            "save": {"success": save.success, "message": save.message},
            "after_refit": after,
            "after_clock": after_clock,
            "seconds": time.monotonic() - started,
        }


def main():
    rclpy.init()
    try:
        result = Driver(PLAN).run(sys.argv[1])
    finally:
        rclpy.shutdown()
    json.dump(result, sys.stdout)
    print(f"drive_models: {result['seconds']:.1f} s", file=sys.stderr)


if __name__ == "__main__":
    main()
