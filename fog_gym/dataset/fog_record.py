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

Example:
    >>> from fog_gym.fog.fields import FogBank
    >>> bank = FogBank(50.0, start=100.0, length=40.0, edge=0.0, name="dense")
    >>> record = decode_fog_record(encode_fog_record((0.0, 0.0, 0.0), 0.0, {"dense": bank}))
    >>> round(float(record.optical_depth("dense", [0, 0, 1], [[200, 0, 1], [50, 0, 1]])[0]), 4)  # 40 m·ln 20/50
    2.3966
    >>> fog_record_problem(b'{"frame": [0, 0], "time": 0, "fields": {}}')
    'frame must be three finite numbers [x0, y0, heading]'
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from typing import NamedTuple

import numpy as np

from fog_gym.checks import json_numbers
from fog_gym.fog.fields import field_from_info, field_json
from fog_gym.fog.physics import FogField

KEYS = ("frame", "time", "fields")


class FogRecord(NamedTuple):
    """One sample's fog fields (module docstring): the field frame in the world, the field time, and each level's
    field by level name."""

    frame: np.ndarray  # (3,) x0, y0, heading
    time: float
    fields: dict[str, FogField]

    def optical_depth(self, level: str, start: Sequence[float], ends: np.ndarray) -> np.ndarray:
        """``τ`` of level ``level``'s field along the straight segments from the world point ``start`` (3,) to each
        world point of ``ends`` (N, 3), in closed form; ``exp(−τ)`` is their one-way transmittance."""
        if level not in self.fields:
            raise KeyError(f"no fog level {level!r} in this record; it has {sorted(self.fields)}")
        start = np.asarray(start, np.float64).reshape(3)
        ends = np.asarray(ends, np.float64).reshape(-1, 3)
        ray = ends - start
        length = np.linalg.norm(ray, axis=1)
        unit = ray / np.maximum(length, 1e-9)[:, None]
        x0, y0, heading = (float(v) for v in self.frame)
        h = np.array([math.cos(heading), math.sin(heading)])
        u0 = (start[0] - x0) * h[0] + (start[1] - y0) * h[1]
        return self.fields[level].optical_depth(u0, start[2], unit[:, :2] @ h, unit[:, 2], length, self.time)


def encode_fog_record(frame: Sequence[float], time: float, fields: Mapping[str, FogField]) -> bytes:
    """The file's bytes; ``ValueError`` naming the argument for a bad frame, time or field."""
    f = np.asarray(frame, np.float64)
    if f.shape != (3,) or not np.isfinite(f).all():
        raise ValueError(f"frame must be three finite numbers [x0, y0, heading], got {frame!r}")
    if isinstance(time, bool) or not isinstance(time, (int, float, np.number)) or not math.isfinite(float(time)):
        raise ValueError(f"time must be a finite number of seconds, got {time!r}")
    if not fields or not all(isinstance(k, str) and isinstance(v, FogField) for k, v in fields.items()):
        raise ValueError(f"fields must map level names to fog fields, got {fields!r}")
    record = {"frame": f.tolist(), "time": float(time),
              "fields": {k: json.loads(field_json(v)) for k, v in fields.items()}}  # fmt: skip
    return json.dumps(record, sort_keys=True).encode()


def fog_record_problem(data: bytes, levels: Sequence[str] | None = None) -> str | None:
    """The problem with a fog-field file's bytes (one phrase), or None; ``levels``: the level names it must hold.
    Never raises."""
    try:
        record = json.loads(data)
    except (ValueError, RecursionError) as e:  # not UTF-8, not JSON, nested too deeply, an over-long number
        return f"corrupt JSON ({type(e).__name__})" if data else "empty file"
    if not isinstance(record, dict):
        return "expected a JSON object"
    missing = [k for k in KEYS if k not in record]
    if missing:
        return f"missing keys {missing}"
    try:
        frame, time = json_numbers("frame", record["frame"]), json_numbers("time", record["time"])
    except ValueError:
        return "frame and time must be numbers"
    if frame.shape != (3,) or not np.isfinite(frame).all():
        return "frame must be three finite numbers [x0, y0, heading]"
    if time.shape != () or not np.isfinite(time):
        return "time must be a finite number of seconds"
    fields = record["fields"]
    if not isinstance(fields, dict) or not fields:
        return "fields must map level names to fog fields"
    if levels is not None and sorted(fields) != sorted(levels):
        return f"fields must name the levels {sorted(levels)}, got {sorted(fields)}"
    for name, info in fields.items():
        if not isinstance(info, dict):
            return f"field {name!r} must be a JSON object"
        try:
            field_from_info(info)
        except (ValueError, TypeError, KeyError, RecursionError) as e:
            return f"field {name!r}: {e}"
    return None


def decode_fog_record(data: bytes) -> FogRecord:
    """A fog-field file's bytes → :class:`FogRecord`; ``ValueError`` with the problem if they are not one."""
    problem = fog_record_problem(data)
    if problem is not None:
        raise ValueError(problem)
    r = json.loads(data)
    return FogRecord(np.asarray(r["frame"], np.float64), float(r["time"]),
                     {k: field_from_info(v) for k, v in r["fields"].items()})  # fmt: skip
