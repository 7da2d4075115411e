"""LiDAR sensor profiles for fog on real data: how a sensor's file stores intensity, how far it sees, where it sits.

fog-gym's LiDAR fog is Hahner et al.'s model (:func:`fog_gym.fog.fog_lidar`), which takes each point's received
intensity on the model's 0–255 scale: the sensor constant is derived from it under one assumed target reflectivity
Γ (Hahner et al. apply it this way to HDL-64E scans). A profile maps a file's intensity onto that scale —
``model = clip(file / intensity_scale, 0, 1) · 255`` — and back, and places the sensor above the road so that fog
fields (:mod:`fog_gym.fog.fields`: height fog, banks) have their road level.

=================  ==========  ============  =========  ========  ==========================================
profile            intensity   max range     mount      accuracy  sources
=================  ==========  ============  =========  ========  ==========================================
``fogdrive``       [0, 1]      120 m         2.0 m      —         FogDrive Table 2 (CARLA's ``exp(−0.004 d)``)
``kitti``          [0, 1]      120 m         1.73 m     ±2 cm     Geiger et al., IJRR 2013 (KITTI set-up,
                                                                  reflectance in [0, 1]); HDL-64E S2 manual
``nuscenes``       0–255       70 m usable   1.84 m     ±2 cm     Caesar et al., arXiv 1903.11027 (HDL-32E,
                                                                  20 Hz); nuscenes-devkit issues #463, #515
                                                                  (intensity 0–255); LIDAR_TOP's calibrated
                                                                  height in v1.0-mini
=================  ==========  ============  =========  ========  ==========================================

``noise_m`` is the fog-return range noise of Hahner et al.'s v2 noise (10 m in the paper, for every profile).
A user profile is a small JSON or TOML file with the same fields (:func:`load_profile`).

Example:
    >>> p = PROFILES["nuscenes"]
    >>> p.to_model(np.array([0.0, 127.5, 255.0, 300.0])).tolist(), p.from_model(np.array([0.5])).tolist()
    ([0.0, 0.5, 1.0, 1.0], [128.0])
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np


@dataclass(frozen=True)
class LidarProfile:
    """A LiDAR's file conventions and mounting (module docstring). ``integer_intensity``: the file stores whole
    numbers (nuScenes' 0–255), so fogged intensities are rounded back to them."""

    name: str
    intensity_scale: float = 1.0
    max_range_m: float = 120.0
    mount_height_m: float = 2.0
    noise_m: float = 10.0
    accuracy_m: float = 0.02
    channels: int = 64
    integer_intensity: bool = False
    source: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"name must be a non-empty string, got {self.name!r}")
        for f in ("intensity_scale", "max_range_m"):
            v = getattr(self, f)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"{f} must be a positive number, got {v!r}")
        for f in ("mount_height_m", "noise_m", "accuracy_m"):
            v = getattr(self, f)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ValueError(f"{f} must be a number >= 0, got {v!r}")
        if isinstance(self.channels, bool) or not isinstance(self.channels, int) or self.channels < 1:
            raise ValueError(f"channels must be a positive integer, got {self.channels!r}")

    def to_model(self, intensity: np.ndarray) -> np.ndarray:
        """File intensities → the model's [0, 1] (× 255 inside the model)."""
        return np.clip(np.asarray(intensity, np.float64) / self.intensity_scale, 0.0, 1.0).astype(np.float32)

    def from_model(self, intensity: np.ndarray) -> np.ndarray:
        """The model's [0, 1] → file intensities (whole numbers for ``integer_intensity``)."""
        v = np.asarray(intensity, np.float64) * self.intensity_scale
        return np.rint(v) if self.integer_intensity else v

    def sensor_to_field(self) -> np.ndarray:
        """The default placement of the sensor in the field frame: its own axes (x forward, z up), ``mount_height_m``
        above the road."""
        m = np.eye(4)
        m[2, 3] = self.mount_height_m
        return m


PROFILES: dict[str, LidarProfile] = {
    "fogdrive": LidarProfile("fogdrive", 1.0, 120.0, 2.0, 10.0, 0.0, 64, False,
                             "FogDrive Table 2: CARLA's 64-channel LiDAR at (0, 0, 2) m, intensity exp(-0.004 d) in [0, 1]"),
    "kitti": LidarProfile("kitti", 1.0, 120.0, 1.73, 10.0, 0.02, 64, False,
                          "Geiger et al., IJRR 2013: Velodyne HDL-64E at 1.73 m, reflectance in [0, 1]; HDL-64E S2 "
                          "manual: 120 m, < 2 cm accuracy"),
    "nuscenes": LidarProfile("nuscenes", 255.0, 70.0, 1.84, 10.0, 0.02, 32, True,
                             "Caesar et al., arXiv 1903.11027: Velodyne HDL-32E, 20 Hz, 70 m usable; nuscenes-devkit "
                             "issues #463 and #515: intensity 0-255; LIDAR_TOP calibrated at 1.84 m"),
}  # fmt: skip


def load_profile(path: str | Path) -> LidarProfile:
    """A user profile from a JSON or TOML file of :class:`LidarProfile`'s fields (``name`` required); unknown keys
    are refused, naming them."""
    p = Path(path)
    try:
        text = p.read_text()
    except OSError as e:
        raise ValueError(f"cannot read the profile {p}: {e.strerror or e}") from None
    if p.suffix.lower() == ".toml":
        try:
            import tomllib
        except ImportError:  # Python 3.10
            raise ValueError(f"{p}: TOML profiles need Python 3.11 (tomllib); write it as JSON") from None
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as e:
            raise ValueError(f"{p} is not valid TOML: {e}") from None
    else:
        try:
            data = json.loads(text)
        except json.JSONDecodeError as e:
            raise ValueError(f"{p} is not valid JSON: {e}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{p} must hold a table of profile fields")
    known = {f.name for f in fields(LidarProfile)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ValueError(f"{p}: unknown profile fields {unknown} (known: {sorted(known)})")
    return LidarProfile(**data)


def get_profile(profile: str | Path | LidarProfile) -> LidarProfile:
    """A profile by name (:data:`PROFILES`), from a file, or as given."""
    if isinstance(profile, LidarProfile):
        return profile
    if isinstance(profile, str) and profile in PROFILES:
        return PROFILES[profile]
    if isinstance(profile, (str, Path)) and Path(profile).suffix.lower() in (".json", ".toml"):
        return load_profile(profile)
    raise ValueError(f"profile must be one of {tuple(PROFILES)}, a .json / .toml file or a LidarProfile, got {profile!r}")


def profile_info(profile: LidarProfile) -> dict[str, Any]:
    return asdict(profile)
