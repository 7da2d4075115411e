"""Motion blur over a camera's exposure: a velocity-buffer blur (numba kernels, pure functions over arrays).

A sensor integrates the light of its exposure time ``T``; what moves across the image meanwhile is smeared along
its path. :func:`image_flow` gives each pixel the image motion of the surface it sees over the exposure: the
point ``X`` (from planar depth and the intrinsics, in the camera's optical frame) moves relative to the camera at
``d = Rᵀ(v_point − v_camera)`` (world velocities: the vehicle's own velocity for its pixels, found by the instance
buffer; zero for the static world and the sky; the ego's velocity for the camera), so over the exposure, centred
on the frame's instant, its image runs from ``π(X − d·T/2)`` to ``π(X + d·T/2)``. :func:`blur_motion` averages the
frame along that segment (bilinear samples, one per pixel of path, at most :data:`MAX_SAMPLES`), the post-process
motion blur of game engines (CARLA's cameras have one). The ego's rotation over the exposure is neglected (its yaw
rate on highway-env's roads is a few degrees per second: under a pixel of rotation in the default 2 ms day
exposure).

Example:
    >>> K = np.array([[100.0, 0, 50], [0, 100.0, 50], [0, 0, 1]])
    >>> depth = np.full((100, 100), 10.0, np.float32)
    >>> flow = image_flow(depth, np.zeros((100, 100), np.uint16), K, np.eye(4), np.zeros((1, 3)), np.array([10.0, 0, 0]), 0.01)
    >>> round(float(flow[50, 50, 0]), 2), round(float(flow[50, 50, 1]), 2)  # 10 cm at 10 m: 1 px to the left
    (-1.0, 0.0)
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym._numba import pick, serial_twin

#: At most this many samples along a pixel's path (longer paths are sampled more sparsely).
MAX_SAMPLES = 32


@njit(cache=True, nogil=True, parallel=True)
def _flow_kernel(depth, instance, kinv, rot_t, vel_cam, exposure, out):
    height, width = depth.shape
    fx, fy = 1.0 / kinv[0, 0], 1.0 / kinv[1, 1]
    cx, cy = -kinv[0, 2] * fx, -kinv[1, 2] * fy
    for i in prange(height):
        for j in range(width):
            z = depth[i, j]
            x = (j + 0.5 - cx) / fx * z
            y = (i + 0.5 - cy) / fy * z
            v = vel_cam[instance[i, j]]  # the point's velocity relative to the camera, world frame
            dx = (rot_t[0, 0] * v[0] + rot_t[0, 1] * v[1] + rot_t[0, 2] * v[2]) * exposure
            dy = (rot_t[1, 0] * v[0] + rot_t[1, 1] * v[1] + rot_t[1, 2] * v[2]) * exposure
            dz = (rot_t[2, 0] * v[0] + rot_t[2, 1] * v[1] + rot_t[2, 2] * v[2]) * exposure
            z0, z1 = z - 0.5 * dz, z + 0.5 * dz
            if z0 <= 0.05 or z1 <= 0.05:
                out[i, j, 0] = 0.0
                out[i, j, 1] = 0.0
                continue
            u0 = fx * (x - 0.5 * dx) / z0
            u1 = fx * (x + 0.5 * dx) / z1
            w0 = fy * (y - 0.5 * dy) / z0
            w1 = fy * (y + 0.5 * dy) / z1
            out[i, j, 0] = np.float32(u1 - u0)
            out[i, j, 1] = np.float32(w1 - w0)
    return out


_flow_kernel_serial = serial_twin(_flow_kernel)


def image_flow(depth: np.ndarray, instance: np.ndarray, K: np.ndarray, cam_to_world: np.ndarray,
               velocities: np.ndarray, ego_velocity: np.ndarray, exposure: float) -> np.ndarray:  # fmt: skip
    """Per pixel (H, W, 2) float32: the image motion [px] (u right, v down) of the surface it sees over an exposure of
    ``exposure`` seconds. ``velocities`` (N + 1, 3): world velocity by instance id (row 0 the static world, zero);
    ``ego_velocity`` (3,) the camera's; ``cam_to_world`` the camera's optical frame → world (4×4)."""
    depth = np.ascontiguousarray(depth, np.float32)
    inst = np.ascontiguousarray(instance)
    vel = np.asarray(velocities, np.float64)
    if inst.shape != depth.shape or vel.ndim != 2 or vel.shape[1] != 3 or int(inst.max(initial=0)) >= len(vel):
        raise ValueError(f"instance {inst.shape} must match depth {depth.shape}, and velocities (N, 3) cover its ids")
    rel = vel - np.asarray(ego_velocity, np.float64)[None, :]
    rot_t = np.ascontiguousarray(np.asarray(cam_to_world, np.float64)[:3, :3].T)
    out = np.empty(depth.shape + (2,), np.float32)
    kernel = pick(_flow_kernel, _flow_kernel_serial, depth.size)
    return kernel(depth, inst.astype(np.int64), np.linalg.inv(np.asarray(K, np.float64)), rot_t, rel, float(exposure), out)


@njit(cache=True, nogil=True, parallel=True)
def _blur_kernel(rgb, flow, max_samples, out):
    height, width, _ = rgb.shape
    for i in prange(height):
        for j in range(width):
            fu = flow[i, j, 0]
            fv = flow[i, j, 1]
            n = int(math.ceil(max(abs(fu), abs(fv))))
            if n < 1:
                for ch in range(3):
                    out[i, j, ch] = rgb[i, j, ch]
                continue
            n = min(n + 1, max_samples)
            a0 = 0.0
            a1 = 0.0
            a2 = 0.0
            for s in range(n):
                t = s / (n - 1) - 0.5
                u = min(max(j + t * fu, 0.0), width - 1.0)
                v = min(max(i + t * fv, 0.0), height - 1.0)
                j0 = min(int(u), width - 2) if width > 1 else 0
                i0 = min(int(v), height - 2) if height > 1 else 0
                j1 = min(j0 + 1, width - 1)
                i1 = min(i0 + 1, height - 1)
                bu = u - j0
                bv = v - i0
                w00 = (1 - bu) * (1 - bv)
                w01 = bu * (1 - bv)
                w10 = (1 - bu) * bv
                w11 = bu * bv
                a0 += w00 * rgb[i0, j0, 0] + w01 * rgb[i0, j1, 0] + w10 * rgb[i1, j0, 0] + w11 * rgb[i1, j1, 0]
                a1 += w00 * rgb[i0, j0, 1] + w01 * rgb[i0, j1, 1] + w10 * rgb[i1, j0, 1] + w11 * rgb[i1, j1, 1]
                a2 += w00 * rgb[i0, j0, 2] + w01 * rgb[i0, j1, 2] + w10 * rgb[i1, j0, 2] + w11 * rgb[i1, j1, 2]
            out[i, j, 0] = np.uint8(min(a0 / n + 0.5, 255.0))
            out[i, j, 1] = np.uint8(min(a1 / n + 0.5, 255.0))
            out[i, j, 2] = np.uint8(min(a2 / n + 0.5, 255.0))
    return out


_blur_kernel_serial = serial_twin(_blur_kernel)


def blur_motion(rgb: np.ndarray, flow: np.ndarray, max_samples: int = MAX_SAMPLES) -> np.ndarray:
    """``rgb`` (H, W, 3) uint8 averaged along each pixel's ``flow`` (:func:`image_flow`), centred on the pixel.

    >>> img = np.zeros((1, 9, 3), np.uint8); img[0, 4] = 90
    >>> flow = np.zeros((1, 9, 2), np.float32); flow[..., 0] = 2.0
    >>> blur_motion(img, flow)[0, :, 0].tolist()  # a 3-sample path: the bright pixel shared by its neighbours
    [0, 0, 0, 30, 30, 30, 0, 0, 0]
    """
    img = np.ascontiguousarray(rgb)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8 or np.shape(flow) != img.shape[:2] + (2,):
        raise ValueError(f"rgb must be (H, W, 3) uint8 and flow (H, W, 2), got {img.dtype} {img.shape} and {np.shape(flow)}")
    out = np.empty_like(img)
    kernel = pick(_blur_kernel, _blur_kernel_serial, img.shape[0] * img.shape[1])
    return kernel(img, np.ascontiguousarray(flow, np.float32), int(max_samples), out)
