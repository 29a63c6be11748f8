"""What the rclpy drivers of the node's tests share (drive_node.py, drive_models.py): an rclpy node
with the two QoS profiles they use, a /clock publisher and waiting with a deadline.
"""

import time

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock

# How long a driver waits for anything before it gives up (and the test fails).
WAIT_SECS = 30.0

# What the drivers publish: reliable, volatile, deep enough that nothing is dropped.
EVERY = QoSProfile(
    depth=10000,
    history=HistoryPolicy.KEEP_LAST,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
# How they read the node's latched outputs: reliable, transient local, the latest only.
LATEST = QoSProfile(
    depth=1,
    history=HistoryPolicy.KEEP_LAST,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)


class RosDriver:
    """An rclpy node named `name` that publishes simulated time on /clock."""

    def __init__(self, name):
        self.node = Node(name)
        self.clock = self.node.create_publisher(Clock, "/clock", EVERY)

    def spin_until(self, condition, what):
        deadline = time.monotonic() + WAIT_SECS
        while not condition():
            if time.monotonic() > deadline:
                raise RuntimeError(f"timed out after {WAIT_SECS} s waiting for {what}")
            rclpy.spin_once(self.node, timeout_sec=0.05)

    def publish_clock(self, t):
        msg = Clock()
        msg.clock.sec = t
        self.clock.publish(msg)
