"""What the rclpy drivers that read the node's own interfaces (chronomap_msgs) share
(drive_models.py, drive_node.py): a stamped prediction (chronomap_msgs/msg/Prediction) and an
answer of ~/predict (chronomap_msgs/srv/Predict) as plain JSON, and calling a service.

Import it after chronomap_msgs_path.setup(): asking ~/predict imports chronomap_msgs.
"""

import math

from builtin_interfaces.msg import Time


def finite_or_none(x):
    """JSON has no NaN (the node's lower and upper of a state without an interval)."""
    return None if math.isnan(x) else x


def prediction_json(msg):
    """A chronomap_msgs/msg/Prediction as plain JSON."""
    return {
        "stamp": [msg.header.stamp.sec, msg.header.stamp.nanosec],
        "frame_id": msg.header.frame_id,
        "name": msg.name,
        "model": msg.model,
        "probability": msg.probability,
        "entropy": msg.entropy,
        "made": [msg.made.sec, msg.made.nanosec],
        "observations": msg.observations,
        "lower": finite_or_none(msg.lower),
        "upper": finite_or_none(msg.upper),
        "coverage": msg.coverage,
    }


def stamp(t):
    """builtin_interfaces/msg/Time of `t` seconds."""
    whole = int(t)
    return Time(sec=whole, nanosec=int(round((t - whole) * 1e9)))


def call(driver, client, request, what):
    """Calls a service with `driver` (a driving.RosDriver) once it is there: its answer."""
    driver.spin_until(client.service_is_ready, f"the service {what}")
    future = client.call_async(request)
    driver.spin_until(future.done, f"the answer of {what}")
    return future.result()


def predict_at(driver, client, name, times):
    """~/predict (`client`) of the state `name` at `times` (seconds), as plain JSON."""
    from chronomap_msgs.srv import Predict

    request = Predict.Request()
    request.name = name
    request.times = [stamp(t) for t in times]
    answer = call(driver, client, request, "~/predict")
    return {
        "success": answer.success,
        "message": answer.message,
        "model": answer.model,
        "probability": list(answer.probability),
        "entropy": list(answer.entropy),
        "coverage": answer.coverage,
        "lower": list(answer.lower),
        "upper": list(answer.upper),
    }
