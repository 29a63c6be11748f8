"""Checks the chronomap_msgs interfaces built for rclpy, and their examples for the Rust side.

Run by the ROS venv's Python inside a private network namespace (DDS discovery must not leave
the machine), with CHRONOMAP_ROS_MSGS naming what tests/ros2/build_chronomap_msgs.sh built:

    unshare -n sh -c 'ip link set lo up && ip link set lo multicast on && exec \
        target/ros-venv/bin/python tests/ros2/check_chronomap_msgs.py'

It checks, failing with a message naming what differs:

1. tests/ros2/chronomap_msgs_examples.json against rclpy: `serialize_message` of each example
   equals the recorded CDR bytes except in the alignment padding (Fast CDR leaves padding bytes
   unwritten, so rclpy's are whatever the buffer held; the recorded ones are zero), the recorded
   bytes deserialize to the example's field values, and they equal what the plain CDR encoder
   below (XCDR1, little endian, written from the interface definitions) makes of the values;
2. the RIHS01 type hashes recorded there against those the generator wrote and those rclpy's
   endpoints announce, and the DDS topic and type names against the ROS graph;
3. an rclpy publisher → rclpy subscriber of chronomap_msgs/msg/Prediction, and an rclpy
   client → rclpy server of chronomap_msgs/srv/Predict (answering and refusing), in two
   processes over UDP, the values received equal to those sent.

`--write-examples` rewrites the examples file from the values below after checks 1 and 2 of
the new content; `--serve` is the talker process of check 3.
"""

import json
import math
import os
import pathlib
import struct
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
EXAMPLES = HERE / 'chronomap_msgs_examples.json'
sys.path.insert(0, str(HERE))
import chronomap_msgs_path  # noqa: E402

PREFIX = pathlib.Path(chronomap_msgs_path.setup())

import rclpy  # noqa: E402
from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402

from chronomap_msgs.msg import Prediction  # noqa: E402
from chronomap_msgs.srv import Predict  # noqa: E402


def entropy_bits(p):
    """Binary entropy in bits."""
    if p <= 0.0 or p >= 1.0:
        return 0.0
    return -(p * math.log2(p) + (1.0 - p) * math.log2(1.0 - p))


# The examples: a prediction of a continuous state (with its interval) as the node publishes
# it, and one service call answered and one refused. Values are exact in binary where possible;
# entropies are what entropy_bits computes. (A state without an interval has lower = upper =
# NaN and coverage 0.0; NaN does not compare equal, so the examples carry an interval.)
EXAMPLE_VALUES = {
    'prediction': {
        'header': {'stamp': {'sec': 1700003600, 'nanosec': 250000000}, 'frame_id': ''},
        'name': 'level',
        'model': 'fremen:2',
        'probability': 0.25,
        'entropy': entropy_bits(0.25),
        'made': {'sec': 1700000000, 'nanosec': 1},
        'observations': 1234,
        'lower': 0.0625,
        'upper': 0.5,
        'coverage': 0.9,
    },
    'predict_request': {
        'name': 'door',
        'times': [{'sec': 1700000000, 'nanosec': 0}, {'sec': 1700003600, 'nanosec': 500000000}],
    },
    'predict_response': {
        'success': True,
        'message': '',
        'model': 'fremen:2',
        'probability': [0.25, 0.5],
        'entropy': [entropy_bits(0.25), 1.0],
        'coverage': 0.9,
        'lower': [0.0625, 0.125],
        'upper': [0.5, 0.875],
    },
    'predict_response_refused': {
        'success': False,
        'message': "no state named 'window'",
        'model': '',
        'probability': [],
        'entropy': [],
        'coverage': 0.0,
        'lower': [],
        'upper': [],
    },
}
TYPES = {
    'prediction': ('chronomap_msgs/msg/Prediction', Prediction),
    'predict_request': ('chronomap_msgs/srv/Predict_Request', Predict.Request),
    'predict_response': ('chronomap_msgs/srv/Predict_Response', Predict.Response),
    'predict_response_refused': ('chronomap_msgs/srv/Predict_Response', Predict.Response),
}
# What rmw_fastrtps_cpp names them on the wire; checked against the ROS graph below.
DDS = {
    'chronomap_msgs/msg/Prediction': 'chronomap_msgs::msg::dds_::Prediction_',
    'chronomap_msgs/srv/Predict_Request': 'chronomap_msgs::srv::dds_::Predict_Request_',
    'chronomap_msgs/srv/Predict_Response': 'chronomap_msgs::srv::dds_::Predict_Response_',
}
HASHED = ['chronomap_msgs/msg/Prediction', 'chronomap_msgs/srv/Predict',
          'chronomap_msgs/srv/Predict_Request', 'chronomap_msgs/srv/Predict_Response',
          'chronomap_msgs/srv/Predict_Event']


class Cdr:
    """Plain CDR (XCDR1, little endian) with the 4-byte encapsulation header 00 01 00 00.

    Alignment is relative to the end of that header; padding is written as zeros and its
    offsets (in the whole buffer) are kept in `padding`.
    """

    def __init__(self):
        self.data = bytearray(b'\x00\x01\x00\x00')
        self.padding = []

    def align(self, n):
        while (len(self.data) - 4) % n:
            self.padding.append(len(self.data))
            self.data.append(0)

    def put(self, fmt, value):
        size = struct.calcsize('<' + fmt)
        self.align(size)
        self.data += struct.pack('<' + fmt, value)

    def string(self, s):
        raw = s.encode('utf-8') + b'\x00'
        self.put('I', len(raw))
        self.data += raw

    def time(self, t):
        self.put('i', t['sec'])
        self.put('I', t['nanosec'])

    def f64_seq(self, values):
        self.put('I', len(values))
        for v in values:
            self.put('d', v)


def encode(kind, v):
    c = Cdr()
    if kind == 'prediction':
        c.time(v['header']['stamp'])
        c.string(v['header']['frame_id'])
        c.string(v['name'])
        c.string(v['model'])
        c.put('d', v['probability'])
        c.put('d', v['entropy'])
        c.time(v['made'])
        c.put('Q', v['observations'])
        c.put('d', v['lower'])
        c.put('d', v['upper'])
        c.put('d', v['coverage'])
    elif kind == 'predict_request':
        c.string(v['name'])
        c.put('I', len(v['times']))
        for t in v['times']:
            c.time(t)
    else:
        c.put('?', v['success'])
        c.string(v['message'])
        c.string(v['model'])
        c.f64_seq(v['probability'])
        c.f64_seq(v['entropy'])
        c.put('d', v['coverage'])
        c.f64_seq(v['lower'])
        c.f64_seq(v['upper'])
    return bytes(c.data), c.padding


def to_message(cls, values):
    """A message of `cls` from nested dicts and lists."""
    from builtin_interfaces.msg import Time
    from std_msgs.msg import Header
    msg = cls()
    for field, value in values.items():
        if field == 'header':
            value = Header(stamp=Time(**value['stamp']), frame_id=value['frame_id'])
        elif field == 'made':
            value = Time(**value)
        elif field == 'times':
            value = [Time(**t) for t in value]
        setattr(msg, field, value)
    return msg


def to_values(msg):
    """Nested dicts and lists of a message's fields."""
    if hasattr(msg, 'get_fields_and_field_types'):
        return {f: to_values(getattr(msg, f)) for f in msg.get_fields_and_field_types()}
    if isinstance(msg, (list, tuple)) or type(msg).__name__ == 'array':
        return [to_values(x) for x in msg]
    return msg


def check(condition, message):
    if not condition:
        raise SystemExit(f'check_chronomap_msgs: {message}')


def generated_hashes():
    out = {}
    for rel in ['msg/Prediction.json', 'srv/Predict.json']:
        for entry in json.loads((PREFIX / 'share/chronomap_msgs' / rel).read_text())['type_hashes']:
            out[entry['type_name']] = entry['hash_string']
    return out


def check_serialization(examples):
    for kind, (type_name, cls) in TYPES.items():
        ex = examples['messages'][kind]
        check(ex['type'] == type_name and ex['dds_type'] == DDS[type_name],
              f'{kind}: type names {ex["type"]}, {ex["dds_type"]}')
        recorded = bytes.fromhex(ex['cdr_hex'])
        mine, padding = encode(kind, ex['values'])
        check(mine == recorded, f'{kind}: the recorded bytes\n  {recorded.hex()}\n'
              f'differ from the plain CDR encoding of its values\n  {mine.hex()}')
        check(padding == ex['padding_offsets'],
              f'{kind}: padding offsets {ex["padding_offsets"]} recorded, {padding} computed')
        msg = to_message(cls, ex['values'])
        theirs = serialize_message(msg)
        check(len(theirs) == ex['rclpy_length'],
              f'{kind}: rclpy serializes {len(theirs)} bytes, the examples file records '
              f'{ex["rclpy_length"]}')
        masked = bytearray(theirs[:len(recorded)])
        for i in padding:
            masked[i] = 0
        check(bytes(masked) == recorded,
              f'{kind}: rclpy serializes {ex["values"]} as\n  {theirs.hex()}\n'
              f'(padding zeroed: {bytes(masked).hex()}), the examples file records\n'
              f'  {recorded.hex()}')
        back = to_values(deserialize_message(recorded, cls))
        check(back == ex['values'],
              f'{kind}: rclpy reads the recorded bytes as {back}, not {ex["values"]}')


def write_examples():
    hashes = generated_hashes()
    examples = {
        'about': (
            'CDR bytes of chronomap_msgs examples as rclpy (ros-kilted-rclpy 9.1.2, '
            'rmw_fastrtps_cpp 9.3.3) serializes them with rclpy.serialization.serialize_message: '
            'the 4-byte encapsulation header 00 01 00 00 (plain CDR, little endian, XCDR1), then '
            'the fields, each aligned to its size (at most 8) counted from the end of that '
            "header. Fast CDR leaves alignment padding unwritten, so rclpy's padding bytes are "
            'arbitrary; here they are zero, at padding_offsets (into the whole buffer). '
            'rclpy_length is the length serialize_message returns: for a response whose four '
            "float64[] are empty it is 16 more than the bytes written (rmw_fastrtps' size "
            'estimate counts alignment before the absent elements); those bytes are arbitrary '
            'and readers ignore them. A service request or response is the payload alone; '
            'rmw_fastrtps_cpp carries the request identity beside it (the related sample '
            'identity in the RTPS inline QoS), not in it. Written and checked by '
            'tests/ros2/check_chronomap_msgs.py.'),
        'topics': {
            'prediction': {'ros': '/NAME', 'dds': 'rt/NAME'},
            'predict_service': {'ros': '/NAME', 'dds_request': 'rq/NAMERequest',
                                'dds_reply': 'rr/NAMEReply'},
        },
        'type_hashes': {name: hashes[name] for name in HASHED},
        'messages': {},
    }
    for kind, (type_name, cls) in TYPES.items():
        values = EXAMPLE_VALUES[kind]
        data, padding = encode(kind, values)
        examples['messages'][kind] = {
            'type': type_name, 'dds_type': DDS[type_name], 'values': values,
            'cdr_hex': data.hex(), 'padding_offsets': padding,
            'rclpy_length': len(serialize_message(to_message(cls, values))),
        }
    check_serialization(examples)
    EXAMPLES.write_text(json.dumps(examples, indent=2, ensure_ascii=False) + '\n')
    print(f'wrote {EXAMPLES}')
    return examples


def spin_until(node, done, timeout, what):
    end = time.monotonic() + timeout
    while not done():
        check(time.monotonic() < end, f'no {what} within {timeout} s')
        rclpy.spin_once(node, timeout_sec=0.05)


def serve(examples):
    """The talker process: publishes the example Prediction and serves Predict until stdin
    closes."""
    import threading
    rclpy.init()
    node = rclpy.create_node('chronomap_msgs_talker')
    sent = to_message(Prediction, examples['messages']['prediction']['values'])
    publisher = node.create_publisher(Prediction, 'chronomap/prediction', 10)

    def predict(request, response):
        if request.name != 'door':
            response.success = False
            response.message = f"no state named '{request.name}'"
            return response
        response.success = True
        response.model = 'fremen:2'
        response.probability = [0.25 + 0.25 * i for i in range(len(request.times))]
        response.entropy = [entropy_bits(p) for p in response.probability]
        response.coverage = 0.9
        response.lower = [0.0625 * 2 ** i for i in range(len(request.times))]
        response.upper = [0.5 + 0.375 * i for i in range(len(request.times))]
        return response

    node.create_service(Predict, 'chronomap/predict', predict)
    node.create_timer(0.1, lambda: publisher.publish(sent))
    closed = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), closed.set()), daemon=True).start()
    end = time.monotonic() + 60
    while not closed.is_set() and time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    rclpy.try_shutdown()


def check_graph_and_traffic(examples):
    """An rclpy talker in another process, over UDP as a peer on another machine would talk."""
    import subprocess
    talker = subprocess.Popen([sys.executable, __file__, '--serve'], stdin=subprocess.PIPE)
    rclpy.init()
    try:
        node = rclpy.create_node('chronomap_msgs_listener')
        received = []
        node.create_subscription(Prediction, 'chronomap/prediction', received.append, 10)
        client = node.create_client(Predict, 'chronomap/predict')

        spin_until(node, lambda: received, 20, 'Prediction from the rclpy publisher')
        sent = examples['messages']['prediction']['values']
        check(to_values(received[0]) == sent,
              f'sent {sent}, received {to_values(received[0])}')

        spin_until(node, client.service_is_ready, 20, 'Predict service')
        request = examples['messages']['predict_request']['values']
        for req, want_kind in [(request, 'predict_response'),
                               ({'name': 'window'}, 'predict_response_refused')]:
            future = client.call_async(to_message(Predict.Request, req))
            spin_until(node, future.done, 20, f'response to {req}')
            got = to_values(future.result())
            want = examples['messages'][want_kind]['values']
            check(got == want, f'Predict({req}) answered {got}, not {want}')

        # Names and hashes of the talker's endpoints as the graph reports them (no_mangle: the
        # DDS names themselves).
        hashes = examples['type_hashes']
        endpoints = [
            ('rt/chronomap/prediction', node.get_publishers_info_by_topic,
             'chronomap_msgs/msg/Prediction'),
            ('rq/chronomap/predictRequest', node.get_subscriptions_info_by_topic,
             'chronomap_msgs/srv/Predict_Request'),
            ('rr/chronomap/predictReply', node.get_publishers_info_by_topic,
             'chronomap_msgs/srv/Predict_Response'),
        ]
        for topic, info, type_name in endpoints:
            def talker_endpoints():
                return [e for e in info(topic, no_mangle=True)
                        if e.node_name == 'chronomap_msgs_talker']
            # The graph learns endpoints' nodes a little after the endpoints themselves.
            spin_until(node, talker_endpoints, 20, f'talker endpoint on DDS topic {topic}')
            found = talker_endpoints()
            check(len(found) == 1, f'{len(found)} talker endpoints on DDS topic {topic}, not 1')
            check(found[0].topic_type == DDS[type_name],
                  f'{topic}: DDS type {found[0].topic_type}, not {DDS[type_name]}')
            check(str(found[0].topic_type_hash) == hashes[type_name],
                  f'{topic}: type hash {found[0].topic_type_hash}, not {hashes[type_name]}')
        types = dict(node.get_service_names_and_types())
        check(types.get('/chronomap/predict') == ['chronomap_msgs/srv/Predict'],
              f'service types {types.get("/chronomap/predict")}')
    finally:
        rclpy.try_shutdown()
        talker.stdin.close()
        try:
            talker.wait(timeout=10)
        except subprocess.TimeoutExpired:
            talker.kill()
            talker.wait()
    check(talker.returncode == 0, f'the talker process exited {talker.returncode}')


def main(argv):
    started = time.monotonic()
    # rclpy's log files go to a directory removed afterwards, unless ROS_HOME names one.
    if 'ROS_HOME' not in os.environ:
        ros_home = tempfile.TemporaryDirectory(prefix='chronomap-msgs-check-')
        os.environ['ROS_HOME'] = ros_home.name
    # Fast DDS over UDP only (no shared memory between the two processes), as with a DDS
    # peer on another machine or one that is not Fast DDS.
    os.environ['FASTDDS_BUILTIN_TRANSPORTS'] = 'UDPv4'
    if argv == ['--serve']:
        serve(json.loads(EXAMPLES.read_text()))
        return 0
    if argv == ['--write-examples']:
        examples = write_examples()
    elif argv:
        print('usage: check_chronomap_msgs.py [--write-examples]', file=sys.stderr)
        return 2
    else:
        check(EXAMPLES.is_file(), f'{EXAMPLES} is missing')
        examples = json.loads(EXAMPLES.read_text())
        check_serialization(examples)
    generated = generated_hashes()
    for name, value in examples['type_hashes'].items():
        check(generated.get(name) == value,
              f'{name}: the generator computed {generated.get(name)}, the examples file '
              f'records {value}')
    check_graph_and_traffic(examples)
    print(f'chronomap_msgs: serialization, type hashes, DDS names, publish/subscribe and '
          f'service call checked in {time.monotonic() - started:.1f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
