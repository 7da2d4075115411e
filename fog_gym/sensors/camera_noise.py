"""Camera noise: photon shot noise, read noise, a gain that follows the auto-exposure, and quantisation (EMVA 1288).

fog-gym's renderer gives each pixel an exposed linear signal ``x`` (the frame's 8-bit value over 255 by day; at night
the value through the inverse of the night tone curve, :func:`fog_gym.render.shading.tone`). A real sensor turns
that signal into electrons and back into a digital value, and on the way it adds noise. The linear camera model of
the EMVA 1288 standard (Release 4.0, its linear model of a camera's output and noise):

* the pixel collects ``μ_e = x · Q / A`` electrons on average, ``Q`` the full-well capacity (a full-scale signal at
  the sensor's base gain fills the well) and ``A`` the total gain; the count is Poisson: ``σ_e² = μ_e``
  (photon shot noise);
* the read-out adds Gaussian noise of ``σ_r`` electrons rms (read and dark noise together);
* the well saturates at ``Q``; the system gain ``K = 255·A/Q`` DN per electron maps the count onto the 8-bit
  output, through the night tone curve at night, rounded to the nearest level (quantisation, ``σ_q² = 1/12`` DN²;
  the sensor's 12-bit ADC steps are 1/16 of an output level, finer than the output's own rounding);
* so ``σ_y² = K²(σ_r² + μ_e) + 1/12`` DN² at a mid-grey pixel (:func:`predicted_variance`).

**The gain follows the auto-exposure.** By day ``A = 1`` (a sunlit scene fills the well at a short exposure; the
renderer's day gain is 1). At night the renderer's linear units stand for a scene three to four orders of
magnitude darker than daylight (a lit road: tens of lux; sunlight: tens of thousands); the exposure time stretches
to the frame period and the sensor's analog and digital gain make up the rest. The model takes ``A = night_gain ·
g`` with ``g`` the frame's auto-exposure gain (:attr:`fog_gym.sensors.CameraRig.exposure`, 1–16): night frames
are noisier, and the darker the scene the noisier. A sensor sets its gain in steps (registers of analog and digital
gain), and so does the model: ``A`` is rounded to the nearest of ``gain_step_ev`` stops (default 1/16 EV: the
gain within 2.2 %, the noise's standard deviation within 1.1 %, of the continuous gain's), so that consecutive
frames of a drive share their noise laws (computed once per step and sensor; a lit night street moves a camera's
gain by one to four steps a frame).

**The default sensor** (:data:`DEFAULT_NOISE`, ``camera_noise="default"``) is an automotive-class 3.0 µm pixel of
onsemi's DR-Pix family, as in the AR0230CS datasheet (same pixel family as the AR0231AT automotive sensor): its
maximum SNR of 41 dB gives the full well, ``Q = 10^(41/10) ≈ 12 600 e⁻`` (shot-noise limited at full scale);
read noise ``σ_r = 2.5 e⁻`` is an assumption (the 2–3 e⁻ of the pixel family; not on the datasheet);
``night_gain = 8`` is an assumption (at ``g = 4``, a typical lit street, 1 DN is 1.5 electrons). A
:class:`CameraNoise` takes other values.

**How it is drawn.** The output of a pixel depends only on its noise-free level ``v`` (0–255), the gain and its
random draw, so per camera and frame :func:`noise_law` holds the exact distribution of the model for every ``v``
(the Poisson ⊛ Gaussian law summed exactly, :func:`fog_gym.sensors.poisson_gauss._cdf_tables`), tabulated as
:data:`TABLE_SIZE` quantiles (:func:`noise_table`). One kernel draws from it (:func:`add_noise`,
:func:`add_noise_many`): each pixel's counter-based 32-bit hash (:func:`_hash32`) of the frame's key and the pixel's
index picks its three channels' quantiles (bits 0–9, 11–20 and 22–31), one look-up each, so the same key gives the
same noise on any machine and thread count, and every (episode, frame, camera, fog variant) has its own key
(:func:`frame_key`). Day and night frames alike: the table is the exact law (its own rounding to 1/1024 quantiles
is a total variation of 0.0036 from it by day), and on this project's AVX2 machine its look-ups cost 0.58× the
Gaussian draw in vector arithmetic that day frames took from 2026-11-29 to 2026-12-03 (``docs/sensors.md``, "Day
frames from the table too").

**Motion blur** (``motion_blur=True``, opt-in): the frame is averaged over the exposure time along each pixel's image
motion (:func:`fog_gym.sensors.motion_blur.blur_motion`, a velocity-buffer blur: the ego's motion for the static
world and each vehicle's own motion from the instance buffer), before the noise, as the sensor integrates before it
reads out.

Example:
    >>> table = noise_table(DEFAULT_NOISE, gain=1.0, night=False)
    >>> table.shape, table.dtype
    ((256, 1024), dtype('uint8'))
    >>> round(float(table[128].astype(float).std()), 2), round(predicted_variance(DEFAULT_NOISE, 128, 1.0) ** 0.5, 2)
    (1.64, 1.64)
    >>> img = np.full((4, 4, 3), 128, np.uint8)
    >>> bool((add_noise(img, table, frame_key(0, 0, 0, 0)) == add_noise(img, table, frame_key(0, 0, 0, 0))).all())
    True
    >>> bool((noise_law(DEFAULT_NOISE, 1.0, False).table == table).all())
    True
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from numba import njit, prange, types
from numba.extending import intrinsic

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym._numba import pick, serial_twin
from fog_gym.sensors.poisson_gauss import _cdf_tables, _cdf_tables_serial, _quantile_rows, _quantile_rows_serial
from fog_gym.checks import finite, interval, positive
from fog_gym.render.shading import KNEE

#: Quantiles per level of a noise table (a draw resolves probabilities of 1/1024: tails beyond ±3.3 σ are cut; a
#: smaller table stays in the cache: the lookups are the kernel's cost).
TABLE_SIZE = 1024
_BITS = TABLE_SIZE.bit_length() - 1  # a level's row of the flattened table starts at level << _BITS


@dataclass(frozen=True)
class CameraNoise:
    """A camera's sensor noise (module docstring): full well ``full_well_e`` [e⁻], read noise ``read_noise_e``
    [e⁻ rms], the night gain at auto-exposure gain 1 ``night_gain``, optional motion blur over the exposure time
    (``exposure_s``: by day, at night [s]), the sensor it describes (``sensor``, for the record) and the step of
    its gain ``gain_step_ev`` [EV]: the total gain is set on a grid of that many stops (0: continuous).

    >>> CameraNoise(full_well_e=6000, read_noise_e=3.0).full_well_e
    6000.0
    >>> CameraNoise(read_noise_e=-1)
    Traceback (most recent call last):
    ...
    ValueError: CameraNoise.read_noise_e must be >= 0 electrons, got -1
    """

    full_well_e: float = 12_600.0
    read_noise_e: float = 2.5
    night_gain: float = 8.0
    motion_blur: bool = False
    exposure_s: tuple[float, float] = (0.002, 0.030)
    sensor: str = "onsemi DR-Pix 3.0 um (AR0230CS datasheet: SNRmax 41 dB); read noise and night gain assumed"
    gain_step_ev: float = 1.0 / 16.0

    def __post_init__(self) -> None:
        full = finite("CameraNoise.full_well_e", self.full_well_e)
        if full < 255.0:
            raise ValueError(f"CameraNoise.full_well_e must be >= 255 electrons (one per output level), got {self.full_well_e!r}")
        read = finite("CameraNoise.read_noise_e", self.read_noise_e)
        if read < 0:
            raise ValueError(f"CameraNoise.read_noise_e must be >= 0 electrons, got {self.read_noise_e!r}")
        night = finite("CameraNoise.night_gain", self.night_gain)
        if night < 1.0:
            raise ValueError(f"CameraNoise.night_gain must be >= 1, got {self.night_gain!r}")
        if not isinstance(self.motion_blur, bool):
            raise ValueError(f"CameraNoise.motion_blur must be True or False, got {self.motion_blur!r}")
        exp = tuple(self.exposure_s) if isinstance(self.exposure_s, (tuple, list)) else ()
        if len(exp) != 2 or not all(isinstance(e, (int, float)) and not isinstance(e, bool) and math.isfinite(e)
                                    and 0 < e <= 0.1 for e in exp):  # fmt: skip
            raise ValueError(f"CameraNoise.exposure_s must be (day, night) exposure times in (0, 0.1] s, got {self.exposure_s!r}")
        if not isinstance(self.sensor, str):
            raise ValueError(f"CameraNoise.sensor must be a string, got {self.sensor!r}")
        step = finite("CameraNoise.gain_step_ev", self.gain_step_ev)
        if not 0.0 <= step <= 1.0:
            raise ValueError(f"CameraNoise.gain_step_ev must be in [0, 1] stops (0: continuous), "
                             f"got {self.gain_step_ev!r}")
        object.__setattr__(self, "gain_step_ev", step)
        object.__setattr__(self, "full_well_e", full)
        object.__setattr__(self, "read_noise_e", read)
        object.__setattr__(self, "night_gain", night)
        object.__setattr__(self, "exposure_s", (float(exp[0]), float(exp[1])))

    def gain(self, exposure_gain: float, night: bool) -> float:
        """The total gain ``A`` of a frame with auto-exposure gain ``exposure_gain`` (module docstring), on the
        sensor's grid of :attr:`gain_step_ev` stops (the nearest step; powers of two lie on every grid of 1/n stops).

        >>> DEFAULT_NOISE.gain(1.0, False), DEFAULT_NOISE.gain(4.0, True), round(DEFAULT_NOISE.gain(3.0, True), 3)
        (1.0, 32.0, 23.629)
        """
        a = float(exposure_gain) * (self.night_gain if night else 1.0)
        if self.gain_step_ev == 0.0 or not a > 0.0:
            return a
        return 2.0 ** (round(math.log2(a) / self.gain_step_ev) * self.gain_step_ev)


#: The default sensor: ``camera_noise="default"``.
DEFAULT_NOISE = CameraNoise()
#: Named sensors ``camera_noise=`` accepts.
NOISE_PRESETS: dict[str, CameraNoise] = {"default": DEFAULT_NOISE}


def parse_noise(value: Any, field: str = "camera_noise") -> CameraNoise | None:
    """``None`` (noise-free, the default), a preset name of :data:`NOISE_PRESETS`, or a :class:`CameraNoise`."""
    if value is None or isinstance(value, CameraNoise):
        return value
    if isinstance(value, str) and value in NOISE_PRESETS:
        return NOISE_PRESETS[value]
    raise ValueError(f"{field} must be None, one of {sorted(NOISE_PRESETS)} or a CameraNoise, got {value!r}")


# -- the signal a level stands for and the level a signal gives ---------------------------------------------------
def level_signal(levels: np.ndarray, night: bool) -> np.ndarray:
    """The exposed linear signal ``x`` of 8-bit levels: the level over 255 by day, through the inverse of the night
    tone curve (:func:`fog_gym.render.shading.tone`) at night, where level 255 maps to the middle of its rounding
    interval (the shoulder never reaches 1)."""
    y = np.asarray(levels, np.float64) / 255.0
    if not night:
        return y
    y = np.minimum(y, 254.5 / 255.0)
    shoulder = KNEE - (1.0 - KNEE) * np.log(np.maximum(1.0 - (y - KNEE) / (1.0 - KNEE), 1e-300))
    return np.where(y <= KNEE, y, shoulder)


def _thresholds(noise: CameraNoise, gain: float, night: bool) -> np.ndarray:
    """Electron counts where the output steps from level d to d + 1 (d = 0..254), after saturation at the well."""
    x = level_signal(np.arange(255) + 0.5, night)
    return x * noise.full_well_e / gain


def _checked_laws(noises: Sequence[CameraNoise], gains: Sequence[float]) -> list[float]:
    """The gains as floats, or a one-line ``ValueError``: as many sensors (each a :class:`CameraNoise`) as gains,
    each gain a finite number > 0 (an auto-exposure gain)."""
    if len(noises) != len(gains):
        raise ValueError(f"noises and gains must be as many, got {len(noises)} and {len(gains)}")
    for noise in noises:
        if not isinstance(noise, CameraNoise):
            raise ValueError(f"noise must be a CameraNoise (parse_noise turns a preset name into one), got {noise!r}")
    return [positive("gain", g) for g in gains]


def _exact_cdfs(noises: Sequence[CameraNoise], gains: Sequence[float], night: bool) -> np.ndarray:
    """``(n, 256, 255)``: ``P(output <= d)`` for law ``i`` (sensor ``noises[i]`` at auto-exposure gain ``gains[i]``),
    a noise-free level ``v`` (row) and ``d = 0..254`` (column); every law in one kernel launch."""
    gains = _checked_laws(noises, gains)
    lam = np.empty((len(noises), 256))
    thresholds = np.empty((len(noises), 255))
    signal = level_signal(np.arange(256), night)
    for i, (noise, gain) in enumerate(zip(noises, gains)):
        a = noise.gain(gain, night)
        lam[i] = signal * noise.full_well_e / a  # mean electrons per level
        t = _thresholds(noise, a, night)
        t = np.where(t > noise.full_well_e, np.inf, t)  # a full well reads above every threshold it reaches
        thresholds[i] = np.where(np.isfinite(t), t, -1.0)
    sigma = np.array([noise.read_noise_e for noise in noises], np.float64)
    return pick(_cdf_tables, _cdf_tables_serial, len(noises), 1)(lam, thresholds, sigma)


def _exact_cdf(noise: CameraNoise, gain: float, night: bool) -> np.ndarray:
    """``(256, 255)``: ``P(output <= d)`` for a noise-free level ``v`` (row) and ``d = 0..254`` (column)."""
    return _exact_cdfs([noise], [gain], night)[0]


def _quantiles(cdf: np.ndarray) -> np.ndarray:
    """``(..., 256, TABLE_SIZE)`` uint8 tables of ``(..., 256, 255)`` CDFs: the level of quantile ``u_m = (m + ½)/M``
    is the number of thresholds with ``F(t_d) <= u_m``; threshold ``d`` is reached from ``m = ceil(F·M − ½)`` on, so
    a histogram of those first quantiles, summed along ``m``, is the table."""
    rows = np.ascontiguousarray(cdf).reshape(-1, cdf.shape[-1])
    kernel = pick(_quantile_rows, _quantile_rows_serial, len(rows), 512)
    return kernel(rows, TABLE_SIZE).reshape(*cdf.shape[:-1], TABLE_SIZE)


def noise_table(noise: CameraNoise, gain: float, night: bool) -> np.ndarray:
    """``(256, TABLE_SIZE)`` uint8: row ``v`` holds the model's output levels for a noise-free level ``v`` at the
    quantiles ``(m + ½)/TABLE_SIZE`` (module docstring; ``gain`` is the frame's auto-exposure gain)."""
    return _quantiles(_exact_cdf(noise, gain, night))


class NoiseLaw(NamedTuple):
    """A frame's noise (:func:`noise_law`): the exact law's ``table`` (:func:`noise_table`)."""

    table: np.ndarray


def noise_law(noise: CameraNoise, gain: float, night: bool) -> NoiseLaw:
    """The noise of a frame with auto-exposure gain ``gain`` (module docstring): the exact law's table."""
    return noise_laws([noise], [gain], night)[0]


def noise_laws(noises: Sequence[CameraNoise], gains: Sequence[float], night: bool) -> list[NoiseLaw]:
    """:func:`noise_law` of each (sensor, gain) pair — a frame's cameras — with every exact law summed in one
    kernel launch and tabulated in another (the pairs checked there, :func:`_checked_laws`)."""
    if not len(noises) and not len(gains):
        return []
    return [NoiseLaw(table) for table in _quantiles(_exact_cdfs(noises, gains, night))]


def predicted_variance(noise: CameraNoise, level: float, gain: float, night: bool = False) -> float:
    """EMVA 1288's output variance [DN²] at a noise-free level in the linear part of the encoding:
    ``K²(σ_r² + μ_e) + 1/12`` with ``K = 255·A/Q`` (clipping and the night shoulder not included)."""
    (gain,) = _checked_laws([noise], [gain])
    level = interval("level", level, 0.0, 255.0)
    a = noise.gain(gain, night)
    k = 255.0 * a / noise.full_well_e
    mu_e = level / 255.0 * noise.full_well_e / a
    return k * k * (noise.read_noise_e**2 + mu_e) + 1.0 / 12.0


# -- keys and the kernel -------------------------------------------------------------------------------------------
_M64 = (1 << 64) - 1


def _mix(z: int) -> int:
    z = (z + 0x9E3779B97F4A7C15) & _M64
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _M64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _M64
    return z ^ (z >> 31)


def frame_key(seed: int, tick: int, camera: int, variant: int) -> int:
    """The 64-bit noise key of one frame: episode ``seed`` (drawn from the env's ``camera_noise`` stream), keyframe
    ``tick``, ``camera`` index in the rig and fog ``variant`` (0 the clean frame, a level's key + 1 a fogged one).

    >>> frame_key(1, 2, 0, 0) != frame_key(1, 2, 0, 1) != frame_key(1, 3, 0, 0)
    True
    """
    z = 0
    for part in (seed, tick, camera, variant):
        z = _mix(z ^ (int(part) & _M64))
    return z


#: Pixels (all images of a call together) below which the kernels run on one thread: under this size a parallel
#: launch costs more than it saves (on this project's two cores, the table's kernel serial against parallel: 0.17
#: against 0.27 ms at 320 × 240, 0.68 against 1.0 ms at 640 × 480, 2.7 against 1.65 ms at 1280 × 960).
NOISE_SERIAL_BELOW = 1 << 19
_BLOCK = 256  # pixels whose hashes are drawn together
_CHUNKS = 16  # each image's spans in the parallel kernel (whole spans, not rows: a row's work is too small to share)


# -- 32-bit integer operations: numba widens uint32 arithmetic to 64 bits, which halves the lanes of a vector and
# -- needs 64-bit multiplies; these stay in 32 bits (wrapping), as a C compiler's would
def _u32_op(name):
    @intrinsic
    def op(typingctx, a, b):
        def codegen(context, builder, signature, args):
            return getattr(builder, name)(*args)

        return types.uint32(types.uint32, types.uint32), codegen

    return op


_add32, _mul32, _xor32, _and32, _shr32 = (_u32_op(n) for n in ("add", "mul", "xor", "and_", "lshr"))


@njit(cache=True, nogil=True, inline="always")
def _hash32(i, k1, k2):
    """A 32-bit hash of index ``i`` under the key ``(k1, k2)``: ``i ^ k1`` through two multiply–xorshift rounds,
    ``k2`` added between them (32-bit vector arithmetic, no 64-bit multiplies)."""
    x = _xor32(i, k1)
    x = _mul32(_xor32(x, _shr32(x, np.uint32(16))), np.uint32(0x7FEB352D))
    x = _add32(x, k2)
    x = _mul32(_xor32(x, _shr32(x, np.uint32(15))), np.uint32(0x846CA68B))
    return _xor32(x, _shr32(x, np.uint32(16)))


@njit(cache=True, nogil=True, inline="always")
def _noise_span(flat, table, k1, k2, out, p0, p1):
    """Pixels ``p0 .. p1 − 1`` of the flattened image ``flat`` into ``out``: pixel ``p``'s hash is :func:`_hash32` of
    ``p``; its bits 0–9, 11–20 and 22–31 pick its red, green and blue quantiles. The hashes of a block of pixels first
    (a loop the compiler vectorises), then their look-ups through slices that start at 0 with unsigned indices (no
    check for negative indices in the loop: 18 % less time than signed indices into the whole image). (A 64-bit
    SplitMix64 hash per pixel, the draw before 2026-12-03, cost twice this on a machine without AVX-512's 64-bit
    multiplies: four 1280 × 960 images on one thread, 33.9 against 17.1 ms.)"""
    mask = np.uint32(TABLE_SIZE - 1)
    s11, s22 = np.uint32(11), np.uint32(22)
    bits, one, two = np.uint64(_BITS), np.uint64(1), np.uint64(2)
    hashes = np.empty(_BLOCK, np.uint32)
    for b0 in range(p0, p1, _BLOCK):
        b1 = min(p1, b0 + _BLOCK)
        base = np.uint32(b0)
        for j in range(b1 - b0):
            hashes[j] = _hash32(_add32(np.uint32(j), base), k1, k2)
        f, o = flat[3 * b0:3 * b1], out[3 * b0:3 * b1]
        for j in range(b1 - b0):
            z = hashes[j]
            q = np.uint64(3 * j)
            o[q] = table[(np.uint64(f[q]) << bits) | np.uint64(_and32(z, mask))]
            o[q + one] = table[(np.uint64(f[q + one]) << bits) | np.uint64(_and32(_shr32(z, s11), mask))]
            o[q + two] = table[(np.uint64(f[q + two]) << bits) | np.uint64(_shr32(z, s22))]


@njit(cache=True, nogil=True, inline="always")
def _noise_task(flats, outs, tables, keys, t):
    """Task ``t`` of a frame's noise: span ``t % _CHUNKS`` of image ``t // _CHUNKS`` (flattened) from its table
    (flattened)."""
    i, c = t // _CHUNKS, t % _CHUNKS
    k1, k2 = np.uint32(keys[i] & np.uint64(0xFFFFFFFF)), np.uint32(keys[i] >> np.uint64(32))
    n = flats[i].shape[0] // 3
    step = (n + _CHUNKS - 1) // _CHUNKS
    _noise_span(flats[i], tables[i], k1, k2, outs[i], c * step, min(n, (c + 1) * step))


@njit(cache=True, nogil=True, parallel=True)
def _noise_kernel(flats, outs, tables, keys):
    """Every image of a frame in one launch (a launch per camera pays the pool's wake-up each time): its tasks
    (:func:`_noise_task`) over the pool's threads."""
    for t in prange(len(flats) * _CHUNKS):
        _noise_task(flats, outs, tables, keys, t)
    return outs


@njit(cache=True, nogil=True)
def _noise_tasks(flats, outs, tables, keys, t0, t1):
    """Tasks ``t0 .. t1 − 1`` of a frame's noise on the calling thread (:class:`NoiseJob`: Python threads share
    them)."""
    for t in range(t0, t1):
        _noise_task(flats, outs, tables, keys, t)


_noise_kernel_serial = serial_twin(_noise_kernel)


class NoiseJob:
    """:func:`add_noise_many`'s work, as tasks that any Python thread may take (:meth:`work`): a background thread
    starts on a frame's noise while the env computes its points and labels, and the thread that needs the images
    takes what is left beside it. The same images as :func:`add_noise_many` (the same tasks' code).

    >>> img, table = np.full((4, 4, 3), 128, np.uint8), noise_table(DEFAULT_NOISE, 1.0, False)
    >>> job = NoiseJob([img], [table], [5])
    >>> job.work()
    >>> bool((job.outs[0] == add_noise(img, table, 5)).all())
    True
    """

    def __init__(self, images: Sequence[np.ndarray], laws: Sequence[NoiseLaw | np.ndarray],
                 keys: Sequence[int]) -> None:  # fmt: skip
        if not (len(images) == len(laws) == len(keys)) or not images:
            raise ValueError(f"images, laws and keys must be non-empty and as many, got {len(images)}, {len(laws)}, "
                             f"{len(keys)}")  # fmt: skip
        imgs = [np.ascontiguousarray(x) for x in images]
        for img in imgs:
            if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
                raise ValueError(f"rgb must be an (H, W, 3) uint8 image, got {img.dtype} {img.shape}")
        laws = [law if isinstance(law, NoiseLaw) else NoiseLaw(law) for law in laws]
        for k in keys:
            if isinstance(k, bool) or not isinstance(k, (int, np.integer)):
                raise ValueError(f"keys must be integers (frame_key), got {k!r}")
        for law in laws:
            t = law.table
            if not isinstance(t, np.ndarray) or t.shape != (256, TABLE_SIZE) or t.dtype != np.uint8:
                raise ValueError(f"table must be a (256, {TABLE_SIZE}) uint8 noise table, got "
                                 f"{getattr(t, 'dtype', type(t))} {getattr(t, 'shape', '')}")  # fmt: skip
        # one allocation for all: numpy asks the kernel for huge pages from 4 MiB on, and a frame's fresh 4 KiB pages
        # cost as much as its noise (four separate 1280 × 960 images: 6.9 ms of page faults on this project's
        # machine; one block: 0.03 ms); each image is a view of it
        block = np.empty(sum(x.size for x in imgs), np.uint8)
        ends = np.cumsum([x.size for x in imgs])
        #: The noisy images (filled once every task has run).
        self.outs = [block[e - x.size:e].reshape(x.shape) for x, e in zip(imgs, ends)]
        self.pixels = sum(x.shape[0] * x.shape[1] for x in imgs)
        self.args = (tuple(x.reshape(-1) for x in imgs), tuple(o.reshape(-1) for o in self.outs),
                     tuple(law.table.reshape(-1) for law in laws), np.array([int(k) & _M64 for k in keys], np.uint64))
        self.tasks = len(imgs) * _CHUNKS
        self._next = itertools.count()  # its next() is atomic: each task is taken by one thread

    def work(self) -> None:
        """Take tasks until none is left, one at a time (on one thread; other threads may take tasks meanwhile)."""
        while (t := next(self._next)) < self.tasks:
            _noise_tasks(*self.args, t, t + 1)

    def run(self) -> list[np.ndarray]:
        """Every task in one launch (parallel from :data:`NOISE_SERIAL_BELOW` pixels; the job not yet begun)."""
        pick(_noise_kernel, _noise_kernel_serial, self.pixels, NOISE_SERIAL_BELOW)(*self.args)
        self._next = itertools.count(self.tasks)
        return self.outs


def add_noise_many(images: Sequence[np.ndarray], laws: Sequence[NoiseLaw | np.ndarray], keys: Sequence[int]) -> list[np.ndarray]:
    """Each (H, W, 3) uint8 image of ``images`` with the noise of its law (a :class:`NoiseLaw`, or a bare
    :func:`noise_table`) drawn from its key (:func:`frame_key`), in one kernel launch; new arrays
    (views of one new block), the inputs are not changed."""
    return NoiseJob(images, laws, keys).run()


def add_noise(rgb: np.ndarray, law: NoiseLaw | np.ndarray, key: int) -> np.ndarray:
    """``rgb`` (H, W, 3) uint8 with the noise of ``law`` (a :func:`noise_law`, or a :func:`noise_table`) drawn from
    ``key`` (:func:`frame_key`); a new array, the input is not changed."""
    return add_noise_many([rgb], [law], [key])[0]
