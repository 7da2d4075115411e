"""What a real camera does to the rendered light: motion blur over the exposure, then sensor noise, per frame.

:class:`CameraEffects` holds, for the cameras of a rig that have a :class:`~fog_gym.sensors.camera_noise.CameraNoise`,
the frame's noise laws (one per camera: the gain follows that camera's auto-exposure), image flows (with motion
blur) and noise keys. :meth:`CameraEffects.prepare` sets them up once per frame; :meth:`CameraEffects.apply` turns a
noise-free RGB image of the frame — the clean one or any fogged variant (fog is light in the scene, so it comes
before the sensor) — into what the camera records, each variant with its own draws from the episode's one seed;
:meth:`CameraEffects.apply_all` does it for every camera of the frame in one kernel launch, and
:meth:`CameraEffects.begin` begins it on a background thread, so that a large frame's noise overlaps what the env
does next (its points and labels).

Example:
    >>> from fog_gym.sensors.camera import CameraConfig
    >>> from fog_gym.geometry import Pose
    >>> fx = CameraEffects([CameraConfig("CAM_FRONT", Pose(1.8, 0, 1.2), 8, 6, noise="default")])
    >>> img = np.full((6, 8, 3), 100, np.uint8)
    >>> fx.prepare(seed=7, tick=0, exposure={"CAM_FRONT": 1.0}, night=False)
    >>> a, b = fx.apply("CAM_FRONT", img, 0), fx.apply("CAM_FRONT", img, 1)
    >>> bool((a != img).any()), bool((a != b).any()), abs(float(a.mean()) - 100) < 1
    (True, True, True)
    >>> bool((fx.apply_all({"CAM_FRONT": img}, 1)["CAM_FRONT"] == b).all())
    True
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from fog_gym._numba import background, in_worker
from fog_gym._rounds import held
from fog_gym.sensors.camera_noise import CameraNoise, NoiseJob, NoiseLaw, frame_key, noise_laws
from fog_gym.sensors.motion_blur import blur_motion, image_flow

#: Noise laws kept per (sensor, total gain, night), shared by every rig of the process (day frames all share gain 1;
#: a night drive's gains span a few stops, 16 steps each on the default sensor's grid).
TABLE_CACHE = 64
_LAWS: OrderedDict[tuple, NoiseLaw] = OrderedDict()
_LAWS_LOCK = threading.Lock()
#: Pixels of a frame's images from which :meth:`CameraEffects.begin` draws the noise on the background thread
#: (below, the hand-over costs about what it saves).
OVERLAP_FROM = 1 << 16


def overlaps(pixels: int) -> bool:
    """Whether :meth:`CameraEffects.begin` draws a frame's noise on the background thread: from :data:`OVERLAP_FROM`
    pixels, by day and at night: the draws overlap the points and labels (a 1280 × 960 full-rig day frame's noise
    cost 1.07–1.09× overlapped against 1.14–1.17× drawn in line, on this project's AVX2 machine; ``docs/sensors.md``,
    "Day frames from the table too").

    >>> overlaps(OVERLAP_FROM), overlaps(OVERLAP_FROM - 1)
    (True, False)
    """
    return pixels >= OVERLAP_FROM


class CameraEffects:
    """Motion blur and noise for the cameras of a rig whose config has ``noise`` (module docstring)."""

    def __init__(self, cameras: Sequence[Any]) -> None:
        self.noise: dict[str, CameraNoise] = {c.name: c.noise for c in cameras if getattr(c, "noise", None) is not None}
        self._index = {c.name: i for i, c in enumerate(cameras)}
        self._frame: dict[str, tuple[float, int, np.ndarray | None]] = {}  # name → gain, noise key, image flow
        self._law: dict[str, NoiseLaw] = {}
        self._night = False

    def __bool__(self) -> bool:
        return bool(self.noise)

    def laws(self, noises: Sequence[CameraNoise], gains: Sequence[float], night: bool) -> list[NoiseLaw]:
        """The noise law of each (sensor, gain) pair: cached ones as they are (per total gain on the sensor's grid,
        :meth:`~fog_gym.sensors.camera_noise.CameraNoise.gain`: frames whose auto-exposure gains round to the same
        step share it), the others computed together (:func:`~fog_gym.sensors.camera_noise.noise_laws`: one kernel
        launch for all of a frame's cameras)."""
        keys = [(noise, noise.gain(gain, night), bool(night)) for noise, gain in zip(noises, gains)]
        with held(_LAWS_LOCK):
            missing: dict[tuple, float] = {}
            for key, gain in zip(keys, gains):
                if key not in _LAWS:
                    missing.setdefault(key, float(gain))
        laws = dict(zip(missing, noise_laws([k[0] for k in missing], list(missing.values()), night))) if missing else {}
        with held(_LAWS_LOCK):
            _LAWS.update(laws)
            out = []
            for key in keys:
                _LAWS.move_to_end(key)
                out.append(_LAWS[key])
            while len(_LAWS) > max(TABLE_CACHE, len(keys)):
                _LAWS.popitem(last=False)
        return out

    def prepare(self, seed: int, tick: int, exposure: Mapping[str, float], night: bool,
                flows: Mapping[str, Any] | None = None) -> None:  # fmt: skip
        """Set up the frame ``tick`` of the episode whose noise seed is ``seed``: each camera's law from its
        auto-exposure gain ``exposure[name]`` (computed on first use, with the frame's other cameras' laws);
        ``flows[name]`` the arguments of :func:`~fog_gym.sensors.motion_blur.image_flow` but the exposure, for
        cameras with motion blur."""
        self._frame, self._law = {}, {}
        self._night = bool(night)
        for name, noise in self.noise.items():
            flow = None
            if noise.motion_blur and flows is not None and name in flows:
                flow = image_flow(*flows[name], noise.exposure_s[1] if night else noise.exposure_s[0])
            self._frame[name] = (float(exposure.get(name, 1.0)), frame_key(seed, tick, self._index[name], 0), flow)

    def frame_laws(self) -> dict[str, NoiseLaw]:
        """This frame's noise law of each camera with noise (:meth:`laws`, once per frame)."""
        if not self._law and self._frame:
            names = list(self._frame)
            laws = self.laws([self.noise[n] for n in names], [self._frame[n][0] for n in names], self._night)
            self._law = dict(zip(names, laws))
        return self._law

    def apply(self, name: str, rgb: np.ndarray, variant: int) -> np.ndarray:
        """The recorded image of noise-free ``rgb`` of camera ``name`` in this frame; ``variant`` 0 the clean frame,
        another integer a fogged one (its own draws). Cameras without noise get ``rgb`` back."""
        return self.apply_all({name: rgb}, variant)[name]

    def apply_all(self, images: Mapping[str, np.ndarray], variant: int) -> dict[str, np.ndarray]:
        """:meth:`apply` to every camera's image of ``images`` (name → noise-free RGB), the noise of all of them
        drawn in one kernel launch."""
        return self.begin(images, variant, overlap=False)()

    def begin(self, images: Mapping[str, np.ndarray], variant: int,
              overlap: bool = True) -> Callable[[], dict[str, np.ndarray]]:  # fmt: skip
        """:meth:`apply_all`, begun: a function that returns its dict. With ``overlap``, where :func:`overlaps` says
        so (night frames from :data:`OVERLAP_FROM` pixels; day frames too on machines without 512-bit vectors), the
        laws and the noise run on the process's background thread (:func:`fog_gym._numba.background`, serial
        kernels) while the caller goes on — an env computes its points and labels meanwhile — and the function takes
        the tasks not yet begun and waits for the rest; until it is called, this object and ``images`` must not be
        changed. Otherwise the noise is drawn here, in one parallel launch (with 512-bit vectors a day frame's draw
        ran faster so: ``docs/sensors.md``, "A day frame's noise in line"). Motion blur runs first, here (its kernels
        are parallel). The same images either way."""
        out = dict(images)
        names = [n for n in images if n in self._frame]
        if not names:
            return lambda: out
        rgbs, keys = [], []
        for name in names:
            _, key, flow = self._frame[name]
            rgbs.append(blur_motion(images[name], flow) if flow is not None else images[name])
            keys.append(frame_key(key, variant, 0, 0) if variant else key)

        def job() -> NoiseJob:  # the frame's laws (computed on first use), then the draws' tasks
            laws = self.frame_laws()
            return NoiseJob(rgbs, [laws[n] for n in names], keys)

        pixels = sum(x.shape[0] * x.shape[1] for x in rgbs)
        if not overlap or in_worker() or not overlaps(pixels):
            out.update(zip(names, job().run()))
            return lambda: out
        jobs: list[NoiseJob] = []
        ready = threading.Event()

        def start() -> None:  # on the background thread
            try:
                jobs.append(job())
            finally:
                ready.set()
            jobs[0].work()

        started = background().submit(start)

        def finish() -> dict[str, np.ndarray]:
            ready.wait()
            if jobs:
                jobs[0].work()  # the tasks the background thread has not taken yet, beside it
            started.result()  # its last task done (or its error raised here)
            out.update(zip(names, jobs[0].outs))
            return out

        return finish
