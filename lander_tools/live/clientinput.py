"""What clients of the live bridge may send, checked for shape before it is forwarded to the flight.

The bridge (:mod:`lander_tools.live.bridge`) forwards client publishes and service calls to the
flight's own doors; here only the shape is checked (JSON, numbers where numbers go, the service's
fields and their types). The values (NaN, ranges, lengths) are the nodes' to judge and count.
Plain Python: no rclpy, no foxglove.
"""
from __future__ import annotations

import json
from typing import Any

#: The services clients may call: name -> (ROS type, request fields and their JSON schema types).
SERVICE_FIELDS: dict[str, tuple[str, dict[str, Any]]] = {
    # name -> (ROS type, request fields and their JSON schema types)
    "/lander/pause": ("std_srvs/srv/Trigger", {}),
    "/lander/resume": ("std_srvs/srv/Trigger", {}),
    "/lander/step": ("lander_interfaces/srv/StepSimulation", {"steps": "integer"}),
    "/lander/reset": ("lander_interfaces/srv/Reset", {"use_seed": "boolean", "seed": "integer"}),
    "/lander/deploy_parachute": ("std_srvs/srv/Trigger", {}),
    "/lander/set_stabiliser": ("std_srvs/srv/SetBool", {"data": "boolean"}),
    "/autopilot/switch_controller": ("lander_interfaces/srv/SwitchController",
                                     {"controller": "string", "parameters_yaml": "string"}),
}


class ClientInputError(ValueError):
    """A client's input the bridge cannot forward (malformed, wrong type, unknown topic)."""


def _number(obj: dict[str, Any], key: str, what: str) -> float:
    v = obj.get(key) if isinstance(obj, dict) else None
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ClientInputError(f"{what}: field {key!r} must be a number, got {v!r}")
    return float(v)


def parse_client_message(topic: str, data: bytes) -> tuple[str, Any]:
    """Decode one client-published JSON message: ``(kind, value)`` for the forwarding step.

    Only the shape is checked here (numbers where numbers go); the values (NaN, ranges, lengths)
    are the nodes' to judge. Python's JSON reader accepts ``NaN``/``Infinity``, so such a value
    reaches the node and is refused and counted there."""
    try:
        obj = json.loads(data)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ClientInputError(f"{topic}: not JSON ({exc})") from None
    if topic == "/lander/demand_altitude":
        return "demand", _number(obj, "data", topic)
    if topic == "/lander/wind":
        return "wind", [_number(obj, k, topic) for k in ("x", "y", "z")]
    if topic == "/lander/throttle":
        vals = obj.get("throttles") if isinstance(obj, dict) else None
        if not isinstance(vals, list) or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in vals):
            raise ClientInputError(f"{topic}: field 'throttles' must be a list of numbers, got {vals!r}")
        return "throttle", [float(v) for v in vals]
    raise ClientInputError(f"{topic}: not a topic clients may publish "
                           "(/lander/demand_altitude, /lander/wind, /lander/throttle)")


def parse_service_request(name: str, payload: bytes) -> dict[str, Any]:
    """The request fields of a client's service call (JSON object; missing fields keep the ROS default)."""
    _, fields = SERVICE_FIELDS[name]
    try:
        obj = json.loads(payload) if payload.strip() else {}
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ClientInputError(f"{name}: request is not JSON ({exc})") from None
    if not isinstance(obj, dict):
        raise ClientInputError(f"{name}: request must be a JSON object, got {obj!r}")
    out: dict[str, Any] = {}
    for key, value in obj.items():
        kind = fields.get(key)
        ok = {"integer": isinstance(value, int) and not isinstance(value, bool) and value >= 0,
              "boolean": isinstance(value, bool), "string": isinstance(value, str)}.get(kind or "", False)
        if kind is None:
            raise ClientInputError(f"{name}: unknown field {key!r} (fields: {', '.join(fields) or 'none'})")
        if not ok:
            raise ClientInputError(f"{name}: field {key!r} must be a {'non-negative ' if kind == 'integer' else ''}"
                                   f"{kind}, got {value!r}")
        out[key] = value
    return out
