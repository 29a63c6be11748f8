"""Writes rosbag2 bags with the PyPI `rosbags` package (real ROS 2 message definitions, no ROS
installation), and CDR bytes with rclpy's `serialize_message`, for chronomap's bag tests
(`tests/cli/ingest.rs`).

Usage (one JSON object on stdout describing what was written):

  ros2_bags.py states TRAIN.txt BAG TOPIC TYPE [COMPRESSION]
      `t value` lines -> one std_msgs/msg/Bool or Float64 message each, logged at t (ns).
      COMPRESSION: none (default), file, message or storage (zstd, as rosbag2 does); sqlite
      (SQLite 3 storage, as rosbag2 wrote by default up to Humble) or sqlite-humble (the same
      without the message definitions, which rosbag2 stores only since Iron).
  ros2_bags.py maps FRAMES.json BAG TOPIC
      {"width", "height", "resolution", "origin": [x, y, yaw], "frame_id",
       "frames": [{"time", "data": [int8...]}]} -> nav_msgs/msg/OccupancyGrid, header.stamp = time.
  ros2_bags.py people EVENTS.txt BAG TOPIC
      `t x y ...` lines -> geometry_msgs/msg/PoseArray, the detections of one time in one message.
  ros2_bags.py tracks TRACKS.csv BAG TOPIC
      ATC rows `t,person,x,y,speed,heading` -> people_msgs/msg/People (registered from its .msg
      text, so the bag carries its definition as a real robot's bag does), names = person ids.
  ros2_bags.py cdr OUT.json
      rclpy serialize_message of a Bool, a Float64, an OccupancyGrid, a PoseArray, a LaserScan
      and an Odometry with known fields, as hex.
"""

import json
import lzma
import math
import sys
from pathlib import Path


def read_lines(path):
    opener = lzma.open if str(path).endswith(".xz") else open
    with opener(path, "rt") as f:
        for line in f:
            line = line.strip()
            if line and not line.startswith("#"):
                yield line.split()


def stamp(t):
    """builtin_interfaces/Time fields of unix seconds t (exact to the nanosecond)."""
    sec = math.floor(t)
    nanosec = round((t - sec) * 1e9)
    if nanosec >= 1_000_000_000:
        sec, nanosec = sec + 1, nanosec - 1_000_000_000
    return int(sec), int(nanosec)


def ns(t):
    sec, nanosec = stamp(t)
    return sec * 1_000_000_000 + nanosec


def writer(bag, compression="none"):
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

    if compression.startswith("sqlite"):
        return Writer(Path(bag), version=9, storage_plugin=StoragePlugin.SQLITE3)
    w = Writer(Path(bag), version=9, storage_plugin=StoragePlugin.MCAP)
    if compression != "none":
        w.set_compression(CompressionMode[compression.upper()], CompressionFormat.ZSTD)
    return w


def typestore():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_KILTED)


def header(store, t, frame_id):
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    sec, nanosec = stamp(t)
    return Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id=frame_id)


def states(train, bag, topic, msgtype, compression="none"):
    store = typestore()
    Msg = store.types[msgtype]
    count = 0
    with writer(bag, compression) as w:
        conn = w.add_connection(topic, msgtype, typestore=store)
        for t, v in read_lines(train):
            t, v = float(t), float(v)
            data = bool(v) if msgtype.endswith("Bool") else v
            w.write(conn, ns(t), store.serialize_cdr(Msg(data=data), msgtype))
            count += 1
    if compression == "sqlite-humble":
        # As rosbag2 up to Humble wrote it: no message definitions in the bag.
        import sqlite3

        for db in Path(bag).glob("*.db3"):
            with sqlite3.connect(db) as con:
                con.execute("DROP TABLE message_definitions")
    return {"messages": count}


def maps(frames_json, bag, topic):
    import numpy as np

    store = typestore()
    T = store.types
    spec = json.loads(Path(frames_json).read_text())
    x, y, yaw = spec["origin"]
    origin = T["geometry_msgs/msg/Pose"](
        position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
        orientation=T["geometry_msgs/msg/Quaternion"](
            x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)
        ),
    )
    with writer(bag) as w:
        conn = w.add_connection(topic, "nav_msgs/msg/OccupancyGrid", typestore=store)
        for frame in spec["frames"]:
            t = frame["time"]
            info = T["nav_msgs/msg/MapMetaData"](
                map_load_time=header(store, t, "").stamp,
                resolution=spec["resolution"],
                width=spec["width"],
                height=spec["height"],
                origin=origin,
            )
            msg = T["nav_msgs/msg/OccupancyGrid"](
                header=header(store, t, spec["frame_id"]),
                info=info,
                data=np.array(frame["data"], dtype=np.int8),
            )
            w.write(conn, ns(t), store.serialize_cdr(msg, "nav_msgs/msg/OccupancyGrid"))
    return {"messages": len(spec["frames"])}


PERSON_MSG = """string name
geometry_msgs/Point position
geometry_msgs/Point velocity
float64 reliability
string[] tagnames
string[] tags
"""
PEOPLE_MSG = "std_msgs/Header header\npeople_msgs/Person[] people\n"


def people(events, bag, topic):
    """`t x y ...` event lines -> geometry_msgs/msg/PoseArray, one message per time."""
    store = typestore()
    T = store.types
    Point = T["geometry_msgs/msg/Point"]
    groups = group_by_time([float(f[0]), float(f[1]), float(f[2])] for f in read_lines(events))
    with writer(bag) as w:
        conn = w.add_connection(topic, "geometry_msgs/msg/PoseArray", typestore=store)
        for t, rows in groups:
            poses = [
                T["geometry_msgs/msg/Pose"](
                    position=Point(x=r[1], y=r[2], z=0.0),
                    orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                )
                for r in rows
            ]
            msg = T["geometry_msgs/msg/PoseArray"](header=header(store, t, "map"), poses=poses)
            w.write(conn, ns(t), store.serialize_cdr(msg, "geometry_msgs/msg/PoseArray"))
    return {"messages": len(groups), "detections": sum(len(r) for _, r in groups)}


def tracks(csv, bag, topic):
    """ATC rows `t,person,x,y,speed,heading` -> people_msgs/msg/People (its definition
    registered from .msg text and stored in the bag), one message per time, names = ids."""
    from rosbags.typesys import get_types_from_msg

    store = typestore()
    types = get_types_from_msg(PERSON_MSG, "people_msgs/msg/Person")
    types.update(get_types_from_msg(PEOPLE_MSG, "people_msgs/msg/People"))
    store.register(types)
    T = store.types
    Point = T["geometry_msgs/msg/Point"]
    opener = lzma.open if str(csv).endswith(".xz") else open
    with opener(csv, "rt") as f:
        rows = [line.strip().split(",") for line in f if line.strip()]
    rows = [[float(r[0]), r[1], float(r[2]), float(r[3]), float(r[4]), float(r[5])] for r in rows]
    rows.sort(key=lambda r: r[0])  # stable: equal times keep the file order
    groups = group_by_time(rows)
    with writer(bag) as w:
        conn = w.add_connection(topic, "people_msgs/msg/People", typestore=store)
        for t, group in groups:
            persons = [
                T["people_msgs/msg/Person"](
                    name=r[1],
                    position=Point(x=r[2], y=r[3], z=0.0),
                    velocity=Point(x=r[4] * math.cos(r[5]), y=r[4] * math.sin(r[5]), z=0.0),
                    reliability=1.0,
                    tagnames=[],
                    tags=[],
                )
                for r in group
            ]
            msg = T["people_msgs/msg/People"](header=header(store, t, "map"), people=persons)
            w.write(conn, ns(t), store.serialize_cdr(msg, "people_msgs/msg/People"))
    return {"messages": len(groups), "detections": len(rows)}


def group_by_time(rows):
    groups = []
    for r in rows:
        if not groups or groups[-1][0] != r[0]:
            groups.append((r[0], []))
        groups[-1][1].append(r)
    return groups


def cdr(out):
    from builtin_interfaces.msg import Time
    from geometry_msgs.msg import Pose, PoseArray
    from nav_msgs.msg import OccupancyGrid, Odometry
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import LaserScan
    from std_msgs.msg import Bool, Float64

    def hdr(m, sec, nanosec, frame):
        m.header.stamp = Time(sec=sec, nanosec=nanosec)
        m.header.frame_id = frame
        return m

    grid = hdr(OccupancyGrid(), 1451865600, 500000000, "map")
    grid.info.resolution = 0.05
    grid.info.width, grid.info.height = 3, 2
    grid.info.origin.position.x, grid.info.origin.position.y = -1.5, 2.25
    grid.data = [0, 100, -1, 50, 0, 100]
    poses = hdr(PoseArray(), 1495617883, 770000000, "map")
    for x, y in [(16.4862, -1.0019), (2.5, -0.9)]:
        p = Pose()
        p.position.x, p.position.y = x, y
        poses.poses.append(p)
    scan = hdr(LaserScan(), 1137834225, 713386112, "laser")
    scan.angle_min, scan.angle_max, scan.angle_increment = -1.5707964, 1.5707964, 0.008726646
    scan.range_max = 80.0
    scan.ranges = [1.69, float("inf"), 2.5]
    odom = hdr(Odometry(), 1137834226, 83918080, "odom")
    odom.child_frame_id = "base_link"
    odom.pose.pose.position.x, odom.pose.pose.position.y = -4.8, -21.2
    odom.pose.pose.orientation.z, odom.pose.pose.orientation.w = math.sin(0.5), math.cos(0.5)
    odom.twist.twist.linear.x, odom.twist.twist.angular.z = 0.4, -0.1
    messages = {
        "std_msgs/msg/Bool": Bool(data=True),
        "std_msgs/msg/Float64": Float64(data=0.25),
        "nav_msgs/msg/OccupancyGrid": grid,
        "geometry_msgs/msg/PoseArray": poses,
        "sensor_msgs/msg/LaserScan": scan,
        "nav_msgs/msg/Odometry": odom,
    }
    result = {name: serialize_message(m).hex() for name, m in messages.items()}
    Path(out).write_text(json.dumps(result))
    return {"messages": len(result)}


def main():
    mode, args = sys.argv[1], sys.argv[2:]
    modes = {"states": states, "maps": maps, "people": people, "tracks": tracks, "cdr": cdr}
    result = modes[mode](*args)
    print(json.dumps(result))
    from importlib.metadata import version

    print(f"rosbags {version('rosbags')}", file=sys.stderr)


if __name__ == "__main__":
    main()
