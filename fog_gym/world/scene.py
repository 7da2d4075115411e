"""The Scene: everything the sensors see at one instant, as plain numpy arrays.

Data path (docs/design.md §1): highway-env world → :class:`Scene` → sensors. A :class:`StaticWorld` (road
surface map and roadside props) is built once per episode; each keyframe adds the vehicles, lifted into
3D as a few boxes each (body, cabin or cargo, wheels, lamps), all inside the vehicle's ground-truth box.

Example:
    >>> from fog_gym.world.fleet import VehicleState
    >>> import numpy as np
    >>> state = VehicleState(np.array([1, 2], np.int32), np.array([0, 1], np.int8),
    ...     np.array([[0, 0, 0.75], [20, 0, 1.6]]), np.array([[4.8, 2.1, 1.5], [9, 2.5, 3.2]]),
    ...     np.zeros(2), np.zeros((2, 3)), np.full((2, 3), 0.5))
    >>> prims = vehicle_primitives(state, night=False)
    >>> sorted(set(prims.insts.tolist()))
    [1, 2]
"""

from __future__ import annotations

import math
from dataclasses import dataclass
import threading
from typing import Any

import numpy as np

from fog_gym._rounds import held
from fog_gym.seeds import stream
from fog_gym.world.primitives import Primitives
from fog_gym.world.scenery import STYLES, Props, SurfaceMap, build_surface, place_props
from fog_gym.world.towns import TOWN_SPECS, TOWNS
from fog_gym.world.fleet import VehicleState

#: Semantic tag of each FogDrive class (CARLA ≥ 0.9.14: 14 Car, 15 Truck).
CLASS_TAGS = {0: 14, 1: 15, 2: 18, 3: 19, 4: 14}
_GLASS = np.array([0.10, 0.12, 0.15])
_TYRE = np.array([0.06, 0.06, 0.06])
_HEAD_DAY, _HEAD_NIGHT = np.array([0.85, 0.85, 0.82]), np.array([1.0, 0.96, 0.82])
_TAIL_DAY, _TAIL_NIGHT = np.array([0.55, 0.05, 0.05]), np.array([1.0, 0.12, 0.08])


@dataclass(frozen=True)
class Lighting:
    """Sun, ambient and sky for one episode. ``sun_dir`` points from the scene towards the sun (world frame)."""

    night: bool
    sun_dir: np.ndarray
    ambient: float
    sun_intensity: float
    sky_horizon: np.ndarray  # RGB 0–255
    sky_zenith: np.ndarray
    texture_amp: float

    @classmethod
    def for_time_of_day(cls, time_of_day: str, rng: np.random.Generator) -> Lighting:
        azimuth = rng.uniform(0.0, 2.0 * math.pi)
        if time_of_day == "night":
            # FogDrive sets the sun altitude to −90°: no sun, ambient near zero
            return cls(True, np.array([0.0, 0.0, -1.0]), 0.03, 0.0, np.array([10.0, 12.0, 18.0]),
                       np.array([2.0, 3.0, 6.0]), 0.15)  # fmt: skip
        elevation = math.radians(rng.uniform(35.0, 65.0))
        sun = np.array([math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth), math.sin(elevation)])
        return cls(False, sun, 0.45, 0.6, np.array([205.0, 218.0, 232.0]), np.array([92.0, 140.0, 205.0]), 1.0)

    @property
    def ground_shade(self) -> float:
        """The sunlit ground's brightness factor: ambient plus the sun's share on a horizontal surface."""
        return self.ambient + self.sun_intensity * max(float(self.sun_dir[2]), 0.0)


@dataclass(frozen=True, eq=False)
class StaticWorld:
    """Per-episode static content: the road surface map and the roadside props (the renderer derives what it needs
    from them once per static world)."""

    surface: SurfaceMap
    props: Props

    @classmethod
    def build(cls, surface: SurfaceMap, props: Props) -> StaticWorld:
        return cls(surface, props)


#: Where a town's static world (``static_world="town"``) is built: (centre, half-size) [m]. The highway's covers every
#: spawn (the ego starts ≈ 100–300 m down the road) plus a 20 s episode at 40 m/s and the sensors' reach.
TOWN_WINDOWS: dict[str, tuple[tuple[float, float], float]] = {"highway": ((700.0, 6.0), 1050.0)}
_TOWN_STATIC: dict[tuple, StaticWorld] = {}
_TOWN_LOCK = threading.Lock()


def evict_oldest(cache: dict, limit: int) -> None:
    """Drop ``cache``'s oldest entry once it holds ``limit``; safe when threads share the cache (an entry another
    thread dropped first is not dropped twice).

    >>> d = {1: "a", 2: "b"}; evict_oldest(d, 2); d
    {2: 'b'}
    """
    if len(cache) >= limit:
        try:
            cache.pop(next(iter(cache)), None)
        except (StopIteration, RuntimeError):  # emptied or changed by another thread meanwhile
            pass


def town_static_world(world: Any, town: str, lanes_count: Any, surface_resolution: float, radius: float) -> StaticWorld:
    """A town's static world, built once per process and (town, lane count, surface resolution): the road surface
    and props over the stretch episodes can reach (:data:`TOWN_WINDOWS`; elsewhere ``radius`` around the world's
    start), props from a fixed per-town seed. Every episode of the town reuses it: resets cost milliseconds."""
    key = (town, lanes_count, surface_resolution)
    with held(_TOWN_LOCK):  # a vector env's worlds reset on threads: one builds it, the others wait for it
        static = _TOWN_STATIC.get(key)
        if static is None:
            center, half = TOWN_WINDOWS.get(town, (world.start_position, radius))
            lanes = world.lane_geometry(np.asarray(center, np.float64), half)
            surface = build_surface(lanes, resolution=surface_resolution)
            props = place_props(lanes, surface, stream(TOWNS.index(town) + 1, "scenery"),
                                STYLES[TOWN_SPECS[town].scenery])  # fmt: skip
            static = _TOWN_STATIC[key] = StaticWorld.build(surface, props)
    return static


@dataclass(frozen=True)
class Scene:
    """One instant: vehicles (ego first), static world, lighting, and the render primitives."""

    time: float
    ego_id: int
    ego_pose: tuple[float, float, float]  # x, y, yaw of the ego origin (ground under its centre)
    vehicles: VehicleState
    static: StaticWorld
    lighting: Lighting
    primitives: Primitives
    geometry: str = "boxes"  # "meshes": the props are drawn as their meshes (fog_gym.world.prop_meshes) too
    #: The previous keyframe's ``(time − this time, vehicles)`` (None at an episode's first frame): where a sensor
    #: that takes time finds the vehicles between the two (:class:`fog_gym.world.motion.SceneMotion`)
    previous: tuple[float, VehicleState] | None = None


def _parts(cls: int, L, W, H):
    """Parts of one vehicle class as (x0, x1, y_half, z0, z1, kind) in the vehicle frame; arrays over vehicles."""
    hl = L / 2
    if cls == 1:  # truck: chassis, cab, cargo box, wheels, lamps
        cab_x0 = hl - 2.3
        return [
            (-hl + 0.02, hl - 0.02, 0.45 * W, 0.45 + 0 * L, 1.1 + 0 * L, "tyre"),
            (cab_x0, hl - 0.02, 0.5 * W, 1.1 + 0 * L, 0.85 * H, "body"),
            (-hl + 0.02, cab_x0 - 0.2, 0.5 * W, 1.1 + 0 * L, H, "cargo"),
        ], 1.0, 1.35
    cabin = (-0.32, 0.18) if cls == 0 else (-0.47, 0.25)
    return [
        (-hl + 0.02, hl - 0.02, 0.5 * W, 0.18 * H, 0.58 * H, "body"),
        (cabin[0] * L, cabin[1] * L, 0.44 * W, 0.58 * H, H, "glass"),
    ], 0.66, 0.45 * H


def _layout(state: VehicleState, night: bool, exclude_id: int | None) -> tuple | None:
    """The boxes of every vehicle in its own frame (what :func:`vehicle_primitives` places each frame)."""
    rows = []  # per part: (vehicle indices, x0, x1, y0, y1, z0, z1, colors, emissive)
    keep = np.ones(len(state), bool) if exclude_id is None else state.ids != exclude_id
    for cls in np.unique(state.classes):
        idx = np.flatnonzero((state.classes == cls) & keep)
        if idx.size == 0:
            continue
        L, W, H = state.sizes[idx, 0], state.sizes[idx, 1], state.sizes[idx, 2]
        base = state.colors[idx]
        parts, wheel_d, lamp_z = _parts(int(cls), L, W, H)
        for x0, x1, yh, z0, z1, kind in parts:
            color = {"body": base, "glass": 0.3 * base + 0.7 * _GLASS, "tyre": np.broadcast_to(_TYRE, base.shape),
                     "cargo": 0.25 * base + 0.75 * np.array([0.85, 0.85, 0.82])}[kind]  # fmt: skip
            rows.append((idx, x0, x1, -yh, yh, z0, z1, color, False))
        hl, hw = L / 2, W / 2
        for sx in (-1.0, 1.0):  # wheels, front and rear axle
            for sy in (-1.0, 1.0):
                xc = sx * (hl - np.maximum(0.9, 0.17 * L))
                yc = sy * (hw - 0.14)
                rows.append((idx, xc - wheel_d / 2, xc + wheel_d / 2, yc - 0.12, yc + 0.12, 0 * L, wheel_d + 0 * L,
                             np.broadcast_to(_TYRE, base.shape), False))  # fmt: skip
        lamp_z = np.broadcast_to(lamp_z, L.shape)
        for sy in (-1.0, 1.0):  # head and tail lamps stand 2 cm proud of the body, inside the box
            yc = sy * (hw - 0.32)
            head = _HEAD_NIGHT if night else _HEAD_DAY
            tail = _TAIL_NIGHT if night else _TAIL_DAY
            rows.append((idx, hl - 0.04, hl, yc - 0.16, yc + 0.16, lamp_z - 0.07, lamp_z + 0.07,
                         np.broadcast_to(head, base.shape), night))  # fmt: skip
            rows.append((idx, -hl, -hl + 0.04, yc - 0.16, yc + 0.16, lamp_z - 0.06, lamp_z + 0.06,
                         np.broadcast_to(tail, base.shape), night))  # fmt: skip
    if not rows:
        return None
    vi = np.concatenate([r[0] for r in rows])
    lx = np.concatenate([(r[1] + r[2]) / 2 * np.ones(len(r[0])) for r in rows])
    ly = np.concatenate([(r[3] + r[4]) / 2 * np.ones(len(r[0])) for r in rows])
    z0 = np.concatenate([r[5] * np.ones(len(r[0])) for r in rows])
    z1 = np.concatenate([r[6] * np.ones(len(r[0])) for r in rows])
    halves = np.c_[
        np.concatenate([(r[2] - r[1]) / 2 * np.ones(len(r[0])) for r in rows]),
        np.concatenate([(r[4] - r[3]) / 2 * np.ones(len(r[0])) for r in rows]),
        (z1 - z0) / 2,
    ]
    colors = np.ascontiguousarray(np.concatenate([np.asarray(r[7], np.float64) for r in rows]))
    tags = np.array([CLASS_TAGS[int(k)] for k in state.classes], np.uint8)[vi]
    emissive = np.concatenate([np.full(len(r[0]), r[8]) for r in rows])
    out = (vi, lx, ly, z0, z1, np.ascontiguousarray(halves), colors, tags, emissive)
    for a in out:
        a.flags.writeable = False  # shared by every frame of these vehicles
    return out


_LAYOUTS: dict[tuple, tuple | None] = {}


def vehicle_primitives(state: VehicleState, night: bool, exclude_id: int | None = None, meshes: bool = False) -> Primitives:
    """Boxes for every vehicle (all inside its ground-truth box), as renderer primitive arrays; with ``meshes`` one
    primitive per vehicle drawing its body type's mesh (:mod:`fog_gym.world.bodies`) in its ground-truth box.

    A vehicle's boxes in its own frame depend only on its class, size and colour (and the time of day), so they are
    laid out once per set of vehicles and only placed in the world each frame."""
    if meshes:
        return _mesh_primitives(state, night, exclude_id)
    key = (state.ids.tobytes(), state.classes.tobytes(), state.sizes.tobytes(), state.colors.tobytes(), bool(night),
           exclude_id)  # fmt: skip
    layout = _LAYOUTS.get(key)
    if layout is None and key not in _LAYOUTS:
        layout = _layout(state, night, exclude_id)
        evict_oldest(_LAYOUTS, 256)
        _LAYOUTS[key] = layout
    if layout is None:
        return Primitives.empty()
    vi, lx, ly, z0, z1, halves, colors, tags, emissive = layout
    yaw = state.yaws[vi]
    c, s = np.cos(yaw), np.sin(yaw)
    cx, cy = state.centers[vi, 0], state.centers[vi, 1]
    centers = np.stack((cx + lx * c - ly * s, cy + lx * s + ly * c, (z0 + z1) / 2), axis=1)
    return Primitives(
        centers=centers,
        halves=halves,
        yaws=np.ascontiguousarray(yaw),
        colors=colors,
        tags=tags,
        insts=state.ids[vi].astype(np.uint16),
        emissive=emissive,
        meshes=np.zeros(len(vi), np.int32),
    )


def _mesh_primitives(state: VehicleState, night: bool, exclude_id: int | None) -> Primitives:
    from fog_gym.world.bodies import body_type_of
    from fog_gym.world.meshlib import body_mesh_id

    state = state.take(np.ones(len(state), bool) if exclude_id is None else state.ids != exclude_id)  # (copies)
    ids, classes = state.ids, state.classes
    key = (ids.tobytes(), classes.tobytes())
    bodies = _BODIES.get(key)
    if bodies is None:  # each vehicle's mesh and tag, per set of vehicles (shared by their frames; only read)
        bodies = (np.array([body_mesh_id(body_type_of(int(i), int(c))) for i, c in zip(ids, classes)], np.int32),
                  np.array([CLASS_TAGS[int(k)] for k in classes], np.uint8).reshape(len(ids)))  # fmt: skip
        evict_oldest(_BODIES, 256)
        _BODIES[key] = bodies
    meshes, tags = bodies
    n = len(ids)
    return Primitives(
        centers=np.ascontiguousarray(state.centers, np.float64),
        halves=np.ascontiguousarray(state.sizes / 2, np.float64),
        yaws=np.ascontiguousarray(state.yaws, np.float64),
        colors=np.ascontiguousarray(state.colors, np.float64),
        tags=tags,
        insts=ids.astype(np.uint16),
        emissive=np.full(n, bool(night)),
        meshes=meshes,
    )


_BODIES: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}


def ego_primitives(scene: Scene) -> Primitives:
    """The ego's own primitive (the sensors never see it; its shadow they do)."""
    state = scene.vehicles.take(scene.vehicles.ids == scene.ego_id)
    return vehicle_primitives(state, scene.lighting.night, meshes=scene.geometry == "meshes")


def lamp_heights(state: VehicleState) -> np.ndarray:
    """Height of every vehicle's head and tail lamps above the road (m), as :func:`vehicle_primitives` draws them."""
    lamp_z = np.zeros(len(state))
    for cls in np.unique(state.classes):
        idx = np.flatnonzero(state.classes == cls)
        L, W, H = state.sizes[idx, 0], state.sizes[idx, 1], state.sizes[idx, 2]
        lamp_z[idx] = np.broadcast_to(_parts(int(cls), L, W, H)[2], L.shape)
    return lamp_z


def prop_primitives(props: Props, meshes: bool = False, owners: bool = False) -> Primitives | tuple[Primitives, np.ndarray]:
    """Static props as renderer primitives (instance id 0: static world); with ``meshes`` each draws its kind's mesh
    (:mod:`fog_gym.world.prop_meshes`: trees, poles) in its box, and guard rails and buildings are their parts
    (a beam on posts; wall, parapet and window panes), all within the prop's box. With ``owners`` also the prop (row
    of ``props``) each primitive belongs to."""
    n = len(props)
    prims = Primitives(
        centers=np.ascontiguousarray(props.centers, np.float64),
        halves=np.ascontiguousarray(props.sizes / 2, np.float64),
        yaws=np.ascontiguousarray(props.yaws, np.float64),
        colors=np.ascontiguousarray(props.colors, np.float64),
        tags=np.ascontiguousarray(props.tags, np.uint8),
        insts=np.zeros(n, np.uint16),
        emissive=np.zeros(n, bool),
        meshes=np.zeros(n, np.int32),
    )
    if not (meshes and n):
        return (prims, np.arange(n)) if owners else prims
    from fog_gym.world.prop_meshes import BUILDING_TAG, RAIL_TAG, building_parts, prop_mesh_ids, rail_parts

    seeds = np.abs(np.round(props.centers[:, 0] * 7.0 + props.centers[:, 1] * 13.0)).astype(np.int64)
    prims = Primitives(**{**prims.__dict__, "meshes": prop_mesh_ids(props.sizes, props.tags, seeds)})
    rails, buildings = props.tags == RAIL_TAG, props.tags == BUILDING_TAG
    other = np.flatnonzero(~(rails | buildings))
    rail_rows, building_rows = np.flatnonzero(rails), np.flatnonzero(buildings)
    rail_prims, rail_owner = rail_parts(prims.take(rail_rows))
    building_prims, building_owner = building_parts(prims.take(building_rows))
    out = Primitives.concat(prims.take(other), rail_prims, building_prims)
    owner = np.concatenate([other, rail_rows[rail_owner], building_rows[building_owner]]).astype(np.int64)
    return (out, owner) if owners else out
