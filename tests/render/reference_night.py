"""The two-pass reference of the night renderer (a test oracle, not part of the product).

:func:`shade_night` lights, exposes and encodes an albedo render made with ``face_ids=True`` afterwards, pixel by
pixel, with the same light model as :func:`fog_gym.render.lights.render_night`'s one-pass raster; the tests compare
the two.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from fog_gym.render.lights import (EMISSIVE_GAIN, EXPOSURE_STEP, FACE_CELL, FACE_MAX_CELLS, LAMP_COLOR,
                                   LAMP_HEAD_RADIANCE, LAMP_HEAD_RADIUS, LOG_MAX, LOG_MIN, MAX_PRIM_LIGHTS, N_BINS,
                                   NIGHT_AMBIENT, SKY_GAIN, GroundLightMap, Lights, _face_grids,
                                   _light_args, _prim_lights, _shade_pass, gains_from_histograms)  # fmt: skip
from fog_gym.render.shading import KNEE, draw_heads, tone
from fog_gym.world.primitives import Primitives




def shade_night(
    cam_rot: np.ndarray, cam_trans: np.ndarray, cam_k: np.ndarray, far: float, buffers: dict[str, np.ndarray],
    prims: Primitives | Mapping[str, Any], lights: Lights, ground: tuple[GroundLightMap, GroundLightMap], heads: np.ndarray,
    ambient: float = NIGHT_AMBIENT, gains: np.ndarray | None = None,
) -> np.ndarray:
    """Light, expose and encode in place the RGB of an albedo-mode render; returns the exposure gain per camera.

    The reference (two-pass) form of :func:`render_night`; ``gains`` fixes the exposure instead of measuring it.

    ``buffers`` is :func:`fog_gym.render.raster.render`'s output with ``face_ids=True`` (its ``rgb`` holding
    albedo) for the primitives ``prims``; faces are lit per pixel by ``lights``, the ground by the light maps
    ``ground`` = (whole-world lamp map, per-frame window with the beams); ``heads`` (N, 3) are lamp heads to draw.
    The exposure comes from a histogram of every :data:`EXPOSURE_STEP`-th pixel's radiance (each direction).
    Only ``buffers["rgb"]`` changes.
    """
    missing = [k for k in ("rgb", "depth", "face", "face_emissive", "face_prim", "face_side") if k not in buffers]
    if missing:
        raise ValueError(f"buffers lack {missing}: pass the output of render(..., face_ids=True)")
    rgb = buffers["rgb"]
    n_cam, height = rgb.shape[:2]
    rot = np.ascontiguousarray(cam_rot, np.float64)
    trans = np.ascontiguousarray(cam_trans, np.float64)
    ks = np.ascontiguousarray(cam_k, np.float64)
    prims = Primitives.coerce(prims)
    prim_l, prim_n = _prim_lights(prims.centers, prims.halves, lights.pos, lights.radius, MAX_PRIM_LIGHTS)
    g_off, g_dims, g_data = _face_grids(prims.centers, prims.halves, prims.yaws, prims.emissive, prim_l,
                                        prim_n, *_light_args(lights), FACE_CELL, FACE_MAX_CELLS)  # fmt: skip
    smap, wmap = ground

    def run(step, gains, encode, hist):
        _shade_pass(
            rot, trans, ks, float(far), rgb, buffers["depth"], buffers["face"], buffers["face_emissive"],
            buffers["face_prim"], buffers["face_side"], prims.centers, prims.halves,
            np.ascontiguousarray(np.c_[np.cos(prims.yaws), np.sin(prims.yaws)]), g_off, g_dims, g_data,
            np.zeros(1, np.int64), np.zeros((1, 3), np.float32),  # no mesh triangles in this reference
            smap.irradiance, smap.origin[0], smap.origin[1], 1.0 / smap.resolution,
            wmap.irradiance, wmap.origin[0], wmap.origin[1], 1.0 / wmap.resolution,
            float(ambient), float(EMISSIVE_GAIN), float(SKY_GAIN), step, gains, float(KNEE), encode, hist,
            LOG_MIN, LOG_MAX,
        )  # fmt: skip

    if gains is None:
        hist = np.zeros((n_cam, (height + EXPOSURE_STEP - 1) // EXPOSURE_STEP, N_BINS), np.int64)
        run(EXPOSURE_STEP, np.ones(n_cam), False, hist)
        gains = gains_from_histograms(hist.sum(axis=1))
    run(1, gains, True, np.zeros((1, 1, 1), np.int64))
    heads = np.ascontiguousarray(np.reshape(heads, (-1, 3)), np.float64)
    for c in range(n_cam):
        color = np.round(tone(LAMP_COLOR * LAMP_HEAD_RADIANCE * gains[c]) * 255).astype(np.uint8)
        draw_heads(rot[c : c + 1], trans[c : c + 1], ks[c : c + 1], buffers["depth"][c : c + 1], rgb[c : c + 1],
                    heads, float(LAMP_HEAD_RADIUS), color)  # fmt: skip
    return gains
