"""Detection kernels: which vehicles each fogged sensor actually sees, from rays cast into the scene (numba).

Every sensor here casts the rays its data is made of, but only those that can land on a vehicle: the LiDAR's beams
through a vehicle's angular extent, the camera's pixels inside a vehicle's projected box and a ring around it,
the radar's random rays. Occluders are every other vehicle's box and the ground (z = 0); roadside props are not
tested (on the RL presets' straight highway they stand beside the road). Random draws (CARLA's LiDAR drop-off,
measurement noise, the radar's rays) come from a counter-based hash of (episode key, tick, sensor, ray or vehicle),
so the result does not depend on which rays were cast or in which order, and a seed fixes it.

* LiDAR (CARLA ``ray_cast`` + Hahner et al. fog): a return on vehicle j at range R with intensity
  ``exp(−0.004 R)`` survives CARLA's general and intensity drop-off, then the Hahner model
  (:func:`fog_gym.fog.lidar.hahner_keeps`): a fog return replaces it when the fog's soft response is stronger. At
  most ``max_rays`` beams per vehicle are cast, evenly strided over its angular extent; the surviving count is
  scaled by the stride (exact for vehicles under ``max_rays`` beams: all distant ones).
* Camera (Koschmieder on a day scene): each sampled pixel's ray gives radiance ``J`` (vehicle: its albedo shaded
  by the sun as the renderer shades faces; ground: the road-surface class; sky: the horizon colour) and
  fogged luminance ``I = J·t + A·(1 − t)``, ``t = exp(−α·ℓ)``, ``A`` the horizon's. A vehicle's Weber contrast is
  its mean fogged luminance over its visible pixels against the mean of what those pixels would show without it
  (the fogged road or sky behind it): the contrast of the object against its background that defines visibility,
  so a black car against the sky is seen to ≈ V.
* Radar (CARLA ``sensor.other.radar``): random rays into the FOV cone; a hit on a vehicle is a detection with its
  range, azimuth and radial velocity. Never fogged.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym.fog.depth import segment_depth
from fog_gym.fog.lidar import hahner_keeps
from fog_gym.fog.lidar_field import field_keeps
from fog_gym.fog.returns import field_last_detected, last_detected

_MASK = np.uint64(0xFFFFFFFFFFFFFFFF)
#: Sensor keys of the hash streams.
LIDAR_KEY, CAMERA_KEY, RADAR_KEY, NOISE_KEY = 1, 2, 3, 4


@njit(cache=True, inline="always")
def _splitmix(x):
    x = (x + np.uint64(0x9E3779B97F4A7C15)) & _MASK
    x = ((x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)) & _MASK
    x = ((x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)) & _MASK
    return x ^ (x >> np.uint64(31))


@njit(cache=True, nogil=True)
def uniform(key, a, b, c, d):
    """A uniform draw in [0, 1) from the hash of (key, a, b, c, d) (non-negative integers)."""
    h = _splitmix(np.uint64(key))
    h = _splitmix(h ^ np.uint64(a))
    h = _splitmix(h ^ np.uint64(b))
    h = _splitmix(h ^ np.uint64(c))
    h = _splitmix(h ^ np.uint64(d))
    return (h >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True, nogil=True)
def normal(key, a, b, c, d):
    """A standard normal draw (Box–Muller on two hashed uniforms)."""
    u1 = max(uniform(key, a, b, c, 2 * d), 1e-300)
    u2 = uniform(key, a, b, c, 2 * d + 1)
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


@njit(cache=True, nogil=True)
def ray_box(ox, oy, oz, dx, dy, dz, cx, cy, yaw, hl, hw, h):
    """Entry distance of a ray into an upright box (centre (cx, cy), yaw, half length/width, height h from z = 0) and
    the entry face's normal axis (0: x, 1: y, 2: z) and sign; (inf, -1, 0) when missed or when the origin is inside."""
    return ray_box_cs(ox, oy, oz, dx, dy, dz, cx, cy, math.cos(yaw), math.sin(yaw), hl, hw, h)


@njit(cache=True, nogil=True, inline="always")
def ray_box_cs(ox, oy, oz, dx, dy, dz, cx, cy, c, s, hl, hw, h):
    """:func:`ray_box` of a box whose yaw's cosine and sine are ``c`` and ``s`` (computed once per box, not per ray)."""
    px, py = ox - cx, oy - cy
    lx = c * px + s * py
    ly = -s * px + c * py
    ldx = c * dx + s * dy
    ldy = -s * dx + c * dy
    t0 = -np.inf
    t1 = np.inf
    axis = -1
    sign = 0.0
    lo = (-hl, -hw, 0.0)
    hi = (hl, hw, h)
    o = (lx, ly, oz)
    d = (ldx, ldy, dz)
    for k in range(3):
        if abs(d[k]) < 1e-12:
            if o[k] < lo[k] or o[k] > hi[k]:
                return np.inf, -1, 0.0
            continue
        ta = (lo[k] - o[k]) / d[k]
        tb = (hi[k] - o[k]) / d[k]
        sg = -1.0
        if ta > tb:
            ta, tb = tb, ta
            sg = 1.0
        if ta > t0:
            t0 = ta
            axis = k
            sign = sg
        if tb < t1:
            t1 = tb
        if t0 > t1:
            return np.inf, -1, 0.0
    if t0 <= 0.0:  # behind, or the origin inside the box
        return np.inf, -1, 0.0
    return t0, axis, sign


#: Columns of :func:`box_table`: the boxes' centre, yaw, size, their angular extents seen from the sensor and the yaw's
#: cosine and sine.
BX, BY, BYAW, BL, BW, BH, AMIN, AMAX, EMIN, EMAX, RMIN, BCOS, BSIN = range(13)


@njit(cache=True, nogil=True)
def box_table(n, bx, by, byaw, bl, bw, bh, amin, amax, emin, emax, rmin):
    """The boxes and their :func:`angular_extents` as one ``(n, 13)`` table (columns :data:`BX` … :data:`BSIN`) for
    :func:`nearest`: one array per call instead of eleven (numba counted a reference to each array at every call, two
    atomic operations each: a fifth of the detection kernel's time), and each yaw's cosine and sine once (a ray's
    test of a box took them every time: a seventh of the kernel's time)."""
    box = np.empty((n, 13))
    for j in range(n):
        box[j, BX], box[j, BY], box[j, BYAW] = bx[j], by[j], byaw[j]
        box[j, BL], box[j, BW], box[j, BH] = bl[j], bw[j], bh[j]
        box[j, AMIN], box[j, AMAX], box[j, EMIN], box[j, EMAX] = amin[j], amax[j], emin[j], emax[j]
        box[j, RMIN] = rmin[j]
        box[j, BCOS], box[j, BSIN] = math.cos(byaw[j]), math.sin(byaw[j])
    return box


@njit(cache=True, nogil=True, inline="always")
def nearest(ox, oy, oz, dx, dy, dz, box, order, az, el, max_t):
    """Nearest hit along a ray among the boxes of ``box`` (a :func:`box_table`; slot 0, the ego, is skipped) and the
    ground: (t, box or −1 ground or −2 nothing, face axis, face sign). Boxes are visited nearest first (``order`` by
    their horizontal distance to the footprint, :data:`RMIN`: no hit can be nearer) and skipped when the ray's azimuth
    ``az`` or elevation ``el`` (radians, sensor frame) lies outside their angular extent."""
    best_t = max_t
    best = -2
    best_axis = -1
    best_sign = 0.0
    if dz < 0.0:
        tg = -oz / dz
        if tg < best_t:
            best_t = tg
            best = -1
    for q in range(order.shape[0]):
        j = order[q]
        if box[j, RMIN] >= best_t:
            break
        if az < box[j, AMIN] or az > box[j, AMAX] or el < box[j, EMIN] or el > box[j, EMAX]:
            continue
        t, axis, sign = ray_box_cs(ox, oy, oz, dx, dy, dz, box[j, BX], box[j, BY], box[j, BCOS], box[j, BSIN],
                                   box[j, BL] / 2, box[j, BW] / 2, box[j, BH])  # fmt: skip
        if t < best_t:
            best_t = t
            best = j
            best_axis = axis
            best_sign = sign
    return best_t, best, best_axis, best_sign


@njit(cache=True, nogil=True)
def angular_extents(n, bx, by, byaw, bl, bw, bh, sx, sy, sz, syaw, amin, amax, emin, emax, rmin):
    """Per box seen from a sensor at (sx, sy, sz) with yaw ``syaw``: azimuth interval (radians, positive to the right
    = +y; from its footprint's corners), elevation interval (conservative: from the footprint's nearest and
    farthest horizontal distances) and ``rmin``, the horizontal distance to its footprint. Returns the box indices
    1..n-1 sorted by ``rmin``; a box around the sensor gets an empty azimuth interval."""
    c0, s0 = math.cos(syaw), math.sin(syaw)
    for j in range(n):
        cj, sj = math.cos(byaw[j]), math.sin(byaw[j])
        a_lo, a_hi = np.inf, -np.inf
        r_max = 0.0
        for cx_ in range(2):
            for cy_ in range(2):
                lx = (bl[j] / 2) * (1 if cx_ else -1)
                ly = (bw[j] / 2) * (1 if cy_ else -1)
                wx = bx[j] + cj * lx - sj * ly - sx
                wy = by[j] + sj * lx + cj * ly - sy
                fx = c0 * wx + s0 * wy
                fy = -s0 * wx + c0 * wy
                a = math.atan2(fy, fx)
                a_lo = min(a_lo, a)
                a_hi = max(a_hi, a)
                r_max = max(r_max, math.hypot(fx, fy))
        # the sensor in the box's frame, and its distance to the footprint
        px, py = sx - bx[j], sy - by[j]
        lx = cj * px + sj * py
        ly = -sj * px + cj * py
        qx = max(abs(lx) - bl[j] / 2, 0.0)
        qy = max(abs(ly) - bw[j] / 2, 0.0)
        r_min = math.hypot(qx, qy)
        rmin[j] = r_min
        if a_hi - a_lo > math.pi:  # straddles ±π (behind the sensor): all azimuths
            a_lo, a_hi = -math.pi, math.pi
        if r_min == 0.0:  # the sensor stands inside the footprint
            a_lo, a_hi = 1.0, -1.0
        amin[j], amax[j] = a_lo, a_hi
        r_lo = max(r_min, 1e-6)
        emin[j] = math.atan2(0.0 - sz, r_lo if sz > 0.0 else r_max)
        emax[j] = math.atan2(bh[j] - sz, r_lo if bh[j] > sz else r_max)
    return np.argsort(rmin[1:n]) + 1


@njit(cache=True, nogil=True)
def lidar_detect(n, bx, by, byaw, bl, bw, bh, ex, ey, eyaw, sz, elev, az_cos, az_sin, rng_max, key, tick, alpha,
                 beta_ratio, table_i, table_r, drop_general, drop_limit, drop_zero, max_rays, count, centroid, terms,
                 frame, weights, ramp, weights5, ramp5, beta_max, last=False):  # fmt: skip
    """Surviving LiDAR returns per vehicle (``count``, scaled by the stride) and their centroid in the sensor frame
    (``centroid`` (V, 3)), for a LiDAR at height ``sz`` above the ego origin (ex, ey) with the ego's yaw. ``terms``
    (rows, 8): a packed fog field laid at ``frame`` = (x0, y0, heading) (:func:`fog_gym.fog.lidar_field.field_keeps`
    decides with ``weights`` … ``beta_max``); no rows: homogeneous fog of extinction ``alpha``. ``last``: a return
    counts when the hard target reaches the detection floor (a last-return LiDAR, :mod:`fog_gym.fog.returns`),
    instead of when it is the strongest echo."""
    amin = np.empty(n)
    amax = np.empty(n)
    emin = np.empty(n)
    emax = np.empty(n)
    rmin = np.empty(n)
    order = angular_extents(n, bx, by, byaw, bl, bw, bh, ex, ey, sz, eyaw, amin, amax, emin, emax, rmin)
    box = box_table(n, bx, by, byaw, bl, bw, bh, amin, amax, emin, emax, rmin)
    c0, s0 = math.cos(eyaw), math.sin(eyaw)
    n_el = elev.shape[0]
    n_az = az_cos.shape[0]
    step = 2.0 * math.pi / n_az
    field = terms.shape[0] > 0
    fh, gh = math.cos(frame[2]), math.sin(frame[2])  # the field's axis u
    u0 = (ex - frame[0]) * fh + (ey - frame[1]) * gh
    for j in range(1, n):
        count[j] = 0.0
        centroid[j, 0] = centroid[j, 1] = centroid[j, 2] = 0.0
        if amin[j] > amax[j] or rmin[j] > rng_max:
            continue
        k0 = int(math.ceil((amin[j] + math.pi) / step))
        k1 = int(math.floor((amax[j] + math.pi) / step))
        c_lo = 0
        while c_lo < n_el and elev[c_lo] > emax[j]:
            c_lo += 1
        c_hi = n_el - 1
        while c_hi >= 0 and elev[c_hi] < emin[j]:
            c_hi -= 1
        if k1 < k0 or c_hi < c_lo:
            continue
        nk = k1 - k0 + 1
        nc = c_hi - c_lo + 1
        stride = max(1, int(math.ceil(math.sqrt(nk * nc / max_rays))))
        total = 0.0
        sx = sy = sz_ = 0.0
        for ci in range(c_lo, c_hi + 1, stride):
            ce, se = math.cos(elev[ci]), math.sin(elev[ci])
            for k in range(k0, k1 + 1, stride):
                a = k * step - math.pi
                fx, fy, fz = ce * az_cos[k % n_az], ce * az_sin[k % n_az], se
                dx = c0 * fx - s0 * fy
                dy = s0 * fx + c0 * fy
                if uniform(key, tick, 1, ci, k) < drop_general:
                    continue  # dropped before tracing (the draw does not depend on the hit: tested first, it saves
                    # the trace of the rays CARLA's general drop-off removes anyway)
                t, hit, _, _ = nearest(ex, ey, sz, dx, dy, fz, box, order, a, elev[ci], rng_max)
                if hit != j:
                    continue
                inten = math.exp(-0.004 * t)
                if inten <= drop_limit and uniform(key, tick, 2, ci, k) >= inten * drop_zero / drop_limit + 1 - drop_zero:
                    continue
                if field:
                    if last:
                        if not field_last_detected(t, inten, terms, u0, sz, dx * fh + dy * gh, fz):
                            continue
                    elif not field_keeps(t, inten, terms, u0, sz, dx * fh + dy * gh, fz, weights, ramp, weights5, ramp5,
                                         beta_max):  # fmt: skip
                        continue
                elif alpha > 0.0:
                    if last:
                        if not last_detected(t, inten, alpha):
                            continue
                    elif not hahner_keeps(t, inten, table_i, table_r, alpha, beta_ratio):
                        continue
                w = stride * stride
                total += w
                sx += w * fx * t
                sy += w * fy * t
                sz_ += w * fz * t
        count[j] = total
        if total > 0:
            centroid[j, 0], centroid[j, 1], centroid[j, 2] = sx / total, sy / total, sz_ / total


@njit(cache=True, inline="always")
def _luma(r, g, b):
    return 0.2126 * r + 0.7152 * g + 0.0722 * b


@njit(cache=True, nogil=True, inline="always")
def _pixel_luminance(t, hit, axis, sign, dx, dy, dz, ox, oy, oz, box, colors, sun, ambient, sun_int, grid, gx0,
                     gy0, res, surf_luma, ground_shade, sky_luma, alpha, terms, u_o, du):  # fmt: skip
    """Fogged luminance (0–255) seen along one ray and whether it hit anything but the sky (``box``: the
    :func:`box_table`, for the hit box's yaw); the transmittance is ``exp(−α·t)``, or with a fog field (``terms`` with
    rows) ``exp(−τ)`` along the ray from ``(u_o, oz)`` with run ``du`` along the field's axis."""
    if hit == -2:
        return sky_luma, False
    if hit == -1:
        wx, wy = ox + t * dx, oy + t * dy
        col = int(math.floor((wx - gx0) / res))
        row = int(math.floor((wy - gy0) / res))
        cls = grid[row, col] if 0 <= row < grid.shape[0] and 0 <= col < grid.shape[1] else 0
        j_l = surf_luma[cls] * ground_shade
    else:
        c, s = box[hit, BCOS], box[hit, BSIN]
        if axis == 2:
            nx, ny, nz = 0.0, 0.0, sign
        elif axis == 0:
            nx, ny, nz = c * sign, s * sign, 0.0
        else:
            nx, ny, nz = -s * sign, c * sign, 0.0
        lam = nx * sun[0] + ny * sun[1] + nz * sun[2]
        shade = ambient + sun_int * max(lam, 0.0)
        j_l = _luma(colors[hit, 0], colors[hit, 1], colors[hit, 2]) * 255.0 * shade
    tr = math.exp(-(segment_depth(terms, u_o, oz, du, dz, t) if terms.shape[0] > 0 else alpha * t))
    return j_l * tr + sky_luma * (1.0 - tr), True


@njit(cache=True, nogil=True)
def camera_detect(n, bx, by, byaw, bl, bw, bh, colors, ex, ey, eyaw, cam_x, cam_z, fx_, width, height, alpha, sun,
                  ambient, sun_int, ground_shade, sky_luma, grid, gx0, gy0, res, surf_luma, max_rays, rng_max,
                  pixels, contrast, bearing, size_px, terms, frame):  # fmt: skip
    """Per vehicle: visible pixels (scaled by the stride), Weber contrast in the fogged image against its background,
    bearing of its visible pixels (radians, + right) and its visible box height in pixels, for a camera
    ``cam_x`` ahead of the ego origin at height ``cam_z`` looking along the ego's heading (pinhole, focal ``fx_``,
    ``width`` × ``height`` pixels, principal point at the centre)."""
    c0, s0 = math.cos(eyaw), math.sin(eyaw)
    ox, oy, oz = ex + c0 * cam_x, ey + s0 * cam_x, cam_z
    fh, gh = math.cos(frame[2]), math.sin(frame[2])  # a fog field's axis u (terms with rows)
    u_o = (ox - frame[0]) * fh + (oy - frame[1]) * gh
    amin = np.empty(n)
    amax = np.empty(n)
    emin = np.empty(n)
    emax = np.empty(n)
    rmin = np.empty(n)
    order = angular_extents(n, bx, by, byaw, bl, bw, bh, ox, oy, oz, eyaw, amin, amax, emin, emax, rmin)
    box = box_table(n, bx, by, byaw, bl, bw, bh, amin, amax, emin, emax, rmin)
    cx, cy = width / 2.0, height / 2.0
    for j in range(1, n):
        pixels[j] = 0.0
        contrast[j] = 0.0
        bearing[j] = 0.0
        size_px[j] = 0.0
        if amin[j] > amax[j] or rmin[j] > rng_max or amax[j] < -math.pi / 2 or amin[j] > math.pi / 2:
            continue
        # the box's image rectangle: u = cx + fx tan(az), v = cy − fx tan(el) / cos(az) (conservative)
        if amin[j] <= -1.5 or amax[j] >= 1.5:
            continue
        u0 = int(math.floor(cx + fx_ * math.tan(amin[j])))
        u1 = int(math.floor(cx + fx_ * math.tan(amax[j])))
        c_lo = min(math.cos(amin[j]), math.cos(amax[j]))
        c_hi = 1.0 if amin[j] <= 0.0 <= amax[j] else max(math.cos(amin[j]), math.cos(amax[j]))
        top, bottom = math.tan(emax[j]), math.tan(emin[j])
        v0 = int(math.floor(cy - fx_ * max(top / c_lo, top / c_hi)))
        v1 = int(math.floor(cy - fx_ * min(bottom / c_lo, bottom / c_hi)))
        u0, u1 = max(u0, 0), min(u1, width - 1)
        v0, v1 = max(v0, 0), min(v1, height - 1)
        if u1 < u0 or v1 < v0:
            continue
        nu, nv = u1 - u0 + 1, v1 - v0 + 1
        stride = max(1, int(math.ceil(math.sqrt(nu * nv / max_rays))))
        vis = 0.0
        lum_v = 0.0
        lum_b = 0.0
        bear = 0.0
        rows_lo, rows_hi = height, -1
        for v in range(v0, v1 + 1, stride):
            for u in range(u0, u1 + 1, stride):
                dfx = 1.0
                dfy = (u + 0.5 - cx) / fx_
                dfz = -(v + 0.5 - cy) / fx_
                norm = math.sqrt(dfx * dfx + dfy * dfy + dfz * dfz)
                dfx, dfy, dfz = dfx / norm, dfy / norm, dfz / norm
                dx = c0 * dfx - s0 * dfy
                dy = s0 * dfx + c0 * dfy
                az = math.atan2(dfy, dfx)
                el = math.asin(dfz)
                t, hit, axis, sign = nearest(ox, oy, oz, dx, dy, dfz, box, order, az, el, 1e4)
                if hit != j:
                    continue
                du = dx * fh + dy * gh
                lum, _ = _pixel_luminance(t, hit, axis, sign, dx, dy, dfz, ox, oy, oz, box, colors, sun, ambient,
                                          sun_int, grid, gx0, gy0, res, surf_luma, ground_shade, sky_luma, alpha, terms,
                                          u_o, du)  # fmt: skip
                # what the same pixel shows without the vehicle: its background, fogged
                box[j, AMIN], box[j, AMAX] = 1.0, -1.0
                tb, hb, axb, sgb = nearest(ox, oy, oz, dx, dy, dfz, box, order, az, el, 1e4)
                box[j, AMIN], box[j, AMAX] = amin[j], amax[j]
                lum_bg, _ = _pixel_luminance(tb, hb, axb, sgb, dx, dy, dfz, ox, oy, oz, box, colors, sun, ambient,
                                             sun_int, grid, gx0, gy0, res, surf_luma, ground_shade, sky_luma, alpha,
                                             terms, u_o, du)  # fmt: skip
                w = stride * stride
                vis += w
                lum_v += w * lum
                lum_b += w * lum_bg
                bear += w * az
                rows_lo = min(rows_lo, v)
                rows_hi = max(rows_hi, v)
        pixels[j] = vis
        if vis > 0:
            lb = max(lum_b / vis, 1e-6)
            contrast[j] = (lum_v / vis - lb) / lb
            bearing[j] = bear / vis
            size_px[j] = rows_hi - rows_lo + stride


@njit(cache=True, nogil=True)
def radar_detect(n, bx, by, byaw, bl, bw, bh, vx, vy, ex, ey, eyaw, evx, evy, rad_x, rad_z, rng_max, hfov, vfov,
                 rays, key, tick, hits, rng_sum, az_sum, vr_sum):  # fmt: skip
    """CARLA radar rays (``rays`` per tick, hashed directions in the elliptic FOV cone) from ``rad_x`` ahead of the ego
    origin at height ``rad_z``: per vehicle the number of detections and the sums of their range, azimuth (sensor
    frame, + right) and radial velocity (negative = approaching)."""
    c0, s0 = math.cos(eyaw), math.sin(eyaw)
    ox, oy, oz = ex + c0 * rad_x, ey + s0 * rad_x, rad_z
    amin = np.empty(n)
    amax = np.empty(n)
    emin = np.empty(n)
    emax = np.empty(n)
    rmin = np.empty(n)
    order = angular_extents(n, bx, by, byaw, bl, bw, bh, ox, oy, oz, eyaw, amin, amax, emin, emax, rmin)
    for j in range(n):
        hits[j] = 0.0
        rng_sum[j] = az_sum[j] = vr_sum[j] = 0.0
    max_rx = math.tan(hfov / 2.0) * rng_max
    max_ry = math.tan(vfov / 2.0) * rng_max
    # the boxes a forward ray can reach, with their extents as tangents (monotone in the angles: no atan per ray)
    cand = np.empty(n, np.int64)
    ta_lo, ta_hi, te_lo, te_hi = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    m = 0
    for q in range(order.shape[0]):
        j = order[q]
        if rmin[j] > rng_max or amin[j] > amax[j] or amin[j] <= -1.5 or amax[j] >= 1.5:
            continue
        cand[m] = j
        ta_lo[m], ta_hi[m] = math.tan(amin[j]), math.tan(amax[j])
        te_lo[m], te_hi[m] = math.tan(emin[j]), math.tan(emax[j])
        m += 1
    base = np.uint64(_splitmix(_splitmix(np.uint64(key)) ^ np.uint64(tick)) ^ np.uint64(RADAR_KEY))
    for i in range(rays):
        h = _splitmix(base + np.uint64(i))
        r = (h >> np.uint64(32)) * (1.0 / 4294967296.0)
        th = 2.0 * math.pi * ((h & np.uint64(0xFFFFFFFF)) * (1.0 / 4294967296.0))
        ax, ay, az_ = rng_max, max_rx * r * math.cos(th), max_ry * r * math.sin(th)
        horiz = math.sqrt(ax * ax + ay * ay)
        length = math.sqrt(horiz * horiz + az_ * az_)
        tan_a = ay / ax
        tan_e = az_ / horiz
        fx, fy, fz = ax / length, ay / length, az_ / length
        dx = c0 * fx - s0 * fy
        dy = s0 * fx + c0 * fy
        best_t = length
        best = -2
        if fz < 0.0:
            tg = -oz / fz
            if tg < best_t:
                best_t = tg
                best = -1
        for q in range(m):
            j = cand[q]
            if rmin[j] >= best_t:
                break
            if tan_a < ta_lo[q] or tan_a > ta_hi[q] or tan_e < te_lo[q] or tan_e > te_hi[q]:
                continue
            tj, _, _ = ray_box(ox, oy, oz, dx, dy, fz, bx[j], by[j], byaw[j], bl[j] / 2, bw[j] / 2, bh[j])
            if tj < best_t:
                best_t = tj
                best = j
        if best < 1:
            continue
        hits[best] += 1.0
        rng_sum[best] += best_t
        az_sum[best] += math.atan2(fy, fx)
        vr_sum[best] += (vx[best] - evx) * dx + (vy[best] - evy) * dy
