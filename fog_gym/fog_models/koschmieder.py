"""Koschmieder fog for cameras (:func:`fog_gym.fog.fog_images`; at night plus the glow of :func:`fog_gym.fog.add_glow`).

Needs the camera's ``C_DEPTH`` beside its RGB, its intrinsics and its atmospheric light from the context.

>>> import numpy as np
>>> from fog_gym.fog import parse_fog
>>> from fog_gym.fog_models.base import FogContext
>>> obs = {"C": np.zeros((2, 2, 3), np.uint8), "C_DEPTH": np.full((2, 2), 1000.0, np.float32)}
>>> ctx = FogContext(intrinsics={"C": np.array([[1.0, 0, 1], [0, 1.0, 1], [0, 0, 1]])}, airlight={"C": np.full(3, 200.0)})
>>> int(Koschmieder().apply(obs, "C", [parse_fog("dense")], ctx)["dense"].max())  # the sky takes the airlight
200
"""

from __future__ import annotations

from fog_gym.fog import add_glow, fog_images
from fog_gym.fog_models.base import register_model


@register_model("camera")
class Koschmieder:
    name = "koschmieder"

    def apply(self, obs, channel, levels, context):
        rgb, depth, K = obs[channel], obs[f"{channel}_DEPTH"], context.intrinsics[channel]
        images = fog_images(rgb, depth, K, [lv.alpha for lv in levels], context.airlight[channel], validate=False)
        return {lv.name: add_glow(img, rgb, depth, K, lv.alpha) if context.night else img
                for lv, img in zip(levels, images)}  # fmt: skip
