"""Delivery delay of large maps, chronomap's ROS 2 node against Fast DDS: `chronomap bench ros2`.

Usage: bench_maps.py --node CHRONOMAP --dir DIR --sides 1000,2000 --maps 10 --period 1.0 > OUT.json

Run inside a private network namespace (the Rust side makes one). For every side S:

1. chronomap: the node (`CHRONOMAP ros2`, a parameter file in DIR with one map of the default
   FreMEn model, `map_period` PERIOD) learns one S x S OccupancyGrid that this script
   publishes, then publishes a predicted S x S map every PERIOD seconds. A subscriber with
   Nav2's map QoS (reliable, transient local, keep last 1) records when each arrives. After
   `WARMUP` maps (start-up, the first transient-local delivery), MAPS maps are measured.
2. Fast DDS: an rclpy publisher in another process (this script with --publisher) publishes
   WARMUP + MAPS maps of the same size with the node's QoS at the same period, stamping each
   with the wall-clock time just before `publish()`; the same subscriber records them.

A delay is receipt time - publish time (one clock: one host). The node stamps a map with its
time when it starts predicting; it also logs (at debug level) when it hands the map to DDS,
in a line `... predicted map stamped SEC.NANOSEC handed to DDS at UNIX_SECONDS ...`; with such
lines the node's delays start there (`reference: "publish"`), and the count of published maps
comes from them; without them they start at the stamp (`reference: "stamp"`, which includes
the prediction) and the count of published maps is estimated from the stamps.

Prints one JSON object: per side, the raw delays of both, the counts and the serialized size.
Only this script talks to DDS; the statistics are computed by the Rust side.
"""

import argparse
import json
import os
import re
import signal
import subprocess
import sys
import time

import numpy as np
import rclpy
from nav_msgs.msg import OccupancyGrid
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

# Maps received before the measured ones (node start-up, learning, the transient-local copy).
WARMUP = 2
# Seconds to wait for the node to match, learn and publish its first map.
START_SECS = 120.0
# The node's log line for a map handed to DDS (see the module doc).
HANDED = re.compile(r"predicted map stamped (\d+)\.(\d{9}) handed to DDS at ([0-9.]+)")

NAV2_MAP_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
# What the node reads maps with by default (docs/ros2.md).
NODE_INPUT_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)


def observed_map(side, stamp):
    """An S x S office-like map: walls on the border and every 50th row and column, else free."""
    data = np.zeros((side, side), dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[::50, :] = 100
    data[:, ::50] = 100
    msg = OccupancyGrid()
    msg.header.frame_id = "map"
    msg.header.stamp.sec = int(stamp)
    msg.header.stamp.nanosec = int((stamp - int(stamp)) * 1e9)
    msg.info.resolution = 0.05
    msg.info.width = side
    msg.info.height = side
    msg.info.origin.orientation.w = 1.0
    msg.data = data.reshape(-1)
    return msg


def serialized_bytes(side, frame_id="map"):
    """CDR size of an S x S OccupancyGrid with `frame_id` (encapsulation header included)."""
    header = 8 + 4 + len(frame_id) + 1  # stamp, string length, characters and NUL
    header += -header % 4  # load time aligned to 4
    info = header + 8 + 4 + 4 + 4  # map_load_time, resolution, width, height
    info += -info % 8  # the pose's doubles aligned to 8
    info += 7 * 8
    return 4 + info + 4 + side * side


class Subscriber:
    """The Nav2-QoS subscriber of one topic: (stamp, frame_id, receipt time) of each map."""

    def __init__(self, node, topic):
        self.received = []
        node.create_subscription(OccupancyGrid, topic, self.on_map, NAV2_MAP_QOS)

    def on_map(self, msg):
        now = time.time()
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        self.received.append(
            {
                "stamp": [msg.header.stamp.sec, msg.header.stamp.nanosec],
                "seconds": stamp,
                "frame_id": msg.header.frame_id,
                "cells": len(msg.data),
                "received": now,
            }
        )


def spin_until(node, done, timeout):
    end = time.time() + timeout
    while not done() and time.time() < end:
        rclpy.spin_once(node, timeout_sec=0.02)
    return done()


def node_parameters(side, period, topic_in, topic_out):
    return (
        "chronomap:\n"
        "  ros__parameters:\n"
        f"    map_period: {period}\n"
        f"    max_map_cells: {max(side * side, 1)}\n"
        "    maps:\n"
        "      bench:\n"
        f"        topic: {topic_in}\n"
        f"        predicted_topic: {topic_out}\n"
        '        mask_topic: ""\n'
        '        filter_info_topic: ""\n'
    )


def run_chronomap(ros, args, side):
    topic_in, topic_out = f"/bench_{side}/observed", f"/bench_{side}/predicted"
    config = os.path.join(args.dir, f"node_{side}.yaml")
    with open(config, "w") as f:
        f.write(node_parameters(side, args.period, topic_in, topic_out))
    log_path = os.path.join(args.dir, f"node_{side}.log")
    with open(log_path, "w") as log:
        process = subprocess.Popen(
            [args.node, "ros2", "--config", config, "--log-level", "debug"],
            stdout=subprocess.DEVNULL,
            stderr=log,
        )
    try:
        publisher = ros.create_publisher(OccupancyGrid, topic_in, NODE_INPUT_QOS)
        sub = Subscriber(ros, topic_out)
        if not spin_until(ros, lambda: publisher.get_subscription_count() > 0, START_SECS):
            raise SystemExit(f"the node did not subscribe to {topic_in} (log: {log_path})")
        # A map published before the node's reader matched this publisher is not delivered
        # (volatile): publish again (a later frame of the same map) until a prediction comes.
        deadline = time.time() + START_SECS
        while not sub.received and time.time() < deadline:
            publisher.publish(observed_map(side, time.time()))
            spin_until(ros, lambda: bool(sub.received), 15.0)
        wanted = WARMUP + args.maps
        spin_until(ros, lambda: len(sub.received) >= wanted, 30 + wanted * args.period * 3)
        # Maps published after the last one measured may still be on their way: count only
        # those handed to DDS at least two periods before the end.
        end = time.time()
        spin_until(ros, lambda: False, 2 * args.period)
    finally:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(timeout=60)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    handed = {}
    with open(log_path) as log:
        for line in log:
            m = HANDED.search(line)
            if m:
                handed[(int(m.group(1)), int(m.group(2)))] = float(m.group(3))
    measured = sub.received[WARMUP : WARMUP + args.maps]
    if not measured:
        # The driver waited long enough for WARMUP + MAPS maps: all MAPS count as lost.
        return {"published": args.maps, "maps": [], "reference": "publish" if handed else "stamp"}
    first = min(r["seconds"] for r in measured)
    maps = []
    for r in measured:
        publish = handed.get(tuple(r["stamp"]), r["seconds"])
        maps.append(
            {
                "stamp": r["seconds"],
                "cells": r["cells"],
                "delay": r["received"] - publish,
                "since_stamp": r["received"] - r["seconds"],
            }
        )
    # The maps published from the first measured one to the last (all measured), or to a
    # period before the driver stopped waiting (some never came).
    complete = len(measured) == args.maps
    last = max(r["seconds"] for r in measured) if complete else end - args.period
    if handed:
        stamps = [s + ns * 1e-9 for (s, ns), at in handed.items() if complete or at <= last]
        published = sum(1 for t in stamps if first - 1e-6 <= t <= last + 1e-6)
        reference = "publish"
    else:
        span = (last - first) / args.period
        published = (round(span) if complete else int(span)) + 1
        reference = "stamp"
    published = max(published, len(maps))
    return {"published": published, "maps": maps, "reference": reference}


def run_fastdds(ros, args, side):
    topic = f"/bench_{side}/fastdds"
    sub = Subscriber(ros, topic)
    count = WARMUP + args.maps
    process = subprocess.Popen(
        [
            sys.executable,
            os.path.abspath(__file__),
            "--publisher",
            "--side",
            str(side),
            "--count",
            str(count),
            "--period",
            str(args.period),
            "--topic",
            topic,
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    spin_until(ros, lambda: process.poll() is not None, START_SECS + count * args.period * 3)
    spin_until(ros, lambda: False, 2 * args.period)
    if process.poll() is None:
        process.kill()
    out, _ = process.communicate()
    published = {}
    for line in out.splitlines():
        p = json.loads(line)
        published[p["frame_id"]] = p["at"]
    maps = []
    for r in sub.received:
        index = int(r["frame_id"].split(":")[1])
        if index >= WARMUP:
            maps.append(
                {
                    "stamp": r["seconds"],
                    "cells": r["cells"],
                    "delay": r["received"] - published.get(r["frame_id"], r["seconds"]),
                }
            )
    return {"published": sum(1 for f in published if int(f.split(":")[1]) >= WARMUP), "maps": maps}


def publisher_main(args):
    """The Fast DDS publisher: WARMUP + MAPS maps, one per period, after the subscriber matched."""
    rclpy.init()
    ros = Node("bench_maps_publisher")
    publisher = ros.create_publisher(OccupancyGrid, args.topic, NAV2_MAP_QOS)
    spin_until(ros, lambda: publisher.get_subscription_count() > 0, START_SECS)
    spin_until(ros, lambda: False, 1.0)
    msg = observed_map(args.side, 0.0)
    start = time.time()
    for i in range(args.count):
        spin_until(ros, lambda: time.time() >= start + i * args.period, args.period * 2)
        msg.header.frame_id = f"bench:{i}"
        now = time.time()
        msg.header.stamp.sec = int(now)
        msg.header.stamp.nanosec = int((now - int(now)) * 1e9)
        publisher.publish(msg)
        print(json.dumps({"frame_id": msg.header.frame_id, "at": now}), flush=True)
    # Stay matched while the last maps are repaired.
    spin_until(ros, lambda: False, 3 * args.period)
    ros.destroy_node()
    rclpy.shutdown()


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--node")
    parser.add_argument("--dir")
    parser.add_argument("--sides", default="1000,2000")
    parser.add_argument("--maps", type=int, default=10)
    parser.add_argument("--period", type=float, default=1.0)
    parser.add_argument("--publisher", action="store_true")
    parser.add_argument("--side", type=int)
    parser.add_argument("--count", type=int)
    parser.add_argument("--topic")
    args = parser.parse_args()
    if args.publisher:
        publisher_main(args)
        return
    rclpy.init()
    ros = Node("bench_maps")
    sides = []
    for side in [int(s) for s in args.sides.split(",")]:
        print(f"{side} x {side}: chronomap's node...", file=sys.stderr, flush=True)
        chronomap = run_chronomap(ros, args, side)
        print(f"{side} x {side}: Fast DDS...", file=sys.stderr, flush=True)
        fastdds = run_fastdds(ros, args, side)
        sides.append(
            {
                "side": side,
                "cells": side * side,
                "bytes": serialized_bytes(side),
                "chronomap": chronomap,
                "fastdds": fastdds,
            }
        )
    ros.destroy_node()
    rclpy.shutdown()
    json.dump(
        {
            "maps": args.maps,
            "warmup": WARMUP,
            "period": args.period,
            "rmw": os.environ.get("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp"),
            "python": sys.version.split()[0],
            "sides": sides,
        },
        sys.stdout,
    )


if __name__ == "__main__":
    main()
