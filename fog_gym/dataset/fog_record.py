"""The fog field of each sample: an extra file beside the FogDrive channels (``fog_field/000000.json``).

FogDrive's fog is homogeneous, one visibility per level (the manifest's ``fog_levels``). A set generated with fog
fields (``fog-gym generate --fog-fields banks|height|mixed``, or ``RecordFogDrive`` over a paired fog wrapper of
fields named light, moderate, dense) writes, beside each sample, the field each fog level was rendered with — enough
to compute the optical depth ``τ`` (and the transmittance ``exp(−τ)``) along any segment of the world. It is not a
channel: the index does not list it, so a reader that only knows FogDrive never sees it. Homogeneous sets have no
such files (their levels are the manifest's).

The record, in CARLA's world frame (the ego poses' frame, :mod:`fog_gym.dataset.poses`)::

    {"frame": [x0, y0, heading],   # the field frame: u runs along `heading` [rad] from (x0, y0); z is the height
     "time": t,                    # seconds since the field was laid (a drifting bank has moved velocity·t)
     "fields": {"light": {...},    # each level's field: fog_gym.fog.fields.field_info (JSON; inf as "inf")
                "moderate": {...}, "dense": {...}}}

The dataset layer keeps the fields as JSON (it imports no physics); ``fog_gym.fog.fields.field_from_info`` turns one
into a field, and ``fog_gym.fog.fields.world_optical_depth`` gives its optical depth along world segments.

Example:
    >>> bank = {"type": "FogBank", "name": "dense", "visibility": 50.0, "start": 100.0, "length": 40.0, "edge": 0.0,
    ...         "background": "inf", "velocity": 0.0}
    >>> record = decode_fog_record(encode_fog_record((0.0, 0.0, 0.0), 0.0, {"dense": bank}))
    >>> record.fields["dense"]["start"], fog_record_problem(b'{"frame": [0, 0], "time": 0, "fields": {}}')
    (100.0, 'frame must be three finite numbers [x0, y0, heading]')
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np

from fog_gym.checks import json_numbers, json_record

KEYS = ("frame", "time", "fields")
#: The field types a record may hold (``fog_gym.fog.fields``), and the parameters each must give.
FIELD_TYPES = {"Homogeneous": ("visibility_m",), "HeightFog": ("visibility", "scale_height"),
               "FogBank": ("visibility", "start", "length"), "FogSum": ("terms",)}  # fmt: skip


class FogRecord(NamedTuple):
    """One sample's fog fields (module docstring): the field frame in the world, the field time, and each level's
    field (``field_info`` JSON) by level name."""

    frame: np.ndarray  # (3,) x0, y0, heading
    time: float
    fields: dict[str, dict[str, Any]]


def encode_fog_record(frame: Sequence[float], time: float, fields: Mapping[str, Mapping[str, Any]]) -> bytes:
    """The file's bytes (``fields``: each level's ``field_info``); ``ValueError`` naming the argument for a bad
    frame, time or field."""
    f = np.asarray(frame, np.float64)
    if f.shape != (3,) or not np.isfinite(f).all():
        raise ValueError(f"frame must be three finite numbers [x0, y0, heading], got {frame!r}")
    if isinstance(time, bool) or not isinstance(time, (int, float, np.number)) or not math.isfinite(float(time)):
        raise ValueError(f"time must be a finite number of seconds, got {time!r}")
    record = {"frame": f.tolist(), "time": float(time), "fields": _json_safe(dict(fields))}
    problem = _fields_problem(record["fields"], None)
    if problem:
        raise ValueError(f"fields: {problem}")
    return json.dumps(record, sort_keys=True).encode()


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and math.isinf(value):
        return "inf"
    if isinstance(value, Mapping):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    return value


def fog_record_problem(data: bytes, levels: Sequence[str] | None = None) -> str | None:
    """The problem with a fog-field file's bytes (one phrase), or None; ``levels``: the level names it must hold.
    Never raises."""
    record, problem = json_record(data, KEYS)
    if record is None:
        return problem
    try:
        frame, time = json_numbers("frame", record["frame"]), json_numbers("time", record["time"])
    except ValueError:
        return "frame and time must be numbers"
    if frame.shape != (3,) or not np.isfinite(frame).all():
        return "frame must be three finite numbers [x0, y0, heading]"
    if time.shape != () or not np.isfinite(time):
        return "time must be a finite number of seconds"
    return _fields_problem(record["fields"], levels)


def _fields_problem(fields: Any, levels: Sequence[str] | None) -> str | None:
    if not isinstance(fields, dict) or not fields:
        return "fields must map level names to fog fields"
    if levels is not None and sorted(fields) != sorted(levels):
        return f"fields must name the levels {sorted(levels)}, got {sorted(fields)}"
    for name, info in fields.items():
        problem = _field_problem(info)
        if problem:
            return f"field {name!r}: {problem}"
    return None


def _field_problem(info: Any, depth: int = 0) -> str | None:
    if not isinstance(info, dict):
        return "must be a JSON object"
    kind = info.get("type")
    if kind not in FIELD_TYPES or (kind == "FogSum" and depth):
        return f"type must be one of {sorted(FIELD_TYPES)} (a sum of the others), got {kind!r}"
    missing = [k for k in FIELD_TYPES[kind] if k not in info]
    if missing:
        return f"{kind} lacks {missing}"
    if kind == "FogSum":
        terms = info["terms"]
        if not isinstance(terms, list) or not terms:
            return "FogSum terms must be a non-empty list of fields"
        return next((p for p in (_field_problem(t, depth + 1) for t in terms) if p), None)
    for key, value in info.items():
        if key in ("type", "name"):
            continue
        number = math.inf if value == "inf" else value
        if isinstance(number, bool) or not isinstance(number, (int, float)) or math.isnan(number):
            return f"{key} must be a number, got {value!r}"
    return None


def decode_fog_record(data: bytes) -> FogRecord:
    """A fog-field file's bytes → :class:`FogRecord`; ``ValueError`` with the problem if they are not one."""
    problem = fog_record_problem(data)
    if problem is not None:
        raise ValueError(problem)
    r = json.loads(data)
    return FogRecord(np.asarray(r["frame"], np.float64), float(r["time"]), r["fields"])
