"""Fog as one number: visibility ``V`` (meteorological optical range, 5 % contrast) ↔ extinction ``α = ln 20 / V``.

Presets (FogDrive): light 160 m, moderate 100 m, dense 50 m; "clear" is ``V = ∞``, ``α = 0``. The same α drives
the camera (:mod:`fog_gym.fog.camera`) and the LiDAR (:mod:`fog_gym.fog.lidar`). Research note ``fog_physics.md`` §0.

Example:
    >>> level = parse_fog("dense")
    >>> level.visibility_m, round(level.alpha, 6)
    (50.0, 0.059915)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from fog_gym.fog.depth import extinctions, optical_depths

LN20 = math.log(20.0)
#: FogDrive's fog levels: visibility in metres.
FOG_PRESETS: dict[str, float] = {"light": 160.0, "moderate": 100.0, "dense": 50.0}


class FogField:
    """Fog as a field of extinction ``β(u, z, t)`` in the field frame (``u`` along the ego's heading at reset from the
    LiDAR origin at reset, ``z`` the height above the road): :class:`FogLevel` (homogeneous) and the fields of
    :mod:`fog_gym.fog.fields`. Every field has a ``name`` (its channel suffix), ``alpha`` (its peak extinction, where
    one number is needed) and ``visibility_m``; fields add (extinctions sum)."""

    kind = "FogField"

    @property
    def is_clear(self) -> bool:
        return self.alpha == 0.0

    @property
    def is_homogeneous(self) -> bool:
        """Whether β is the same everywhere (the camera and LiDAR then use the constant-α kernels)."""
        return False

    @property
    def channel_suffix(self) -> str:
        """``FOG_LIGHT`` etc. as in FogDrive's channel names; ``FOG_<NAME>`` for other fields."""
        return "FOG_" + self.name.upper().replace(".", "P")

    def pack(self, time: float = 0.0) -> np.ndarray:
        """The field at ``time`` [s] as rows ``[kind, p0 … p6]`` for the kernels (:mod:`fog_gym.fog.fields`)."""
        raise NotImplementedError  # pragma: no cover

    def beta(self, u, z, time: float = 0.0) -> np.ndarray:
        """Extinction [1/m] at field-frame points ``(u, z)`` (arrays broadcast together) at ``time``."""
        return extinctions(self.pack(time), u, z)

    def optical_depth(self, u0, z0, du, dz, length, time: float = 0.0) -> np.ndarray:
        """Optical depth ``τ = ∫ β ds`` along segments from ``(u0, z0)`` with unit-direction components ``du``
        (along u) and ``dz`` (up), ``length`` metres long, in closed form; ``exp(−τ)`` is their transmittance."""
        return optical_depths(self.pack(time), u0, z0, du, dz, length)

    def __add__(self, other: FogField) -> FogField:
        if not isinstance(other, FogField):
            return NotImplemented
        return FogSum((self, other))

    def info(self) -> dict:
        """The field's parameters, JSON-ready (``fog_gym.fog.fields.field_from_info`` reads them back)."""
        from dataclasses import fields

        params = {f.name: getattr(self, f.name) for f in fields(self)}  # type: ignore[arg-type]
        return {"type": self.kind, **params, "visibility_m": self.visibility_m, "alpha": self.alpha}


@dataclass(frozen=True)
class FogLevel(FogField):
    """One fog condition: a name ("clear", "light", …, or e.g. "75m"), visibility [m] and extinction α [1/m].

    >>> FogLevel.from_visibility(100.0).name, FogLevel.from_visibility(75.0).channel_suffix
    ('moderate', 'FOG_75M')
    """

    name: str
    visibility_m: float
    alpha: float

    @classmethod
    def from_visibility(cls, visibility_m: float) -> FogLevel:
        v = float(visibility_m)
        if math.isinf(v):
            return cls("clear", math.inf, 0.0)
        name = next((k for k, pv in FOG_PRESETS.items() if pv == v), f"{v:g}m")
        return cls(name, v, LN20 / v)

    kind = "Homogeneous"

    @property
    def is_homogeneous(self) -> bool:
        return True

    def pack(self, time: float = 0.0) -> np.ndarray:
        return np.array([[0.0, self.alpha, 0, 0, 0, 0, 0, 0]], np.float64)

    def info(self) -> dict[str, float]:
        """FogDrive's record of a level: ``{"visibility_m", "alpha"}``."""
        return {"visibility_m": self.visibility_m, "alpha": self.alpha}


@dataclass(frozen=True)
class FogSum(FogField):
    """Fields whose extinction coefficients add (``field_a + field_b``)."""

    terms: tuple[FogField, ...]
    name: str = ""
    kind: ClassVar[str] = "FogSum"

    def __post_init__(self) -> None:
        flat: list[FogField] = []
        for term in self.terms:
            if not isinstance(term, FogField):
                raise ValueError(f"a fog sum adds fog fields, got {term!r}")
            flat.extend(term.terms if isinstance(term, FogSum) else [term])
        if not flat:
            raise ValueError("a fog sum needs at least one field")
        object.__setattr__(self, "terms", tuple(flat))
        object.__setattr__(self, "name", self.name.strip().lower() if self.name else "+".join(t.name for t in flat))

    @property
    def alpha(self) -> float:
        return sum(t.alpha for t in self.terms)

    @property
    def visibility_m(self) -> float:
        return LN20 / self.alpha if self.alpha > 0 else math.inf

    @property
    def is_homogeneous(self) -> bool:
        return all(t.is_homogeneous for t in self.terms)

    def pack(self, time: float = 0.0) -> np.ndarray:
        return np.concatenate([t.pack(time) for t in self.terms])

    def info(self) -> dict[str, Any]:
        return {"type": self.kind, "name": self.name, "terms": [t.info() for t in self.terms],
                "visibility_m": self.visibility_m, "alpha": self.alpha}  # fmt: skip


def alpha_from_visibility(visibility_m: float) -> float:
    """α = ln 20 / V (5 % contrast threshold); 0 for V = ∞.

    >>> [round(alpha_from_visibility(v), 6) for v in (50, 100, 160)]
    [0.059915, 0.029957, 0.018723]
    """
    return parse_fog(visibility_m).alpha


def parse_fog(fog: str | float | int | FogField) -> FogLevel | FogField:
    """A level name ("clear", "light", "moderate", "dense") or a visibility in metres (> 0, may be inf) as a
    :class:`FogLevel`; a fog field (:mod:`fog_gym.fog.fields`) as itself."""
    if isinstance(fog, FogField):
        return fog
    if isinstance(fog, str):
        key = fog.strip().lower()
        if key == "clear":
            return FogLevel("clear", math.inf, 0.0)
        if key in FOG_PRESETS:
            return FogLevel(key, FOG_PRESETS[key], LN20 / FOG_PRESETS[key])
        raise ValueError(
            f"fog must be one of ('clear', 'light', 'moderate', 'dense') or a visibility in metres > 0, got {fog!r}"
        )
    if isinstance(fog, bool) or not isinstance(fog, (int, float, np.integer, np.floating)):
        raise ValueError(f"fog must be a level name or a visibility in metres > 0, got {fog!r}")
    v = float(fog)
    if math.isnan(v) or v <= 0.0:
        raise ValueError(f"fog visibility must be a number of metres > 0 (or inf for clear), got {fog!r}")
    return FogLevel.from_visibility(v)


def parse_level(fog: str | float | int | FogField, where: str = "this env") -> FogLevel:
    """:func:`parse_fog` for the users of one extinction (the native vector env, perceived objects): a fog field
    that is not homogeneous is refused with a clear error."""
    level = parse_fog(fog)
    if not level.is_homogeneous or not isinstance(level, FogLevel):
        raise ValueError(f"{where} takes homogeneous fog (a level name or a visibility in metres); fog fields such as "
                         f"{type(level).__name__} work with FogDrive-v0 and FogWrapper")
    return level
