"""Fog fields: extinction that varies in space and time, under one physics for every sensor.

Along any ray the transmittance is ``t = exp(−τ)`` with ``τ = ∫ β(s) ds`` the optical depth, so Koschmieder's
``I = J·t + A·(1 − t)`` (cameras) and Hahner et al.'s LiDAR equation hold with the local extinction β instead of a
constant α (``docs/fog.md``, "Fog with a shape"). A field lives in the **field frame** fixed at reset: ``u`` the
distance along the ego's heading from the LiDAR origin, ``z`` the height above the road. The fields:

* :class:`~fog_gym.fog.physics.FogLevel` — homogeneous fog, today's ``fog="dense"`` or ``fog=50.0``
  (:func:`Homogeneous` builds one): ``β = ln 20 / V``.
* :class:`HeightFog` — ground (radiation) fog: ``β(z) = (ln 20 / V)·exp(−z / H)`` for ``z ≥ 0``, ``β(z < 0) = β(0)``.
* :class:`FogBank` — a slab across the road (advection fog): ``β(u) = β_bg + (β_in − β_bg)·w(u)`` with ``w`` full
  inside ``[start, start + length]`` and linear ramps ``edge`` metres wide centred on the two faces; ``velocity``
  lets it drift along ``u``.
* Fields add (``HeightFog(…) + FogBank(…)`` is a :class:`FogSum`): extinction coefficients sum.

``τ`` has a closed form for each field along a straight segment (exponential in height, piecewise linear in ``u``);
the kernels take a field as a packed table (:meth:`FogField.pack`) and :func:`fog_gym.fog.depth.segment_depth`
evaluates it.

Example:
    >>> bank = FogBank(50.0, start=100.0, length=40.0, edge=0.0)
    >>> [round(float(bank.beta(u, 1.0)), 4) for u in (99.0, 120.0, 141.0)]
    [0.0, 0.0599, 0.0]
    >>> round(float(bank.optical_depth(0.0, 1.0, 1.0, 0.0, 200.0)), 4)  # 40 m of dense fog: τ = 40·ln 20 / 50
    2.3966
    >>> (HeightFog(50.0, 10.0) + bank).name
    'height_50m_10m+bank_50m'
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np
from fog_gym.fog.depth import (BANK, HEIGHT, HOMOGENEOUS, extinctions, optical_depths, point_extinction,  # noqa: F401
                               segment_depth)  # fmt: skip  (re-exported)
from fog_gym.fog.physics import LN20, FogField, FogLevel, FogSum, parse_fog  # noqa: F401  (FogSum: re-exported)



def Homogeneous(visibility: float, name: str | None = None) -> FogLevel:  # noqa: N802  (a field's constructor)
    """Homogeneous fog of meteorological visibility ``visibility`` metres: today's fog, a
    :class:`~fog_gym.fog.physics.FogLevel` (``fog="dense"`` and ``fog=50.0`` mean ``Homogeneous(50.0)``).

    >>> Homogeneous(50.0) == parse_fog("dense"), Homogeneous(75.0, name="haze").channel_suffix
    (True, 'FOG_HAZE')
    """
    level = parse_fog(_visibility(visibility, "visibility", allow_inf=True))
    if name is None:
        return level
    return FogLevel(_name(name), level.visibility_m, level.alpha)


def _visibility(value: Any, what: str, allow_inf: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{what} must be a number of metres > 0, got {value!r}")
    v = float(value)
    if math.isnan(v) or v <= 0.0 or (math.isinf(v) and not allow_inf):
        raise ValueError(f"{what} must be a number of metres > 0{' (or inf)' if allow_inf else ''}, got {value!r}")
    return v


def _finite(value: Any, what: str, low: float | None = None, strict: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{what} must be a finite number, got {value!r}")
    v = float(value)
    if not math.isfinite(v) or (low is not None and (v <= low if strict else v < low)):
        bound = "" if low is None else f" {'>' if strict else '>='} {low:g}"
        raise ValueError(f"{what} must be a finite number{bound}, got {value!r}")
    return v


def _name(name: Any) -> str:
    if not isinstance(name, str) or not name.strip() or any(c in name for c in "/\\ \t\n"):
        raise ValueError(f"name must be a non-empty string without spaces or slashes, got {name!r}")
    return name.strip().lower()


def _beta(visibility: float) -> float:
    return 0.0 if math.isinf(visibility) else LN20 / visibility


@dataclass(frozen=True)
class HeightFog(FogField):
    """Ground fog: ``β(z) = (ln 20 / visibility)·exp(−z / scale_height)`` above the road (``z ≥ 0``), ``β(0)`` below;
    ``visibility`` is the meteorological visibility at road level [m], ``scale_height`` [m] the height over which the
    fog thins by ``e``.

    >>> HeightFog(50.0, 10.0).beta(0.0, [0.0, 10.0, -1.0]).round(5).tolist()
    [0.05991, 0.02204, 0.05991]
    """

    visibility: float
    scale_height: float
    name: str = ""
    kind: ClassVar[str] = "HeightFog"

    def __post_init__(self) -> None:
        object.__setattr__(self, "visibility", _visibility(self.visibility, "visibility", allow_inf=True))
        object.__setattr__(self, "scale_height", _finite(self.scale_height, "scale_height", 0.0, strict=True))
        default = f"height_{self.visibility:g}m_{self.scale_height:g}m"
        object.__setattr__(self, "name", _name(self.name) if self.name else default)

    @property
    def alpha(self) -> float:
        """The peak extinction (at road level) [1/m]."""
        return _beta(self.visibility)

    @property
    def visibility_m(self) -> float:
        return self.visibility

    def pack(self, time: float = 0.0) -> np.ndarray:
        return np.array([[HEIGHT, self.alpha, self.scale_height, 0, 0, 0, 0, 0]], np.float64)


@dataclass(frozen=True)
class FogBank(FogField):
    """A fog bank across the road: with ``u`` the distance along the ego's heading at reset from the LiDAR origin at
    reset, ``β(u) = β_bg + (β_in − β_bg)·w(u)``, ``β_in = ln 20 / visibility``, ``β_bg = ln 20 / background`` (0 for
    inf) and ``w(u) = clip(min(u − start + edge/2, start + length + edge/2 − u) / edge, 0, 1)``: full strength inside,
    linear ramps ``edge`` metres wide centred on the faces at ``start`` and ``start + length`` (a step when
    ``edge = 0``). The bank drifts at ``velocity`` m/s along ``u`` (its faces at time t lie ``velocity·t`` further).

    >>> b = FogBank(50.0, start=100.0, length=50.0, edge=20.0)
    >>> b.beta([89.0, 95.0, 100.0, 125.0, 155.0], 0.0).round(4).tolist()
    [0.0, 0.015, 0.03, 0.0599, 0.015]
    """

    visibility: float
    start: float
    length: float
    edge: float = 20.0
    background: float = math.inf
    velocity: float = 0.0
    name: str = ""
    kind: ClassVar[str] = "FogBank"

    def __post_init__(self) -> None:
        object.__setattr__(self, "visibility", _visibility(self.visibility, "visibility", allow_inf=True))
        object.__setattr__(self, "start", _finite(self.start, "start"))
        object.__setattr__(self, "length", _finite(self.length, "length", 0.0))
        object.__setattr__(self, "edge", _finite(self.edge, "edge", 0.0))
        object.__setattr__(self, "background", _visibility(self.background, "background", allow_inf=True))
        object.__setattr__(self, "velocity", _finite(self.velocity, "velocity"))
        object.__setattr__(self, "name", _name(self.name) if self.name else f"bank_{self.visibility:g}m")

    @property
    def alpha(self) -> float:
        """The peak extinction (inside the bank, or the background's if that is denser) [1/m]."""
        return max(_beta(self.visibility), _beta(self.background))

    @property
    def visibility_m(self) -> float:
        return min(self.visibility, self.background)

    def knots(self, time: float = 0.0) -> tuple[float, float, float, float, float]:
        """``(a, b, c, d, p)``: ``w`` rises linearly from 0 at ``a`` to ``p`` at ``b``, stays until ``c`` and falls to 0
        at ``d`` (``p < 1`` when the bank is shorter than its edge: the ramps meet)."""
        s = self.start + self.velocity * time
        e, end = self.edge, s + self.length
        if e == 0.0:
            return s, s, end, end, 1.0
        p = min(1.0, (self.length + e) / (2.0 * e))
        a, d = s - e / 2.0, end + e / 2.0
        return a, a + p * e, d - p * e, d, p

    def pack(self, time: float = 0.0) -> np.ndarray:
        a, b, c, d, p = self.knots(time)
        b_in, b_bg = _beta(self.visibility), _beta(self.background)
        return np.array([[BANK, b_in - b_bg, a, b, c, d, p, b_bg]], np.float64)


def field_info(field: FogField) -> dict[str, Any]:
    """A field's parameters as a JSON-ready dict (:func:`field_from_info` reads it back); a homogeneous level gives
    FogDrive's ``{"visibility_m", "alpha"}`` plus its type and name."""
    if isinstance(field, FogLevel):
        return {"type": "Homogeneous", "name": field.name, "visibility_m": field.visibility_m, "alpha": field.alpha}
    return field.info()


def field_from_info(info: Mapping[str, Any]) -> FogField:
    """The field that :func:`field_info` (or ``field.info()``) described.

    >>> f = HeightFog(80.0, 5.0) + FogBank(30.0, 120.0, 60.0, name="wall")
    >>> field_from_info(json.loads(json.dumps(field_info(f)))) == f == field_from_info(json.loads(field_json(f)))
    True
    """
    info = {k: (math.inf if v == "inf" else v) for k, v in info.items()}  # (field_json writes inf as "inf")
    kind = info.get("type")
    if kind == "Homogeneous" or (kind is None and "visibility_m" in info):
        level = parse_fog(float(info["visibility_m"]))
        name = info.get("name")
        return level if name in (None, level.name) else FogLevel(name, level.visibility_m, level.alpha)
    if kind == "FogSum":
        return FogSum(tuple(field_from_info(t) for t in info["terms"]), name=info.get("name", ""))
    cls = {"HeightFog": HeightFog, "FogBank": FogBank}.get(kind)
    if cls is None:
        raise ValueError(f"unknown fog field type {kind!r}; expected Homogeneous, HeightFog, FogBank or FogSum")
    return cls(**{f.name: info[f.name] for f in fields(cls) if f.name in info})


def world_optical_depth(field: FogField, frame, time: float, start, ends) -> np.ndarray:
    """``τ`` of ``field`` along the straight world segments from ``start`` (3,) to each point of ``ends`` (N, 3), the
    field laid in the world at ``frame = (x0, y0, heading)`` (``u`` along ``heading`` from ``(x0, y0)``, ``z`` the
    height) and seen ``time`` seconds after it was laid; ``exp(−τ)`` is each segment's one-way transmittance. A
    dataset's fog record (:mod:`fog_gym.dataset.fog_record`) gives the frame, the time and the field.

    >>> bank = FogBank(50.0, 30.0, 20.0, edge=0.0)
    >>> world_optical_depth(bank, (10.0, 5.0, math.pi / 2), 0.0, (10.0, 5.0, 1.0), [[10.0, 105.0, 1.0]]).round(4)  # 20 m
    array([1.1983])
    """
    start = np.asarray(start, np.float64).reshape(3)
    ends = np.asarray(ends, np.float64).reshape(-1, 3)
    ray = ends - start
    length = np.linalg.norm(ray, axis=1)
    unit = ray / np.maximum(length, 1e-9)[:, None]
    heading = float(frame[2])
    h = np.array([math.cos(heading), math.sin(heading)])
    return field.optical_depth(along_axis(frame, start[0], start[1]), start[2], unit[:, :2] @ h, unit[:, 2], length,
                               time)  # fmt: skip


def along_axis(frame, x: float, y: float) -> float:
    """The distance ``u`` of the world point ``(x, y)`` along the axis of a field laid at ``frame = (x0, y0,
    heading)``.

    >>> along_axis((10.0, 5.0, math.pi / 2), 10.0, 105.0)
    100.0
    """
    x0, y0, heading = (float(v) for v in frame)
    return (float(x) - x0) * math.cos(heading) + (float(y) - y0) * math.sin(heading)


def field_json(field: FogField) -> str:
    """:func:`field_info` as compact JSON (inf as the string "inf")."""
    return json.dumps(_json_safe(field_info(field)), sort_keys=True, separators=(",", ":"))


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and math.isinf(value):
        return "inf"
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_json_safe(v) for v in value]
    return value
