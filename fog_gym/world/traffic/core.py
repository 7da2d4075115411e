"""highway-env's neighbour search and collision pre-check over structure-of-arrays, per road instance.

highway-env 1.12.1 spends most of a traffic step in two O(N²) Python loops:

* ``Road.neighbour_vehicles`` — every vehicle asks, for its own lane and for each MOBIL candidate lane,
  which vehicle is ahead and behind; each query projects *all* vehicles on the lane.
* ``Road.step``'s collision loop — every pair of vehicles (and every vehicle–object pair) runs
  ``handle_collisions``, whose first test is a spherical distance pre-check.

This module keeps highway-env's ``Vehicle`` objects as the source of truth and replaces only those loops:

* During ``Road.act`` no position changes, so each lane's projection of every road entity
  (``lane.local_coordinates`` and ``lane.on_lane(..., margin=1)``, highway-env's own scalar functions, hence
  the very same floats) is computed once per lane and cached as arrays; each query is then a masked
  arg-min/arg-max over those arrays with highway-env's tie rules (front: the *last* entity at the smallest
  ``s_v >= s``; rear: the *first* entity at the largest ``s_v < s``).
* Collisions: the spherical pre-check runs vectorised over all pairs with a small safety margin; only the
  surviving pairs call highway-env's own ``handle_collisions`` — in the original (i, j) order, so impacts,
  ``crashed`` and ``hit`` flags come out identical. Pairs the pre-check rejects have no side effect in
  highway-env either.

The per-vehicle Python that remains (IDM/MOBIL ``act``, ``Vehicle.step``, the closest-lane update) is
restated exactly in :mod:`fog_gym.world.traffic.vehicles` for the vehicles whose class uses highway-env's own methods;
other vehicles keep theirs. Spawning, removal, road rules and every random draw stay highway-env's, so seeds
mean the same thing and trajectories equal the reference path. The replacement is installed as bound methods
on one env's ``road`` object (re-installed after every reset): no class is modified, and other highway-env
environments in the process behave exactly as before.

Why not numba here: the per-lane projections of unusual lanes must call highway-env's lane objects to be
bit-identical, and the remaining per-query work is a bisection in Python lists.
"""

from __future__ import annotations

import types
from bisect import bisect_left
from typing import Any

import numpy as np

#: highway-env classes ``accelerate`` accepts (by class name; subclasses are accepted too).
SUPPORTED_ENVS: tuple[str, ...] = (
    "HighwayEnv",
    "HighwayEnvFast",
    "MergeEnv",
    "RoundaboutEnv",
    "IntersectionEnv",
    "RacetrackEnv",
    "ExitEnv",
)

#: Extra metres added to the vectorised collision pre-check so rounding never rejects a pair that
#: highway-env's scalar pre-check would keep (the exact test still runs on every kept pair).
_PRECHECK_MARGIN = 1e-6


def _supported(unwrapped: Any) -> bool:
    from highway_env.envs.common.abstract import AbstractEnv

    if not isinstance(unwrapped, AbstractEnv):
        return False
    names = {c.__name__ for c in type(unwrapped).__mro__}
    return any(n in names for n in SUPPORTED_ENVS)


def is_accelerated(env: Any) -> bool:
    """Whether ``accelerate`` was applied to ``env`` (a gymnasium env or its unwrapped highway-env env)."""
    return bool(getattr(getattr(env, "unwrapped", env), "_fog_traffic_core", False))


def accelerate(env: Any) -> Any:
    """Install the traffic core on a highway-env environment, in place, and return it.

    Accepts what ``gym.make`` returns for highway-v0, highway-fast-v0, merge-v0, roundabout-v0,
    intersection-v0, racetrack-v0 and exit-v0 (or the bare env). Trajectories, rewards, terminations and
    random draws stay identical to highway-env's own path. Calling it again on the same env is a no-op.

    >>> import gymnasium as gym, highway_env  # doctest: +SKIP
    >>> env = accelerate(gym.make("highway-v0"))  # doctest: +SKIP

    Raises ``TypeError`` for anything that is not one of the supported highway-env environments.
    """
    unwrapped = getattr(env, "unwrapped", env)
    if not _supported(unwrapped):
        raise TypeError(
            "accelerate() needs a highway-env environment of one of the classes "
            f"{SUPPORTED_ENVS}, got {type(unwrapped).__name__}"
        )
    if getattr(unwrapped, "_fog_traffic_core", False):
        return env  # documented no-op
    original_reset = unwrapped._reset  # bound method of the class

    def _reset(self: Any) -> None:
        original_reset()
        install(self.road)

    unwrapped._reset = types.MethodType(_reset, unwrapped)
    unwrapped._fog_traffic_core = True
    if getattr(unwrapped, "road", None) is not None:
        install(unwrapped.road)
    return env


def install(road: Any) -> None:
    """Bind the fast ``act``, ``neighbour_vehicles`` and ``step`` on this one ``road`` instance."""
    from highway_env.road.regulation import RegulatedRoad
    from highway_env.road.road import Road

    if type(road) not in (Road, RegulatedRoad):
        return  # an unknown Road subclass keeps highway-env's path
    from fog_gym.world.traffic.vehicles import RoadFast

    road._fog_lane_cache = None
    road._fog_fast = RoadFast(road)
    road.act = types.MethodType(_act, road)
    road.neighbour_vehicles = types.MethodType(_neighbour_vehicles, road)
    road.step = types.MethodType(_regulated_step if type(road) is RegulatedRoad else _step, road)


# -- neighbour search ---------------------------------------------------------------------------------


def lane_cache(road: Any) -> dict:
    """A snapshot of ``road``'s entities for the per-lane projection cache (valid while no position changes)."""
    from highway_env.vehicle.objects import Landmark

    entities = road.vehicles + road.objects
    landmark = [isinstance(v, Landmark) for v in entities]
    return {
        "entities": entities,
        "index": {id(v): i for i, v in enumerate(entities)},
        "landmark": np.array(landmark, dtype=bool),
        "pos": np.array([v.position for v in entities], dtype=np.float64).reshape(len(entities), 2),
        "lanes": {},
        "sorted": {},
        "landmark_list": landmark,
    }


def _act(self: Any) -> None:
    """``Road.act`` with a per-call lane-projection cache (positions are frozen during act).

    Vehicles whose class runs highway-env's IDM/MOBIL unchanged act through
    :meth:`fog_gym.world.traffic.vehicles.RoadFast.act_all`; every other vehicle through its own ``act``, in order.
    """
    cache = self._fog_lane_cache = lane_cache(self)
    fast = self._fog_fast
    pos = cache["pos"]
    heading = np.array([e.heading for e in cache["entities"]], dtype=np.float64)
    fast.xy = dict(zip(cache["index"], zip(*pos.T.tolist(), np.cos(heading).tolist(), np.sin(heading).tolist())))
    try:
        fast.act_all(self.vehicles, self.neighbour_vehicles)
    finally:
        self._fog_lane_cache = None
        fast.xy = {}


def _lane_arrays(cache: dict, lane: Any) -> tuple[np.ndarray, np.ndarray]:
    key = id(lane)
    hit = cache["lanes"].get(key)
    if hit is not None and hit[0] is lane:
        return hit[1], hit[2]
    from highway_env.road.lane import StraightLane

    entities = cache["entities"]
    landmark = cache["landmark"]
    if type(lane) is StraightLane:
        s, on = straight_lane_projection(cache["pos"], lane.start, lane.direction, lane.direction_lateral,
                                         lane.width, lane.length, lane.VEHICLE_LENGTH)  # fmt: skip
        on &= ~landmark
        cache["lanes"][key] = (lane, s, on)
        return s, on
    n = len(entities)
    s = np.empty(n)
    on = np.zeros(n, dtype=bool)
    for i, v in enumerate(entities):
        if landmark[i]:
            continue
        s_v, lat_v = lane.local_coordinates(v.position)
        s[i] = s_v
        on[i] = bool(lane.on_lane(v.position, s_v, lat_v, margin=1))
    cache["lanes"][key] = (lane, s, on)
    return s, on


def straight_lane_projection(
    pos: np.ndarray,
    start: np.ndarray,
    direction: np.ndarray,
    direction_lateral: np.ndarray,
    width: float,
    length: float,
    vehicle_length: float,
    margin: float = 1.0,
) -> tuple[np.ndarray, np.ndarray]:
    """``StraightLane.local_coordinates`` and ``on_lane(margin=1)`` for (N, 2) positions, bit-identical.

    The 2-vector dot products are written out as ``dx * ux + dy * uy``, the same rounding as highway-env's
    ``np.dot`` on two-element vectors.

    >>> s, on = straight_lane_projection(np.array([[5.0, 1.0], [5.0, 4.0], [-10.0, 0.0]]), np.zeros(2),
    ...                                  np.array([1.0, 0.0]), np.array([0.0, 1.0]), 4.0, 100.0, 5.0)
    >>> s.tolist(), on.tolist()
    ([5.0, 5.0, -10.0], [True, False, False])
    """
    dx = pos[:, 0] - start[0]
    dy = pos[:, 1] - start[1]
    s = dx * direction[0] + dy * direction[1]
    lat = dx * direction_lateral[0] + dy * direction_lateral[1]
    on = (np.abs(lat) <= width / 2 + margin) & (-vehicle_length <= s) & (s < length + vehicle_length)
    return s, on


def _lane_sorted(cache: dict, lane: Any) -> tuple[list, list, list]:
    """Every entity's ``s`` on ``lane`` and the on-lane entities sorted by (s, index), as Python lists."""
    key = id(lane)
    hit = cache["sorted"].get(key)
    if hit is not None and hit[0] is lane:
        return hit[1], hit[2], hit[3]
    s, on = _lane_arrays(cache, lane)
    idx = np.flatnonzero(on)
    order = idx[np.lexsort((idx, s[idx]))]
    s_list = s.tolist()
    cache["sorted"][key] = (lane, s_list, s[order].tolist(), order.tolist())
    return s_list, cache["sorted"][key][2], cache["sorted"][key][3]


def _neighbour_vehicles(self: Any, vehicle: Any, lane_index: Any = None) -> tuple[Any, Any]:
    """``Road.neighbour_vehicles`` over cached, sorted per-lane projections; identical results and tie rules.

    highway-env scans every entity: the front vehicle is the *last* one at the smallest ``s_v >= s``, the rear
    one the *first* at the largest ``s_v < s``. Sorted by (s, entity index), both are a bisection away.
    """
    cache = self._fog_lane_cache
    if cache is None or self.neighbour_vehicles_connected_lanes:
        return type(self).neighbour_vehicles(self, vehicle, lane_index)
    lane_index = lane_index or vehicle.lane_index
    if not lane_index:
        return None, None
    lane = self._fog_fast.lane(lane_index)
    s_all, ss, ii = _lane_sorted(cache, lane)
    i_self = cache["index"].get(id(vehicle), -1)
    if i_self >= 0 and not cache["landmark_list"][i_self]:
        s = s_all[i_self]
    else:
        s = lane.local_coordinates(vehicle.position)[0]
    entities = cache["entities"]
    n = len(ss)
    k = pos = bisect_left(ss, s)
    while k < n and ii[k] == i_self:
        k += 1
    v_front = None
    if k < n:
        s_front = ss[k]
        best = ii[k]
        k += 1
        while k < n and ss[k] == s_front:  # equal s: highway-env keeps the last one
            if ii[k] != i_self:
                best = ii[k]
            k += 1
        v_front = entities[best]
    v_rear = None
    if pos > 0:
        k = pos - 1
        s_rear = ss[k]
        while k > 0 and ss[k - 1] == s_rear:  # equal s: highway-env keeps the first one
            k -= 1
        v_rear = entities[ii[k]]
    return v_front, v_rear


# -- collisions ---------------------------------------------------------------------------------------


def _collide(self: Any, dt: float) -> None:
    vehicles = self.vehicles
    objects = self.objects
    n = len(vehicles)
    if n == 0:
        return
    others = vehicles + objects
    m = len(others)
    pos = np.array([v.position for v in others], dtype=np.float64).reshape(m, 2)
    diag = np.array([v.diagonal for v in others], dtype=np.float64)
    speed = np.array([v.speed for v in vehicles], dtype=np.float64)
    d = np.sqrt(((pos[None, :, :] - pos[:n, None, :]) ** 2).sum(axis=-1))  # (n, m)
    reach = (diag[:n, None] + diag[None, :]) / 2 + speed[:, None] * dt + _PRECHECK_MARGIN
    keep = d <= reach
    cols = np.arange(m)[None, :]
    rows = np.arange(n)[:, None]
    keep &= (cols > rows) | (cols >= n)  # vehicles[i + 1:], then every object
    rows_kept, cols_kept = np.nonzero(keep)
    if len(rows_kept):
        apart = clearly_apart(others, rows_kept, cols_kept, dt)
        rows_kept, cols_kept = rows_kept[~apart], cols_kept[~apart]
    for i, j in zip(rows_kept.tolist(), cols_kept.tolist()):
        vehicles[i].handle_collisions(others[j], dt)


#: Separation [m] a pair's swept rectangles need along one of their axes before ``clearly_apart`` skips it:
#: far above the rounding of highway-env's polygon test, far below any gap that matters.
_SAT_MARGIN = 1e-5


def clearly_apart(entities: list, i: np.ndarray, j: np.ndarray, dt: float) -> np.ndarray:
    """Pairs (``entities[i]``, ``entities[j]``) that highway-env's polygon test finds neither intersecting nor
    about to intersect, because their rectangles (``i``'s swept by the relative displacement over ``dt``) are
    separated by more than ``_SAT_MARGIN`` along one of the four axes that test projects on.

    ``handle_collisions`` has no effect on such a pair, so skipping it changes nothing; a pair not found apart
    (or of a class with its own geometry or collision code) still goes to highway-env's test.

    >>> from highway_env.vehicle.kinematics import Vehicle
    >>> a = Vehicle(None, [0.0, 0.0], heading=0.0, speed=10.0)  # 5 m × 2 m
    >>> b = Vehicle(None, [0.0, 3.0], heading=0.0, speed=10.0)  # in the next lane
    >>> c = Vehicle(None, [5.4, 0.0], heading=0.0, speed=0.0)  # 0.4 m ahead, at rest: reached within dt
    >>> clearly_apart([a, b, c], np.array([0, 0]), np.array([1, 2]), 0.05).tolist()
    [True, False]
    """
    from fog_gym.world.traffic.vehicles import plain_geometry

    ok = np.array([plain_geometry(entities[a]) and plain_geometry(entities[b]) for a, b in zip(i.tolist(), j.tolist())])
    ents = entities
    pos = np.array([e.position for e in ents], dtype=np.float64).reshape(len(ents), 2)
    heading = np.array([e.heading for e in ents], dtype=np.float64)
    half = np.array([(e.LENGTH / 2, e.WIDTH / 2) for e in ents], dtype=np.float64).reshape(len(ents), 2)
    speed = np.array([e.speed for e in ents], dtype=np.float64)
    c, s = np.cos(heading), np.sin(heading)
    disp = (speed * dt)[:, None] * np.stack([c, s], axis=1)
    d = pos[j] - pos[i]  # b's centre relative to a's
    rel = disp[i] - disp[j]  # a's displacement relative to b's
    axes = np.stack([np.stack([c[i], s[i]], 1), np.stack([-s[i], c[i]], 1),
                     np.stack([c[j], s[j]], 1), np.stack([-s[j], c[j]], 1)], axis=1)  # (K, 4, 2)  # fmt: skip

    def extent(k: np.ndarray) -> np.ndarray:  # half-extent of entities k's rectangles along every axis: (K, 4)
        along = np.abs(axes[..., 0] * c[k][:, None] + axes[..., 1] * s[k][:, None])
        across = np.abs(-axes[..., 0] * s[k][:, None] + axes[..., 1] * c[k][:, None])
        return half[k, 0][:, None] * along + half[k, 1][:, None] * across

    ra, rb = extent(i), extent(j)
    t = axes[..., 0] * d[:, None, 0] + axes[..., 1] * d[:, None, 1]
    vp = axes[..., 0] * rel[:, None, 0] + axes[..., 1] * rel[:, None, 1]
    min_a = -ra + np.minimum(vp, 0)
    max_a = ra + np.maximum(vp, 0)
    gap = np.maximum((t - rb) - max_a, min_a - (t + rb))
    return ok & (gap > _SAT_MARGIN).any(axis=1)


def _step(self: Any, dt: float) -> None:
    """``Road.step`` with the kinematics inlined, one closest-lane pass and the collision pre-check vectorised.

    The inlined path needs every vehicle to step through highway-env's own ``Vehicle.step`` (no vehicle reads
    another's lane during the step, so the closest-lane updates can wait for the last one); otherwise each
    vehicle steps through its own method, as in highway-env.
    """
    from fog_gym.world.traffic.vehicles import step_kind

    vehicles = self.vehicles
    kinds = [step_kind(v, self) for v in vehicles]
    if not self.record_history and None not in kinds:
        fast = self._fog_fast
        for vehicle, idm in zip(vehicles, kinds):
            fast.kinematic_step(vehicle, dt, idm)
        fast.update_lanes(vehicles)
    else:
        for vehicle in vehicles:
            vehicle.step(dt)
    _collide(self, dt)


def _regulated_step(self: Any, dt: float) -> None:
    """``RegulatedRoad.step``: its road-rule enforcement, then the fast ``Road.step``."""
    self.steps += 1
    if self.steps % int(1 / dt / self.REGULATION_FREQUENCY) == 0:
        self.enforce_road_rules()
    _step(self, dt)
