"""Makes the chronomap_msgs interfaces importable in an rclpy driver.

`.ci/run` builds ros/chronomap_msgs with tests/ros2/build_chronomap_msgs.sh into
target/chronomap-msgs and exports CHRONOMAP_ROS_MSGS with that directory. A driver run by the ROS
venv's Python does:

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # tests/ros2
    import chronomap_msgs_path
    chronomap_msgs_path.setup()           # or setup('/path/to/target/chronomap-msgs')
    from chronomap_msgs.msg import Prediction
    from chronomap_msgs.srv import Predict

That is all: setup() puts PREFIX/python first on sys.path and PREFIX on AMENT_PREFIX_PATH (for
tools that look interfaces up in the ament index). No LD_LIBRARY_PATH is needed: the libraries
find one another through their RUNPATH, and the venv's own libraries are found as for the
wheels' message packages. The same from a shell: PYTHONPATH=PREFIX/python.
"""

import os
import sys

STAMP = 'chronomap_msgs.stamp'


def setup(prefix=None):
    """Adds the built package at `prefix` (default: $CHRONOMAP_ROS_MSGS); returns the prefix."""
    if prefix is None:
        prefix = os.environ.get('CHRONOMAP_ROS_MSGS')
        if not prefix:
            raise RuntimeError(
                'CHRONOMAP_ROS_MSGS is not set: build the interfaces with '
                'tests/ros2/build_chronomap_msgs.sh VENV OUTDIR and set it to OUTDIR')
    prefix = os.path.abspath(prefix)
    if not os.path.isfile(os.path.join(prefix, STAMP)):
        raise RuntimeError(
            f'{prefix} holds no built chronomap_msgs (no {STAMP}): build it with '
            'tests/ros2/build_chronomap_msgs.sh VENV OUTDIR')
    python = os.path.join(prefix, 'python')
    if python not in sys.path:
        sys.path.insert(0, python)
    ament = os.environ.get('AMENT_PREFIX_PATH', '')
    if prefix not in ament.split(os.pathsep):
        os.environ['AMENT_PREFIX_PATH'] = os.pathsep.join(p for p in (prefix, ament) if p)
    return prefix
