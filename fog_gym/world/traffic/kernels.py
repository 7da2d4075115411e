"""highway-env's straight-road traffic as numba kernels over (worlds × vehicles) arrays: no Python per vehicle.

One call of :func:`step_worlds` advances every active world by one policy step: the ego's meta-action, then
``frames`` sub-steps of highway-env 1.12.1's ``Road.act`` (the ego's cruise and lane controllers, IDM/MOBIL for
the traffic, nothing for stalled vehicles), ``Road.step`` (the kinematic bicycle model, the closest-lane update)
and the collision loop (spherical pre-check, then the separating-axis polygon test with its impact transition),
in highway-env's vehicle order and operation order, for the road highway-env builds for ``HighwayEnv``: ``lanes``
parallel straight lanes from (0, 4 i) to (10 000, 4 i), 4 m wide, speed limit 30 m/s. Then it computes the
highway reward terms. State lives in :class:`fog_gym.world.traffic.native.NativeTraffic`'s arrays; the column
meaning is in its docstring.

Arithmetic follows highway-env's order; transcendental functions are the C library's, where highway-env's numpy
may use other last-bit rounding (and its 2-vector ``np.dot`` BLAS's, with or without FMA), so trajectories agree
to ≤ 1e-9 m with identical decisions rather than bit for bit (``tests/world/test_native_traffic.py``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)

# vehicle kinds
EGO, IDM, STALLED = 0, 1, 2
# meta-actions (highway-env's DiscreteMetaAction.ACTIONS_ALL)
LANE_LEFT, IDLE, LANE_RIGHT, FASTER, SLOWER = 0, 1, 2, 3, 4

LANE_WIDTH = 4.0
LANE_LENGTH = 10000.0
SPEED_LIMIT = 30.0
VEHICLE_LENGTH = 5.0  # AbstractLane.VEHICLE_LENGTH
MAX_SPEED, MIN_SPEED = 40.0, -40.0
# ControlledVehicle
TAU_ACC, TAU_HEADING, TAU_LATERAL = 0.6, 0.2, 0.6
TAU_PURSUIT = 0.5 * TAU_HEADING
KP_A, KP_HEADING, KP_LATERAL = 1 / TAU_ACC, 1 / TAU_HEADING, 1 / TAU_LATERAL
MAX_STEERING_ANGLE = np.pi / 3
# IDMVehicle (the class constants fog-gym's default IDM profile sets; highway-env's defaults besides)
TIME_WANTED = 1.5
POLITENESS = 0.0
LANE_CHANGE_MIN_ACC_GAIN = 0.2
LANE_CHANGE_MAX_BRAKING_IMPOSED = 2.0
LANE_CHANGE_DELAY = 1.0
ACC_MAX = 6.0
_PI = np.pi
_TWO_PI = 2 * np.pi
_QUARTER_PI = np.pi / 4

# float state columns (F, …) and int state columns (I, …): see NativeTraffic
FX, FY, FH, FS, FTS, FTIMER, FDELTA, FLEN, FWID, FDIAG, FIMPX, FIMPY, FSTEER, FACC = range(14)
N_FLOAT = 14
IKIND, ILANE, ITLANE, ICRASH, IIMPACT, IHASTS, ISPEEDIDX = range(7)
N_INT = 7


@njit(cache=True, inline="always")
def _clip(x, lo, hi):
    if x < lo:
        x = lo
    if x > hi:
        x = hi
    return x


@njit(cache=True, inline="always")
def _nz(x):
    if abs(x) > 1e-2:
        return x
    if x >= 0:
        return 1e-2
    return -1e-2


@njit(cache=True, inline="always")
def _wrap(x):
    return ((x + _PI) % _TWO_PI) - _PI


@njit(cache=True, inline="always")
def _lane_y(i):
    return i * LANE_WIDTH


@njit(cache=True, nogil=True)
def closest_lane(x, y, h, lanes):
    """``RoadNetwork.get_closest_lane_index``: the first lane of least ``|r| + max(s − L, 0) + max(−s, 0) + |angle|``."""
    best = 0
    best_d = 0.0
    angle = abs(_wrap(h - 0.0))
    for i in range(lanes):
        r = y - _lane_y(i)
        d = abs(r) + max(x - LANE_LENGTH, 0.0) + max(0.0 - x, 0.0) + 1.0 * angle
        if i == 0 or d < best_d:
            best = i
            best_d = d
    return best


@njit(cache=True, inline="always")
def _on_lane_margin1(x, y, i):
    lat = y - _lane_y(i)
    return abs(lat) <= LANE_WIDTH / 2 + 1 and -VEHICLE_LENGTH <= x and x < LANE_LENGTH + VEHICLE_LENGTH


@njit(cache=True, inline="always")
def _reachable(x, y, i):
    lat = y - _lane_y(i)
    return abs(lat) <= 2 * LANE_WIDTH and 0 <= x and x < LANE_LENGTH + VEHICLE_LENGTH


@njit(cache=True, nogil=True)
def neighbours(f, it, n, k, lane):
    """``Road.neighbour_vehicles(vehicle k, lane)``: (front, rear) slot indices, −1 for none."""
    s = f[k, FX]
    s_front = 0.0
    s_rear = 0.0
    front = -1
    rear = -1
    for j in range(n):
        if j == k:
            continue
        s_v = f[j, FX]
        if not _on_lane_margin1(s_v, f[j, FY], lane):
            continue
        if s <= s_v and (front < 0 or s_v <= s_front):
            s_front = s_v
            front = j
        if s_v < s and (rear < 0 or s_v > s_rear):
            s_rear = s_v
            rear = j
    return front, rear


@njit(cache=True, nogil=True)
def desired_gap(f, d0, cam, cmin, e, fr):
    """``IDMVehicle.desired_gap(ego e, front fr)`` (projected), with the caller's class constants."""
    ab = -cam * cmin
    ce = math.cos(f[e, FH])
    se = math.sin(f[e, FH])
    cf = math.cos(f[fr, FH])
    sf = math.sin(f[fr, FH])
    spe = f[e, FS]
    dvx = spe * ce - f[fr, FS] * cf
    dvy = spe * se - f[fr, FS] * sf
    dv = dvx * ce + dvy * se
    return d0 + spe * TIME_WANTED + spe * dv / (2 * math.sqrt(ab))


@njit(cache=True, nogil=True)
def idm_acceleration(f, it, delta, d0, cam, cmin, e, fr):
    """``IDMVehicle.acceleration`` of a vehicle with exponent ``delta`` for ego ``e`` behind ``fr`` (−1: none)."""
    if e < 0:
        return 0.0
    ts = f[e, FTS] if it[e, IHASTS] else 0.0
    ts = _clip(ts, 0.0, SPEED_LIMIT)
    acc = cam * (1 - (max(f[e, FS], 0.0) / abs(_nz(ts))) ** delta)
    if fr >= 0:
        d = f[fr, FX] - f[e, FX]
        acc -= cam * (desired_gap(f, d0, cam, cmin, e, fr) / _nz(d)) ** 2
    return acc


@njit(cache=True, nogil=True)
def steering_control(f, k, target_lane):
    """``ControlledVehicle.steering_control(target_lane)`` on a straight lane of heading 0."""
    sp = f[k, FS]
    lat = f[k, FY] - _lane_y(target_lane)
    lateral_speed_command = -KP_LATERAL * lat
    nzs = _nz(sp)
    heading_command = math.asin(_clip(lateral_speed_command / nzs, -1.0, 1.0))
    heading_ref = 0.0 + _clip(heading_command, -_QUARTER_PI, _QUARTER_PI)
    heading_rate_command = KP_HEADING * _wrap(heading_ref - f[k, FH])
    slip_angle = math.asin(_clip(f[k, FLEN] / 2 / nzs * heading_rate_command, -1.0, 1.0))
    steering = math.atan(2 * math.tan(slip_angle))
    return _clip(steering, -MAX_STEERING_ANGLE, MAX_STEERING_ANGLE)


@njit(cache=True, nogil=True)
def _mobil(f, it, n, k, lane, d0, cam, cmin):
    delta = f[k, FDELTA]
    new_pre, new_fol = neighbours(f, it, n, k, lane)
    new_following_a = idm_acceleration(f, it, delta, d0, cam, cmin, new_fol, new_pre)
    new_following_pred_a = idm_acceleration(f, it, delta, d0, cam, cmin, new_fol, k)
    if new_following_pred_a < -LANE_CHANGE_MAX_BRAKING_IMPOSED:
        return False
    old_pre, old_fol = neighbours(f, it, n, k, it[k, ILANE])
    self_pred_a = idm_acceleration(f, it, delta, d0, cam, cmin, k, new_pre)
    self_a = idm_acceleration(f, it, delta, d0, cam, cmin, k, old_pre)
    old_following_a = idm_acceleration(f, it, delta, d0, cam, cmin, old_fol, k)
    old_following_pred_a = idm_acceleration(f, it, delta, d0, cam, cmin, old_fol, old_pre)
    jerk = self_pred_a - self_a + POLITENESS * (
        new_following_pred_a - new_following_a + old_following_pred_a - old_following_a
    )
    if jerk < LANE_CHANGE_MIN_ACC_GAIN:
        return False
    return True


@njit(cache=True, nogil=True)
def _idm_act(f, it, n, k, lanes, d0, cam, cmin):
    """``IDMVehicle.act`` (follow_road never triggers on a 10 km lane)."""
    if it[k, ICRASH]:
        return
    # change_lane_policy
    if it[k, ILANE] != it[k, ITLANE]:
        target = it[k, ITLANE]
        for j in range(n):
            if j != k and it[j, ILANE] != target and it[j, IKIND] != STALLED and it[j, ITLANE] == target:
                d = f[j, FX] - f[k, FX]
                d_star = desired_gap(f, d0, cam, cmin, k, j)
                if 0 < d and d < d_star:
                    it[k, ITLANE] = it[k, ILANE]
                    break
    elif LANE_CHANGE_DELAY < f[k, FTIMER]:
        f[k, FTIMER] = 0.0
        li = it[k, ILANE]
        for side in range(2):
            cand = li - 1 if side == 0 else li + 1
            if cand < 0 or cand > lanes - 1:
                continue
            if not _reachable(f[k, FX], f[k, FY], cand):
                continue
            if abs(f[k, FS]) < 1:
                continue
            if _mobil(f, it, n, k, cand, d0, cam, cmin):
                it[k, ITLANE] = cand
    steer = steering_control(f, k, it[k, ITLANE])
    steer = _clip(steer, -MAX_STEERING_ANGLE, MAX_STEERING_ANGLE)
    delta = f[k, FDELTA]
    front, _ = neighbours(f, it, n, k, it[k, ILANE])
    acc = idm_acceleration(f, it, delta, d0, cam, cmin, k, front)
    if it[k, ILANE] != it[k, ITLANE]:
        front, _ = neighbours(f, it, n, k, it[k, ITLANE])
        target_acc = idm_acceleration(f, it, delta, d0, cam, cmin, k, front)
        acc = min(acc, target_acc)
    f[k, FSTEER] = steer
    f[k, FACC] = _clip(acc, -ACC_MAX, ACC_MAX)


@njit(cache=True, nogil=True)
def _ego_act(f, it, k):
    """``ControlledVehicle.act()``: heading control to the target lane, speed control to the target speed."""
    steer = steering_control(f, k, it[k, ITLANE])
    f[k, FSTEER] = _clip(steer, -MAX_STEERING_ANGLE, MAX_STEERING_ANGLE)
    f[k, FACC] = KP_A * (f[k, FTS] - f[k, FS])


@njit(cache=True, nogil=True)
def speed_to_index(speed, speeds, m):
    """``MDPVehicle.speed_to_index``: the nearest allowed speed's index (numpy's half-to-even rounding)."""
    x = (speed - speeds[0]) / (speeds[m - 1] - speeds[0])
    return int(_clip(np.round(x * (m - 1)), 0, m - 1))


@njit(cache=True, nogil=True)
def _meta(f, it, k, action, lanes, speeds, m):
    """``MDPVehicle.act(meta-action)``: the target speed index or the target lane."""
    if action == FASTER or action == SLOWER:
        idx = speed_to_index(f[k, FS], speeds, m) + (1 if action == FASTER else -1)
        idx = int(_clip(idx, 0, m - 1))
        it[k, ISPEEDIDX] = idx
        f[k, FTS] = speeds[idx]
    elif action == LANE_RIGHT or action == LANE_LEFT:
        cand = it[k, ITLANE] + (1 if action == LANE_RIGHT else -1)
        cand = int(_clip(cand, 0, lanes - 1))
        if _reachable(f[k, FX], f[k, FY], cand):
            it[k, ITLANE] = cand


@njit(cache=True, nogil=True)
def _kinematics(f, it, k, dt, lanes):
    """``Vehicle.step(dt)`` (``IDMVehicle.step``: the timer first)."""
    if it[k, IKIND] == IDM:
        f[k, FTIMER] += dt
    sp = f[k, FS]
    if it[k, ICRASH]:
        f[k, FSTEER] = 0.0
        f[k, FACC] = -1.0 * sp
    acc = f[k, FACC]
    if sp > MAX_SPEED:
        acc = min(acc, 1.0 * (MAX_SPEED - sp))
    elif sp < MIN_SPEED:
        acc = max(acc, 1.0 * (MIN_SPEED - sp))
    f[k, FACC] = acc
    beta = math.atan(1 / 2 * math.tan(f[k, FSTEER]))
    h = f[k, FH]
    f[k, FX] = f[k, FX] + sp * math.cos(h + beta) * dt
    f[k, FY] = f[k, FY] + sp * math.sin(h + beta) * dt
    if it[k, IIMPACT]:
        f[k, FX] = f[k, FX] + f[k, FIMPX]
        f[k, FY] = f[k, FY] + f[k, FIMPY]
        it[k, ICRASH] = 1
        it[k, IIMPACT] = 0
    f[k, FH] = h + sp * math.sin(beta) / (f[k, FLEN] / 2) * dt
    f[k, FS] = sp + acc * dt
    it[k, ILANE] = closest_lane(f[k, FX], f[k, FY], f[k, FH], lanes)


@njit(cache=True, nogil=True)
def _polygon(f, k, out):
    """``RoadObject.polygon()``: the 4 corners (and the first again) of vehicle k's rectangle."""
    hl = f[k, FLEN] / 2
    hw = f[k, FWID] / 2
    c = math.cos(f[k, FH])
    s = math.sin(f[k, FH])
    px = (-hl, -hl, hl, hl)
    py = (-hw, hw, hw, -hw)
    for i in range(4):
        out[i, 0] = c * px[i] + -s * py[i] + f[k, FX]
        out[i, 1] = s * px[i] + c * py[i] + f[k, FY]
    out[4, 0] = out[0, 0]
    out[4, 1] = out[0, 1]


@njit(cache=True, nogil=True)
def _project(poly, nx, ny):
    lo = poly[0, 0] * nx + poly[0, 1] * ny
    hi = lo
    for i in range(1, 5):
        p = poly[i, 0] * nx + poly[i, 1] * ny
        if p < lo:
            lo = p
        if p > hi:
            hi = p
    return lo, hi


@njit(cache=True, inline="always")
def _interval_distance(min_a, max_a, min_b, max_b):
    return min_b - max_a if min_a < min_b else min_a - max_b


@njit(cache=True, nogil=True)
def polygons_intersecting(a, b, dax, day, dbx, dby):
    """``utils.are_polygons_intersecting``: (intersecting, will intersect, translation x, translation y)."""
    intersecting = True
    will = True
    min_distance = np.inf
    tx = 0.0
    ty = 0.0
    for which in range(2):
        poly = a if which == 0 else b
        for e in range(4):
            nx = -poly[e + 1, 1] + poly[e, 1]
            ny = poly[e + 1, 0] - poly[e, 0]
            norm = math.sqrt(nx * nx + ny * ny)
            nx /= norm
            ny /= norm
            min_a, max_a = _project(a, nx, ny)
            min_b, max_b = _project(b, nx, ny)
            if _interval_distance(min_a, max_a, min_b, max_b) > 0:
                intersecting = False
            vp = nx * (dax - dbx) + ny * (day - dby)
            if vp < 0:
                min_a += vp
            else:
                max_a += vp
            distance = _interval_distance(min_a, max_a, min_b, max_b)
            if distance > 0:
                will = False
            if not intersecting and not will:
                break
            if abs(distance) < min_distance:
                min_distance = abs(distance)
                dx = (a[0, 0] + a[1, 0] + a[2, 0] + a[3, 0]) / 4 - (b[0, 0] + b[1, 0] + b[2, 0] + b[3, 0]) / 4
                dy = (a[0, 1] + a[1, 1] + a[2, 1] + a[3, 1]) / 4 - (b[0, 1] + b[1, 1] + b[2, 1] + b[3, 1]) / 4
                if dx * nx + dy * ny > 0:
                    tx, ty = nx, ny
                else:
                    tx, ty = -nx, -ny
    if will:
        return intersecting, will, min_distance * tx, min_distance * ty
    return intersecting, will, 0.0, 0.0


@njit(cache=True, nogil=True)
def _collide(f, it, n, dt, pa, pb):
    """``Road.step``'s collision loop: every pair (i < j) through ``RoadObject.handle_collisions``."""
    for i in range(n):
        for j in range(i + 1, n):
            dx = f[j, FX] - f[i, FX]
            dy = f[j, FY] - f[i, FY]
            if math.sqrt(dx * dx + dy * dy) > (f[i, FDIAG] + f[j, FDIAG]) / 2 + f[i, FS] * dt:
                continue
            _polygon(f, i, pa)
            _polygon(f, j, pb)
            ci, si = math.cos(f[i, FH]), math.sin(f[i, FH])
            cj, sj = math.cos(f[j, FH]), math.sin(f[j, FH])
            inter, will, tx, ty = polygons_intersecting(pa, pb, f[i, FS] * ci * dt, f[i, FS] * si * dt,
                                                        f[j, FS] * cj * dt, f[j, FS] * sj * dt)  # fmt: skip
            if will:
                f[i, FIMPX] = tx / 2
                f[i, FIMPY] = ty / 2
                it[i, IIMPACT] = 1
                f[j, FIMPX] = -tx / 2
                f[j, FIMPY] = -ty / 2
                it[j, IIMPACT] = 1
            if inter:
                it[i, ICRASH] = 1
                it[j, ICRASH] = 1


@njit(cache=True, nogil=True)
def step_world(f, it, n, action, frames, dt, lanes, speeds, m, d0, cam, cmin):
    """One policy step of one world: the ego's meta-action, then ``frames`` sub-steps of act, step, collisions."""
    pa = np.empty((5, 2))
    pb = np.empty((5, 2))
    for frame in range(frames):
        if frame == 0:
            _meta(f, it, 0, action, lanes, speeds, m)
        for k in range(n):  # Road.act, in road order (the ego is slot 0)
            kind = it[k, IKIND]
            if kind == EGO:
                _ego_act(f, it, k)
            elif kind == IDM:
                _idm_act(f, it, n, k, lanes, d0, cam, cmin)
        for k in range(n):  # Road.step
            _kinematics(f, it, k, dt, lanes)
        _collide(f, it, n, dt, pa, pb)


@njit(cache=True, nogil=True, parallel=True)
def step_worlds(active, floats, ints, counts, actions, frames, dt, lanes, speeds, m, d0, cam, cmin):
    """:func:`step_world` for every active world (``active[w]``), in parallel over worlds."""
    for w in prange(floats.shape[0]):
        if active[w]:
            step_world(floats[w], ints[w], counts[w], actions[w], frames, dt, lanes, speeds, m, d0, cam, cmin)


@njit(cache=True, nogil=True)
def highway_rewards(f, it, lanes, out):
    """highway-env's ``HighwayEnv._rewards`` of the ego (slot 0): collision, right lane, high speed (the forward
    speed scaled by ``out``'s first two entries, the reward speed range, and clipped to [0, 1]) and on-road."""
    lo, hi = out[0], out[1]
    forward_speed = f[0, FS] * math.cos(f[0, FH])
    scaled = 0 + (forward_speed - lo) * (1 - 0) / (hi - lo)
    lat = f[0, FY] - _lane_y(it[0, ILANE])
    on_road = abs(lat) <= LANE_WIDTH / 2 + 0 and -VEHICLE_LENGTH <= f[0, FX] and f[0, FX] < LANE_LENGTH + VEHICLE_LENGTH
    out[2] = float(it[0, ICRASH])
    out[3] = it[0, ITLANE] / max(lanes - 1, 1)
    out[4] = _clip(scaled, 0.0, 1.0)
    out[5] = 1.0 if on_road else 0.0
