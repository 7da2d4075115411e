"""The dehazers of pipeline C: Dark Channel Prior (:func:`fog_gym.dehaze.dcp`), AOD-Net and DehazeFormer-T trained
from scratch on the train split's (clean, fog) pairs (the paper fine-tunes AOD-Net from community weights and uses
DehazeFormer-S with the authors' RESIDE weights; no weights can be downloaded here) and, beyond the paper, the
Koschmieder oracle (:func:`fog_gym.dehaze.oracle`, the exact inverse from depth, α and airlight: the upper bound
of any dehazer). Every dehazer works on the frame at its recorded resolution.

The oracle needs the airlight the fog was made with: by day fog-gym estimates it from the first clean frame of
the episode (:func:`fog_gym.fog.atmospheric_light`), at night from that frame and its depth
(:func:`fog_gym.fog.night_airlight`), and sample 0 of a scene is that frame, so the oracle recomputes it exactly;
the night glow around lamps (:func:`fog_gym.fog.add_glow`) is not inverted.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from fog_gym.dataset.access import FogDrive
from fog_gym.dataset.decode import load_channel
from fog_gym.experiments.defog.data import Frame, intrinsic, load_image

DEHAZERS = ("DCP", "AOD-Net", "DehazeFormer", "oracle")


class OracleDehazer:
    """The exact inverse of fog-gym's camera fog for frames of a dataset (module docstring)."""

    def __init__(self, ds: FogDrive) -> None:
        self.ds = ds
        self._airlight: dict[tuple[str, str], np.ndarray] = {}

    def airlight(self, f: Frame) -> np.ndarray:
        from fog_gym.fog import atmospheric_light, night_airlight

        key = (f.first, f.camera)
        if key not in self._airlight:
            first = Frame(f.scene, f.first, f.first, f.camera)
            rgb = load_image(self.ds, first, "clean")
            if "_night_" in f.scene:
                depth_ch = f"{f.camera}_DEPTH"
                depth = load_channel(depth_ch, self.ds.get_sample_paths(f.first, [depth_ch])[depth_ch])
                self._airlight[key] = night_airlight(rgb, depth)
            else:
                self._airlight[key] = atmospheric_light(rgb)
        return self._airlight[key]

    def __call__(self, fogged: np.ndarray, f: Frame, level: str) -> np.ndarray:
        from fog_gym.dehaze import oracle
        from fog_gym.fog import parse_fog

        depth_ch = f"{f.camera}_DEPTH"
        depth = load_channel(depth_ch, self.ds.get_sample_paths(f.sample, [depth_ch])[depth_ch])
        h, w = depth.shape
        return oracle(fogged, depth, intrinsic(w, h), parse_fog(level).alpha, self.airlight(f))


def dehazers(ds: FogDrive, aod: Any, dehazeformer: Any = None,
             precision: str = "fp32") -> dict[str, Callable[[np.ndarray, Frame, str], np.ndarray]]:  # fmt: skip
    """Each dehazer as ``f(fogged image, frame, level) -> image``, with the trained AOD-Net ``aod`` and
    DehazeFormer ``dehazeformer`` (left out when None; ``precision`` "bf16" runs it under bfloat16 autocast)."""
    from fog_gym.dehaze import dcp
    from fog_gym.dehaze.aodnet import dehaze as aod_dehaze

    out = {"DCP": lambda img, f, lv: dcp(img), "AOD-Net": lambda img, f, lv: aod_dehaze(aod, img)}
    if dehazeformer is not None:
        from fog_gym.dehaze.dehazeformer import dehaze as df_dehaze

        out["DehazeFormer"] = lambda img, f, lv: df_dehaze(dehazeformer, img, precision)
    out["oracle"] = OracleDehazer(ds)
    return out
