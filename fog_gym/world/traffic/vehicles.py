"""highway-env's per-vehicle hot paths (IDM/MOBIL ``act``, kinematic ``step``, closest-lane update), exact.

After the O(N²) loops (``fog_gym.world.traffic.core``), a highway-env traffic step is dominated by per-vehicle Python
that spends most of its time in numpy *scalar* calls (``np.clip``, ``np.dot`` of 2-vectors, lane objects'
``local_coordinates``) and in ``RoadNetwork.get_closest_lane_index``, which projects every vehicle on every
lane after every sub-step. This module re-states those functions of highway-env 1.12.1 for the vehicles whose
class uses them unchanged (``IDMVehicle`` for ``act``; any ``Vehicle`` whose ``step`` is highway-env's own):

* scalar arithmetic on Python floats in highway-env's exact operation order (``+ - * /`` round identically;
  2-vector dot products are ``x0 * y0 + x1 * y1``, which is what ``np.dot`` computes for them);
* transcendental functions whose libm and numpy results can differ (``arctan``, ``arcsin``, ``tan``,
  ``arctan2``, ``power``) are still numpy's, so the very same rounding applies; ``cos``/``sin``/``sqrt`` are
  the C library's in both;
* ``Road.act`` in two phases: the lateral decisions (``follow_road``, MOBIL's lane-change policy) per vehicle
  in road order, then steering control and IDM acceleration for all plain IDM vehicles in one numpy pass
  (:meth:`RoadFast.act_all`; numpy's element-wise results equal its scalar ones);
* the closest lane of every stepped vehicle in one numpy pass over (vehicles × lanes) for straight, sine and
  circular lanes (the same element-wise operations as the scalar lane methods; ``argmin`` keeps the first
  minimum as highway-env's does), other lane kinds through their own ``distance_with_heading``.

Vehicles of other classes (or with instance-level overrides) go through their own methods, in the original
order. Nothing here draws random numbers: ``IDMVehicle.act`` and ``Vehicle.step`` draw none.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

_PI = math.pi
_TWO_PI = 2 * math.pi
_QUARTER_PI = math.pi / 4
_STRAIGHT, _SINE, _CIRCULAR, _OTHER = 0, 1, 2, 3

#: Methods a vehicle class must inherit unchanged from highway-env for the fast ``act`` / ``step``.
_ACT_METHODS = frozenset(("act", "follow_road", "change_lane_policy", "mobil", "steering_control", "acceleration",
                          "desired_gap", "lane_distance_to"))  # fmt: skip
_STEP_METHODS = frozenset(("step", "clip_actions", "on_state_update"))
_KIN_ATTRS = ("velocity", "direction", "lane_distance_to")

_class_cache: dict[str, dict[type, bool]] = {"act": {}, "step": {}, "kin": {}, "vehicle": {}, "controlled": {}}


_CLASSES: tuple[Any, ...] = ()


def _classes() -> tuple[Any, ...]:
    global _CLASSES
    if not _CLASSES:
        from highway_env.vehicle.behavior import IDMVehicle
        from highway_env.vehicle.kinematics import Vehicle
        from highway_env.vehicle.objects import RoadObject

        _CLASSES = (IDMVehicle, Vehicle, RoadObject)
    return _CLASSES


def _class_is(cls: type, kind: str) -> bool:
    cache = _class_cache[kind]
    hit = cache.get(cls)
    if hit is None:
        IDMVehicle, Vehicle, RoadObject = _classes()
        if kind == "act":
            hit = issubclass(cls, IDMVehicle) and all(getattr(cls, m) is getattr(IDMVehicle, m) for m in _ACT_METHODS)
        elif kind == "step":  # IDMVehicle.step (timer + Vehicle.step) or Vehicle.step itself
            hit = (issubclass(cls, Vehicle) and getattr(cls, "step") in (IDMVehicle.step, Vehicle.step)
                   and all(getattr(cls, m) is getattr(Vehicle, m) for m in ("clip_actions", "on_state_update")))  # fmt: skip
        elif kind == "vehicle":
            hit = issubclass(cls, Vehicle)
        elif kind == "controlled":
            from highway_env.vehicle.controller import ControlledVehicle

            hit = issubclass(cls, ControlledVehicle)
        else:  # "kin": velocity = speed * (cos, sin)(heading), RoadObject.lane_distance_to
            hit = issubclass(cls, RoadObject) and all(
                getattr(cls, a) in (getattr(Vehicle, a), getattr(RoadObject, a)) for a in _KIN_ATTRS
            )
        cache[cls] = hit
    return hit


def _wrap(x: float) -> float:
    """``highway_env.utils.wrap_to_pi``."""
    return ((x + _PI) % _TWO_PI) - _PI


def _nz(x: float) -> float:
    """``highway_env.utils.not_zero`` (eps = 1e-2)."""
    if abs(x) > 1e-2:
        return x
    elif x >= 0:
        return 1e-2
    return -1e-2


def _clip(x: float, lo: float, hi: float) -> float:
    """``np.clip`` of a scalar: ``minimum(maximum(x, lo), hi)`` (NaN passes through)."""
    if x < lo:
        x = lo
    if x > hi:
        x = hi
    return x


class RoadFast:
    """Per-road caches: lane lookups, lane geometry as Python floats, the lane table for the closest-lane pass."""

    def __init__(self, road: Any) -> None:
        self.road = road
        self.network = road.network
        self._lanes: dict[Any, Any] = {}
        self._geom: dict[int, tuple] = {}
        self._geom_at: dict[Any, tuple] = {}
        self._table: dict | None = None
        self.xy: dict[int, tuple[float, float, float, float]] = {}  # id(entity) -> x, y, cos h, sin h (during act)

    # -- lanes ----------------------------------------------------------------------------------------
    def geom_at(self, index: Any) -> tuple:
        """``geom(network.get_lane(index))``, cached by lane index."""
        g = self._geom_at.get(index)
        if g is None:
            g = self._geom_at[index] = self.geom(self.lane(index))
        return g

    def lane(self, index: Any) -> Any:
        lane = self._lanes.get(index)
        if lane is None:
            lane = self.network.get_lane(index)
            self._lanes[index] = lane
        return lane

    def geom(self, lane: Any) -> tuple:
        g = self._geom.get(id(lane))
        if g is None or g[1] is not lane:
            from highway_env.road.lane import StraightLane

            if type(lane) is StraightLane:
                sx, sy = lane.start.tolist()
                ux, uy = lane.direction.tolist()
                lx, ly = lane.direction_lateral.tolist()
                g = (_STRAIGHT, lane, sx, sy, ux, uy, lx, ly, lane.length, lane.width, lane.heading,
                     lane.length - lane.VEHICLE_LENGTH / 2, lane.length + lane.VEHICLE_LENGTH)  # fmt: skip
            else:
                g = (_OTHER, lane)
            self._geom[id(lane)] = g
        return g

    def long_lat(self, g: tuple, x: float, y: float, pos: np.ndarray) -> tuple[float, float]:
        """``lane.local_coordinates(pos)`` (``x, y`` are ``pos`` as Python floats)."""
        if g[0] == _STRAIGHT:
            dx = x - g[2]
            dy = y - g[3]
            return dx * g[4] + dy * g[5], dx * g[6] + dy * g[7]
        return g[1].local_coordinates(pos)

    def long(self, g: tuple, x: float, y: float, pos: np.ndarray) -> float:
        if g[0] == _STRAIGHT:
            return (x - g[2]) * g[4] + (y - g[3]) * g[5]
        return g[1].local_coordinates(pos)[0]

    def entity_xy(self, e: Any) -> tuple[float, float, float, float]:
        t = self.xy.get(id(e))
        if t is None:
            x, y = e.position.tolist()
            t = (x, y, math.cos(e.heading), math.sin(e.heading))
        return t

    # -- IDM / MOBIL ----------------------------------------------------------------------------------
    def lane_distance(self, ego: Any, other: Any) -> float:
        """``ego.lane_distance_to(other)``."""
        lane = ego.lane
        g = self.geom(lane)
        ox, oy, _, _ = self.entity_xy(other)
        ex, ey, _, _ = self.entity_xy(ego)
        return self.long(g, ox, oy, other.position) - self.long(g, ex, ey, ego.position)

    def desired_gap(self, v: Any, ego: Any, front: Any) -> float:
        """``v.desired_gap(ego, front)`` (projected)."""
        d0 = v.DISTANCE_WANTED
        tau = v.TIME_WANTED
        ab = -v.COMFORT_ACC_MAX * v.COMFORT_ACC_MIN
        _, _, ce, se = self.entity_xy(ego)
        _, _, cf, sf = self.entity_xy(front)
        spe = ego.speed
        spf = front.speed
        dvx = spe * ce - spf * cf
        dvy = spe * se - spf * sf
        dv = dvx * ce + dvy * se
        return d0 + spe * tau + spe * dv / (2 * math.sqrt(ab))

    def acceleration(self, v: Any, ego: Any, front: Any) -> float:
        """``IDMVehicle.acceleration(v, ego_vehicle=ego, front_vehicle=front)``."""
        if ego is None or not _class_is(type(ego), "vehicle"):  # isinstance(ego, Vehicle), by class
            return 0
        if not _class_is(type(ego), "kin") or (front is not None and not _class_is(type(front), "kin")):
            return _classes()[0].acceleration(v, ego, front)
        ts = getattr(ego, "target_speed", 0)
        lane = ego.lane
        if lane is not None and lane.speed_limit is not None:
            ts = _clip(ts, 0, lane.speed_limit)
        sp = ego.speed
        if 0 > sp:
            sp = 0
        cam = v.COMFORT_ACC_MAX
        acc = cam * (1 - np.power(sp / abs(_nz(ts)), v.DELTA))
        if front is not None:
            d = self.lane_distance(ego, front)
            acc -= cam * np.power(self.desired_gap(v, ego, front) / _nz(d), 2)
        return acc

    def reachable(self, g: tuple, x: float, y: float, pos: np.ndarray) -> bool:
        """``lane.is_reachable_from(pos)``."""
        lane = g[1]
        if g[0] != _STRAIGHT:
            return lane.is_reachable_from(pos)
        if lane.forbidden:
            return False
        s, r = self.long_lat(g, x, y, pos)
        return abs(r) <= 2 * g[9] and 0 <= s < g[12]

    def abort_lane_change(self, v: Any) -> None:
        """``change_lane_policy``'s abort check: someone else is already changing into the same lane."""
        target = v.target_lane_index
        for other in self.road.vehicles:
            if (other is not v and other.lane_index != target and _class_is(type(other), "controlled")
                    and other.target_lane_index == target):  # fmt: skip
                if not (_class_is(type(v), "kin") and _class_is(type(other), "kin")):
                    d = v.lane_distance_to(other)
                    d_star = v.desired_gap(v, other)
                else:
                    d = self.lane_distance(v, other)
                    d_star = self.desired_gap(v, v, other)
                if 0 < d < d_star:
                    v.target_lane_index = v.lane_index
                    break

    def mobil(self, v: Any, lane_index: Any, nb: Any) -> bool:
        """``IDMVehicle.mobil``."""
        new_preceding, new_following = nb(v, lane_index)
        new_following_a = self.acceleration(v, new_following, new_preceding)
        new_following_pred_a = self.acceleration(v, new_following, v)
        if new_following_pred_a < -v.LANE_CHANGE_MAX_BRAKING_IMPOSED:
            return False
        old_preceding, old_following = nb(v)
        self_pred_a = self.acceleration(v, v, new_preceding)
        route = v.route
        if route and route[0][2] is not None:
            target = v.target_lane_index
            if np.sign(lane_index[2] - target[2]) != np.sign(route[0][2] - target[2]):
                return False
            elif self_pred_a < -v.LANE_CHANGE_MAX_BRAKING_IMPOSED:
                return False
        else:
            self_a = self.acceleration(v, v, old_preceding)
            old_following_a = self.acceleration(v, old_following, v)
            old_following_pred_a = self.acceleration(v, old_following, old_preceding)
            jerk = self_pred_a - self_a + v.POLITENESS * (
                new_following_pred_a - new_following_a + old_following_pred_a - old_following_a
            )
            if jerk < v.LANE_CHANGE_MIN_ACC_GAIN:
                return False
        return True

    def act_all(self, vehicles: list, nb: Any) -> None:
        """``Road.act``: every vehicle acts, in order; plain IDM vehicles' controls then in one numpy pass.

        The lateral decisions (``follow_road``, MOBIL) run per vehicle in road order, because a vehicle's abort
        check reads the others' target lanes. Steering and IDM acceleration read only the vehicle's own final
        target lane and positions, speeds and lanes that do not change during ``act``, so they are computed
        afterwards for all plain IDM vehicles at once (:meth:`idm_controls`), with the same element-wise
        operations. Other vehicles act through their own ``act`` at their place in the order.
        """
        pending = []
        for v in vehicles:
            if act_eligible(v):
                if not v.crashed:
                    self.idm_decide(v, nb)
                    pending.append(v)
            else:
                v.act()
        if pending:
            self.idm_controls(pending, nb)

    def idm_controls(self, vehicles: list, nb: Any) -> None:
        """Steering and IDM acceleration of ``IDMVehicle.act`` for ``vehicles`` (decisions taken), batched."""
        n = len(vehicles)
        r = np.empty(n)
        future_heading = np.empty(n)
        heading = np.empty(n)
        nzs = np.empty(n)
        params = np.empty((n, 6))  # KP_LATERAL, KP_HEADING, LENGTH / 2, MAX_STEERING_ANGLE, ACC_MAX, COMFORT_ACC_MAX
        base = np.empty(n)
        delta = np.empty(n)
        x_own = np.zeros(n)
        x_target = np.zeros(n)
        has_own = np.zeros(n, dtype=bool)
        has_target = np.zeros(n, dtype=bool)
        changing = np.zeros(n, dtype=bool)
        exact: dict[int, float] = {}  # IDM accelerations from highway-env itself (unusual neighbour classes)
        for i, v in enumerate(vehicles):
            x, y, _, _ = self.entity_xy(v)
            sp = v.speed
            tli = v.target_lane_index
            g = self.geom_at(tli)
            s, r[i] = self.long_lat(g, x, y, v.position)
            future_heading[i] = g[10] if g[0] == _STRAIGHT else g[1].heading_at(s + sp * v.TAU_PURSUIT)
            heading[i] = v.heading
            nzs[i] = _nz(sp)
            cam = v.COMFORT_ACC_MAX
            params[i] = (v.KP_LATERAL, v.KP_HEADING, v.LENGTH / 2, v.MAX_STEERING_ANGLE, v.ACC_MAX, cam)
            # IDM free-road term (ego = v)
            ts = getattr(v, "target_speed", 0)
            lane = v.lane
            if lane is not None and lane.speed_limit is not None:
                ts = _clip(ts, 0, lane.speed_limit)
            base[i] = (sp if not 0 > sp else 0) / abs(_nz(ts))
            delta[i] = v.DELTA
            front, _ = nb(v, v.lane_index)
            front_target = None
            if v.lane_index != tli:
                changing[i] = True
                front_target, _ = nb(v, tli)
            if (front is not None and not _class_is(type(front), "kin")) or (
                front_target is not None and not _class_is(type(front_target), "kin")
            ):
                exact[i] = self._exact_idm(v, nb)
                continue
            if front is not None:
                has_own[i] = True
                x_own[i] = self.desired_gap(v, v, front) / _nz(self.lane_distance(v, front))
            if front_target is not None:
                has_target[i] = True
                x_target[i] = self.desired_gap(v, v, front_target) / _nz(self.lane_distance(v, front_target))
        kp_lat, kp_head, half_length, msa, acc_max, cam = params.T
        # steering_control(target_lane_index), then act's clip
        heading_command = np.arcsin(np.clip(-kp_lat * r / nzs, -1, 1))
        heading_ref = future_heading + np.clip(heading_command, -_QUARTER_PI, _QUARTER_PI)
        heading_rate_command = kp_head * _wrap_array(heading_ref - heading)
        slip_angle = np.arcsin(np.clip(half_length / nzs * heading_rate_command, -1, 1))
        steering = np.clip(np.clip(np.arctan(2 * np.tan(slip_angle)), -msa, msa), -msa, msa)
        # acceleration(ego=v, front) on the current lane and, when changing lane, on the target lane
        free = cam * (1 - np.power(base, delta))
        acc = np.where(has_own, free - cam * np.power(x_own, 2), free)
        acc_target = np.where(has_target, free - cam * np.power(x_target, 2), free)
        acc = np.where(changing & (acc_target < acc), acc_target, acc)
        acc = np.clip(acc, -acc_max, acc_max)
        for i, (v, st, a) in enumerate(zip(vehicles, steering.tolist(), acc.tolist())):
            if i in exact:
                a = exact[i]
            v.action = {"steering": st, "acceleration": a}

    def _exact_idm(self, v: Any, nb: Any) -> float:
        """The clipped IDM acceleration of ``IDMVehicle.act`` for ``v``, scalar (unusual neighbour classes)."""
        front, _ = nb(v, v.lane_index)
        acc = self.acceleration(v, v, front)
        if v.lane_index != v.target_lane_index:
            front, _ = nb(v, v.target_lane_index)
            target_acc = self.acceleration(v, v, front)
            if target_acc < acc:
                acc = target_acc
        return _clip(acc, -v.ACC_MAX, v.ACC_MAX)

    def idm_act(self, v: Any, nb: Any) -> None:
        """``IDMVehicle.act()`` for a vehicle whose class uses highway-env's IDM/MOBIL unchanged, scalar."""
        if v.crashed:
            return
        self.idm_decide(v, nb)
        self.idm_control(v, nb)

    def idm_decide(self, v: Any, nb: Any) -> None:
        """``IDMVehicle.act``'s lateral decisions: ``follow_road`` and MOBIL's ``change_lane_policy``."""
        x, y, _, _ = self.entity_xy(v)
        pos = v.position
        # follow_road
        g = self.geom_at(v.target_lane_index)
        if self.long(g, x, y, pos) > (g[11] if g[0] == _STRAIGHT else g[1].length - g[1].VEHICLE_LENGTH / 2):
            v.follow_road()  # rare: re-checks and asks the network for the next lane
        # MOBIL
        if v.enable_lane_change:
            li = v.lane_index
            if li != v.target_lane_index:
                if li[:2] == v.target_lane_index[:2]:
                    self.abort_lane_change(v)
            elif v.LANE_CHANGE_DELAY < v.timer:
                v.timer = 0
                for lane_index in self.network.side_lanes(li):
                    if not self.reachable(self.geom_at(lane_index), x, y, pos):
                        continue
                    if abs(v.speed) < 1:
                        continue
                    if self.mobil(v, lane_index, nb):
                        v.target_lane_index = lane_index

    def idm_control(self, v: Any, nb: Any) -> None:
        """``IDMVehicle.act``'s steering and IDM acceleration, scalar (``idm_controls`` batches them)."""
        x, y, _, _ = self.entity_xy(v)
        pos = v.position
        # steering_control(target_lane_index)
        sp = v.speed
        tli = v.target_lane_index
        g = self.geom_at(tli)
        s, r = self.long_lat(g, x, y, pos)
        s_next = s + sp * v.TAU_PURSUIT
        future_heading = g[10] if g[0] == _STRAIGHT else g[1].heading_at(s_next)
        lateral_speed_command = -v.KP_LATERAL * r
        nzs = _nz(sp)
        heading_command = np.arcsin(_clip(lateral_speed_command / nzs, -1, 1))
        heading_ref = future_heading + _clip(heading_command, -_QUARTER_PI, _QUARTER_PI)
        heading_rate_command = v.KP_HEADING * _wrap(heading_ref - v.heading)
        slip_angle = np.arcsin(_clip(v.LENGTH / 2 / nzs * heading_rate_command, -1, 1))
        steering = np.arctan(2 * np.tan(slip_angle))
        msa = v.MAX_STEERING_ANGLE
        steering = _clip(float(_clip(steering, -msa, msa)), -msa, msa)
        # IDM
        front, _ = nb(v, v.lane_index)
        acc = self.acceleration(v, v, front)
        if v.lane_index != tli:
            front, _ = nb(v, tli)
            target_acc = self.acceleration(v, v, front)
            if target_acc < acc:
                acc = target_acc
        acc_max = v.ACC_MAX
        v.action = {"steering": steering, "acceleration": _clip(acc, -acc_max, acc_max)}

    # -- kinematics -----------------------------------------------------------------------------------
    def kinematic_step(self, v: Any, dt: float, idm: bool) -> None:
        """``Vehicle.step(dt)`` (``IDMVehicle.step`` when ``idm``) without its ``on_state_update``."""
        if idm:
            v.timer += dt
        action = v.action
        sp = v.speed
        if v.crashed:
            action["steering"] = 0
            action["acceleration"] = -1.0 * sp
        steering = action["steering"] = float(action["steering"])
        acc = action["acceleration"] = float(action["acceleration"])
        if sp > v.MAX_SPEED:
            limit = 1.0 * (v.MAX_SPEED - sp)
            if limit < acc:
                acc = action["acceleration"] = limit
        elif sp < v.MIN_SPEED:
            limit = 1.0 * (v.MIN_SPEED - sp)
            if limit > acc:
                acc = action["acceleration"] = limit
        beta = float(np.arctan(1 / 2 * np.tan(steering)))
        h = v.heading
        hb = h + beta
        pos = v.position
        x, y = pos.tolist()
        pos[0] = x + sp * math.cos(hb) * dt
        pos[1] = y + sp * math.sin(hb) * dt
        if v.impact is not None:
            pos += v.impact
            v.crashed = True
            v.impact = None
        v.heading = h + sp * math.sin(beta) / (v.LENGTH / 2) * dt
        v.speed = sp + acc * dt

    # -- closest lane ---------------------------------------------------------------------------------
    def lane_table(self) -> dict:
        if self._table is None:
            from highway_env.road.lane import CircularLane, SineLane, StraightLane

            indexes, lanes = [], []
            for _from, to_dict in self.network.graph.items():
                for _to, ls in to_dict.items():
                    for _id, lane in enumerate(ls):
                        indexes.append((_from, _to, _id))
                        lanes.append(lane)
            kinds = {StraightLane: _STRAIGHT, SineLane: _SINE, CircularLane: _CIRCULAR}
            kind = np.array([kinds.get(type(lane), _OTHER) for lane in lanes])
            t: dict[str, Any] = {"indexes": indexes, "lanes": lanes, "kind": kind, "n": len(lanes)}
            st = np.flatnonzero((kind == _STRAIGHT) | (kind == _SINE))
            t["st"] = st
            if len(st):
                L = [lanes[i] for i in st]
                t["st_start"] = np.array([lane.start for lane in L], dtype=np.float64).reshape(-1, 2)
                t["st_dir"] = np.array([lane.direction for lane in L], dtype=np.float64).reshape(-1, 2)
                t["st_lat"] = np.array([lane.direction_lateral for lane in L], dtype=np.float64).reshape(-1, 2)
                t["st_len"] = np.array([lane.length for lane in L], dtype=np.float64)
                t["st_head"] = np.array([lane.heading for lane in L], dtype=np.float64)
                sine = np.array([type(lane) is SineLane for lane in L])
                t["st_sine"] = sine
                t["st_amp"] = np.array([getattr(lane, "amplitude", 0.0) for lane in L], dtype=np.float64)
                t["st_puls"] = np.array([getattr(lane, "pulsation", 0.0) for lane in L], dtype=np.float64)
                t["st_phase"] = np.array([getattr(lane, "phase", 0.0) for lane in L], dtype=np.float64)
            ci = np.flatnonzero(kind == _CIRCULAR)
            t["ci"] = ci
            if len(ci):
                L = [lanes[i] for i in ci]
                t["ci_center"] = np.array([lane.center for lane in L], dtype=np.float64).reshape(-1, 2)
                t["ci_radius"] = np.array([lane.radius for lane in L], dtype=np.float64)
                t["ci_phase0"] = np.array([lane.start_phase for lane in L], dtype=np.float64)
                t["ci_dir"] = np.array([lane.direction for lane in L], dtype=np.float64)
                t["ci_len"] = np.array([lane.length for lane in L], dtype=np.float64)
            t["other"] = np.flatnonzero(kind == _OTHER)
            self._table = t
        return self._table

    def update_lanes(self, vehicles: list) -> None:
        """``on_state_update`` (closest lane index and lane) for ``vehicles``, in one pass."""
        if not vehicles:
            return
        t = self.lane_table()
        n = len(vehicles)
        pos = np.array([v.position for v in vehicles], dtype=np.float64).reshape(n, 2)
        heading = np.array([v.heading for v in vehicles], dtype=np.float64)
        dist = np.empty((n, t["n"]))
        st = t["st"]
        if len(st):
            dx = pos[:, 0:1] - t["st_start"][None, :, 0]
            dy = pos[:, 1:2] - t["st_start"][None, :, 1]
            s = dx * t["st_dir"][None, :, 0] + dy * t["st_dir"][None, :, 1]
            r = dx * t["st_lat"][None, :, 0] + dy * t["st_lat"][None, :, 1]
            lane_heading = np.broadcast_to(t["st_head"][None, :], s.shape)
            if t["st_sine"].any():
                sine = t["st_sine"]
                arg = t["st_puls"][sine] * s[:, sine] + t["st_phase"][sine]
                r = r.copy()
                r[:, sine] = r[:, sine] - t["st_amp"][sine] * np.sin(arg)
                lane_heading = lane_heading.copy()
                lane_heading[:, sine] = t["st_head"][sine] + np.arctan(
                    t["st_amp"][sine] * t["st_puls"][sine] * np.cos(arg)
                )
            dist[:, st] = _distance(s, r, heading, lane_heading, t["st_len"])
        ci = t["ci"]
        if len(ci):
            dx = pos[:, 0:1] - t["ci_center"][None, :, 0]
            dy = pos[:, 1:2] - t["ci_center"][None, :, 1]
            phase0 = t["ci_phase0"][None, :]
            phi = np.arctan2(dy, dx)
            phi = phase0 + _wrap_array(phi - phase0)
            rad = np.sqrt(dx * dx + dy * dy)
            direction = t["ci_dir"][None, :]
            radius = t["ci_radius"][None, :]
            s = direction * (phi - phase0) * radius
            r = direction * (radius - rad)
            lane_heading = (direction * s / radius + phase0) + np.pi / 2 * direction
            dist[:, ci] = _distance(s, r, heading, lane_heading, t["ci_len"])
        for j in t["other"]:
            lane = t["lanes"][j]
            for i, v in enumerate(vehicles):
                dist[i, j] = lane.distance_with_heading(v.position, v.heading)
        best = np.argmin(dist, axis=1).tolist()
        indexes, lanes = t["indexes"], t["lanes"]
        for v, j in zip(vehicles, best):
            v.lane_index = indexes[j]
            v.lane = lanes[j]


def _wrap_array(x: np.ndarray) -> np.ndarray:
    return ((x + np.pi) % (2 * np.pi)) - np.pi


def _distance(s: np.ndarray, r: np.ndarray, heading: np.ndarray, lane_heading: np.ndarray,
              length: np.ndarray) -> np.ndarray:  # fmt: skip
    """``lane.distance_with_heading`` over (vehicles, lanes): ``|r| + max(s - L, 0) + max(-s, 0) + |angle|``."""
    angle = np.abs(_wrap_array(heading[:, None] - lane_heading))
    return np.abs(r) + np.maximum(s - length[None, :], 0) + np.maximum(0 - s, 0) + 1.0 * angle


_ACT_CLASSES = _class_cache["act"]


def act_eligible(v: Any) -> bool:
    """Whether ``v.act()`` is highway-env's ``IDMVehicle.act`` with its helpers unchanged (class and instance)."""
    hit = _ACT_CLASSES.get(type(v))
    if hit is None:
        hit = _class_is(type(v), "act")
    return hit and v.__dict__.keys().isdisjoint(_ACT_METHODS)


def step_kind(v: Any, road: Any) -> bool | None:
    """``True``: ``IDMVehicle.step``; ``False``: ``Vehicle.step``; ``None``: something else (use ``v.step``)."""
    if v.road is not road or not _class_is(type(v), "step") or not v.__dict__.keys().isdisjoint(_STEP_METHODS):
        return None
    IDMVehicle, _, _ = _classes()
    return type(v).step is IDMVehicle.step


_GEOMETRY_METHODS = ("polygon", "handle_collisions", "_is_colliding")


def plain_geometry(e: Any) -> bool:
    """Whether ``e`` collides as highway-env's ``RoadObject`` (rectangle ``LENGTH`` × ``WIDTH`` at ``position``
    and ``heading``, displacement ``speed * direction * dt``), class and instance."""
    cls = type(e)
    hit = _class_cache["kin"].get(cls)
    if hit is None:
        hit = _class_is(cls, "kin")
    if not hit:
        return False
    geo = _class_cache.setdefault("geometry", {})
    g = geo.get(cls)
    if g is None:
        _, _, RoadObject = _classes()
        g = geo[cls] = all(getattr(cls, m) is getattr(RoadObject, m) for m in _GEOMETRY_METHODS)
    return g and e.__dict__.keys().isdisjoint(_GEOMETRY_METHODS)
