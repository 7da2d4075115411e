"""Procedural vehicle bodies: triangle meshes with real silhouettes for FogDrive's vehicle classes.

Each :class:`BodyType` is lofted through cross-sections along the vehicle (:func:`fog_gym.world.mesh.loft`): a
rounded lower body up to the beltline and a narrower glasshouse above it, whose height along the car draws the
silhouette — a sloped bonnet, windscreen, roof, rear window and boot. Glass is the glasshouse's sides and its steep
top quads (windscreen, rear window); head and tail lamps and the licence plates are thin boxes on the end faces; wheels are 12-sided tyres with 8-sided rims; mirrors small boxes at the A-pillars. Trucks add a cargo box (or a
trailer, or an open bed) behind their cab.

Every body is built once per process at its nominal size and placed per frame with a per-axis scale to the
vehicle's (length, width, height), which the class tables draw (:mod:`fog_gym.world.fleet`). **The vehicle's 3D box
is the tight bound of its mesh**: bumpers at ±length/2, mirrors at ±width/2, the roof at the height, the tyres on
the road (z = 0); every part is a closed solid.

Body types per FogDrive class (:data:`CLASS_BODIES`): 0 car — sedan, hatchback, coupé, SUV; 1 truck — box truck,
tractor-trailer, pickup; 4 bigger car — van, bus, ambulance. A vehicle's body type follows from its id
(:func:`body_type_of`): no random draw is added, so traffic stays identical to highway-env's.

Example:
    >>> m = body_mesh("sedan")
    >>> bool(np.allclose(m.bounds(), [[-2.3, -0.95, 0.0], [2.3, 0.95, 1.48]]))
    True
    >>> sorted(CLASS_BODIES)
    [0, 1, 4]
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from fog_gym.world.mesh import (BODY, CARGO, GLASS, HEADLAMP, PLATE, TAILLAMP, TRIM, TYRE, Mesh, box_mesh, cylinder,
                                loft)  # fmt: skip

#: Cross-section points (12): the lower body's outline from the bottom round the right side to the beltline, the
#: glasshouse's top edge, and back down the left side. Each entry: (y as a share of the local half-width — "w" body,
#: "g" glasshouse — and which height it sits at).
_RING = [(-0.78, "w", "b"), (0.78, "w", "b"), (0.91, "w", 0.12), (1.0, "w", 0.42), (0.96, "w", 0.78), (0.90, "w", "t"),
         (1.0, "g", "r"), (-1.0, "g", "r"), (-0.90, "w", "t"), (-0.96, "w", 0.78), (-1.0, "w", 0.42), (-0.91, "w", 0.12)]  # fmt: skip
#: Ring edges: 0 bottom, 1–4 right lower side, 5 right glasshouse side, 6 roof, 7 left glasshouse side, 8–11 left
#: lower side.
_GLASS_SIDES, _ROOF_EDGE = (5, 7), 6
_CABIN = 0.10  # a station whose glasshouse is at least this tall (share of the height) has windows
_STEEP = 0.45  # a roof quad rising more than this per unit length is a windscreen or rear window


@dataclass(frozen=True)
class BodyType:
    """A body as stations along the vehicle, rear to front: ``(x, bottom, belt, roof, half_width, glass_half_width)``,
    x in shares of the length (−0.5 rear … 0.5 front), heights in shares of the height, widths in shares of the half
    width; ``size`` the nominal (length, width, height) it is built at; ``wheels`` the axles' x (shares of the length)
    and the wheel radius (share of the height); ``rear`` an optional box behind the cab ((x0, x1) shares of the
    length, height share, material, "box" or "bed")."""

    name: str
    fog_class: int
    size: tuple[float, float, float]
    stations: tuple[tuple[float, float, float, float, float, float], ...]
    wheels: tuple[tuple[float, ...], float]
    rear: tuple | None = None
    side_glass: bool = True  # windows along the sides (a panel van has none behind the doors)


BODY_TYPES: dict[str, BodyType] = {b.name: b for b in (
    BodyType("sedan", 0, (4.6, 1.9, 1.48), (
        (-0.500, 0.24, 0.55, 0.58, 0.86, 0.70), (-0.470, 0.19, 0.64, 0.66, 0.92, 0.76), (-0.290, 0.19, 0.66, 0.68, 0.93, 0.78),
        (-0.150, 0.19, 0.64, 1.00, 0.93, 0.74), (0.070, 0.19, 0.64, 1.00, 0.93, 0.76), (0.230, 0.19, 0.62, 0.66, 0.93, 0.78),
        (0.450, 0.20, 0.58, 0.60, 0.91, 0.76), (0.500, 0.26, 0.52, 0.54, 0.84, 0.70)), ((-0.31, 0.30), 0.22)),
    BodyType("hatchback", 0, (4.2, 1.85, 1.50), (
        (-0.500, 0.22, 0.60, 0.92, 0.88, 0.72), (-0.455, 0.19, 0.64, 1.00, 0.92, 0.76), (0.080, 0.19, 0.64, 1.00, 0.93, 0.76),
        (0.240, 0.19, 0.62, 0.66, 0.93, 0.78), (0.450, 0.20, 0.58, 0.60, 0.91, 0.76), (0.500, 0.26, 0.52, 0.54, 0.84, 0.70)),
        ((-0.32, 0.31), 0.22)),
    BodyType("coupe", 0, (4.5, 1.9, 1.38), (
        (-0.500, 0.22, 0.55, 0.58, 0.86, 0.70), (-0.470, 0.18, 0.63, 0.65, 0.92, 0.74), (-0.330, 0.18, 0.64, 0.67, 0.93, 0.76),
        (-0.080, 0.18, 0.62, 1.00, 0.93, 0.70), (0.030, 0.18, 0.62, 1.00, 0.93, 0.72), (0.220, 0.18, 0.60, 0.64, 0.93, 0.78),
        (0.460, 0.19, 0.55, 0.57, 0.90, 0.74), (0.500, 0.24, 0.50, 0.52, 0.84, 0.70)), ((-0.31, 0.31), 0.24)),
    BodyType("suv", 0, (4.7, 1.95, 1.58), (
        (-0.500, 0.27, 0.62, 0.94, 0.88, 0.74), (-0.470, 0.23, 0.64, 1.00, 0.93, 0.78), (0.120, 0.23, 0.64, 1.00, 0.93, 0.78),
        (0.260, 0.23, 0.63, 0.69, 0.93, 0.80), (0.460, 0.24, 0.61, 0.63, 0.91, 0.78), (0.500, 0.30, 0.56, 0.58, 0.86, 0.72)),
        ((-0.31, 0.31), 0.24)),
    BodyType("box_truck", 1, (8.5, 2.5, 3.4), (
        (0.220, 0.18, 0.46, 0.48, 0.92, 0.86), (0.240, 0.16, 0.48, 0.78, 0.93, 0.88), (0.420, 0.16, 0.48, 0.78, 0.93, 0.88),
        (0.480, 0.16, 0.46, 0.60, 0.93, 0.86), (0.500, 0.20, 0.42, 0.44, 0.88, 0.80)), ((-0.32, -0.20, 0.36), 0.15),
        rear=((-0.500, 0.205), 1.0, CARGO, "box")),
    BodyType("tractor_trailer", 1, (9.5, 2.5, 3.7), (
        (0.300, 0.17, 0.45, 0.47, 0.92, 0.86), (0.320, 0.15, 0.48, 0.90, 0.93, 0.88), (0.470, 0.15, 0.48, 0.90, 0.93, 0.88),
        (0.490, 0.15, 0.46, 0.74, 0.93, 0.86), (0.500, 0.19, 0.42, 0.44, 0.88, 0.80)), ((-0.40, -0.28, 0.20, 0.40), 0.14),
        rear=((-0.500, 0.280), 1.0, CARGO, "box")),
    BodyType("pickup", 1, (8.0, 2.5, 3.2), (
        (-0.080, 0.22, 0.48, 0.50, 0.92, 0.84), (-0.060, 0.20, 0.50, 1.00, 0.93, 0.82), (0.180, 0.20, 0.50, 1.00, 0.93, 0.84),
        (0.300, 0.20, 0.49, 0.56, 0.93, 0.86), (0.470, 0.21, 0.46, 0.48, 0.91, 0.84), (0.500, 0.25, 0.42, 0.44, 0.86, 0.78)),
        ((-0.34, 0.32), 0.15), rear=((-0.500, -0.085), 0.50, BODY, "bed")),
    BodyType("van", 4, (5.4, 2.0, 2.2), (
        (-0.500, 0.19, 0.50, 0.96, 0.90, 0.80), (-0.480, 0.16, 0.50, 1.00, 0.93, 0.84), (0.250, 0.16, 0.50, 1.00, 0.93, 0.84),
        (0.340, 0.16, 0.50, 0.62, 0.93, 0.86), (0.470, 0.17, 0.48, 0.50, 0.91, 0.84), (0.500, 0.21, 0.44, 0.46, 0.86, 0.78)),
        ((-0.32, 0.33), 0.16), side_glass=False),
    BodyType("bus", 4, (5.9, 2.1, 2.5), (
        (-0.500, 0.15, 0.42, 0.98, 0.92, 0.86), (-0.485, 0.13, 0.42, 1.00, 0.93, 0.88), (0.460, 0.13, 0.42, 1.00, 0.93, 0.88),
        (0.490, 0.13, 0.40, 0.96, 0.93, 0.86), (0.500, 0.16, 0.38, 0.90, 0.90, 0.82)), ((-0.30, 0.30), 0.14)),
    BodyType("ambulance", 4, (5.8, 2.1, 2.5), (
        (0.120, 0.16, 0.46, 0.48, 0.92, 0.84), (0.140, 0.15, 0.46, 0.86, 0.93, 0.86), (0.260, 0.15, 0.46, 0.86, 0.93, 0.86),
        (0.350, 0.15, 0.46, 0.58, 0.93, 0.86), (0.470, 0.16, 0.44, 0.46, 0.91, 0.84), (0.500, 0.20, 0.40, 0.42, 0.86, 0.78)),
        ((-0.32, 0.33), 0.15), rear=((-0.500, 0.125), 1.0, CARGO, "box")),
)}  # fmt: skip
#: Body types of each FogDrive class.
CLASS_BODIES: dict[int, tuple[str, ...]] = {}
for _b in BODY_TYPES.values():
    CLASS_BODIES[_b.fog_class] = (*CLASS_BODIES.get(_b.fog_class, ()), _b.name)
#: The ego's body (a Tesla Model 3: a sedan).
EGO_BODY = "sedan"


def body_type_of(vehicle_id: int, fog_class: int, ego_id: int | None = None) -> str:
    """The body type of a vehicle: the ego a sedan; any other one of its class's types, picked by a hash of its id
    (stable over an episode, spread evenly over the types; no random draw).

    >>> [body_type_of(i, 0) for i in range(2, 6)]
    ['suv', 'coupe', 'hatchback', 'hatchback']
    """
    if ego_id is not None and vehicle_id == ego_id:
        return EGO_BODY
    names = CLASS_BODIES.get(int(fog_class))
    if not names:
        raise ValueError(f"fog_class must be one of {sorted(CLASS_BODIES)}, got {fog_class!r}")
    h = int(vehicle_id) & 0xFFFFFFFFFFFFFFFF  # MurmurHash3's 64-bit finaliser: neighbouring ids spread evenly
    h = ((h ^ (h >> 33)) * 0xFF51AFD7ED558CCD) & 0xFFFFFFFFFFFFFFFF
    h = ((h ^ (h >> 33)) * 0xC4CEB9FE1A85EC53) & 0xFFFFFFFFFFFFFFFF
    return names[(h ^ (h >> 33)) % len(names)]


def _ring(bottom: float, belt: float, roof: float, w: float, g: float) -> np.ndarray:
    out = []
    for share, which, at in _RING:
        y = share * (w if which == "w" else g)
        z = bottom if at == "b" else belt if at == "t" else roof if at == "r" else bottom + at * (belt - bottom)
        out.append((y, z))
    return np.array(out)


def _hull(body: BodyType) -> Mesh:
    """The lofted body (lower body and glasshouse) at the nominal size."""
    L, W, H = body.size
    st = np.array(body.stations, np.float64)
    x = st[:, 0] * L
    x[0] += PROUD if st[0, 0] <= -0.49 else 0.0  # the lamps and plates stand proud of the end faces
    x[-1] -= PROUD if st[-1, 0] >= 0.49 else 0.0
    rings = [_ring(b * H, t * H, r * H, w * W / 2, g * W / 2) for _, b, t, r, w, g in st]
    mats = np.full((len(st) - 1, len(_RING)), BODY, np.uint8)
    cabin = (st[:, 3] - st[:, 2]) >= _CABIN
    for i in range(len(st) - 1):
        slope = abs(st[i + 1, 3] - st[i, 3]) * H / max((st[i + 1, 0] - st[i, 0]) * L, 1e-9)
        if body.side_glass or st[i + 1, 0] > 0.0 or not cabin.all():
            if cabin[i] and cabin[i + 1]:
                for j in _GLASS_SIDES:
                    mats[i, j] = GLASS
        if slope > _STEEP and (cabin[i] or cabin[i + 1]):
            mats[i, _ROOF_EDGE] = GLASS  # windscreen / rear window
        mats[i, 0] = TRIM  # the underside
    # rounded ends: a body end (not a cargo box's) tapers over its last TAPER of the length to a smaller face
    x, rings, mats = list(x), list(rings), [row for row in mats]
    for end in (-1, 0):
        if abs(st[end, 0]) < 0.49:
            continue
        sign = 1.0 if end == -1 else -1.0
        face = rings[end]
        centre = face.mean(axis=0)
        rings_new = centre + (face - centre) * [TAPER_SCALE, TAPER_SCALE]
        x_inner = x[end] - sign * TAPER * L
        if end == -1:
            x[-1] = x_inner
            x.append(x_inner + sign * TAPER * L)
            rings.append(rings_new)
            mats.append(np.where(mats[-1] == GLASS, BODY, mats[-1]))
        else:
            x[0] = x_inner
            x.insert(0, x_inner + sign * TAPER * L)
            rings.insert(0, rings_new)
            mats.insert(0, np.where(mats[0] == GLASS, BODY, mats[0]))
    hull = loft(np.array(x), rings, np.array(mats), cap=BODY)
    return Mesh(hull.vertices, hull.triangles, hull.materials)


#: A body end tapers over this share of the length to a face this much smaller (rounded bumpers, no flat slab).
TAPER, TAPER_SCALE = 0.035, 0.8


#: Lamps and licence plates stand this far proud of the body's end faces (the body stops short by as much, so the
#: box stays the tight bound).
PROUD = 0.015


def _lamps(body: BodyType) -> list[Mesh]:
    """Head and tail lamps and the licence plates: thin boxes on the end faces, from the face to ±length/2."""
    L, W, H = body.size
    st = np.array(body.stations, np.float64)
    out = []
    for end, lamp in ((st[-1], HEADLAMP), (st[0], TAILLAMP)):
        if abs(end[0]) < 0.49:  # this end is a cargo box's or a bed's: _rear adds its lamps
            continue
        sign = 1.0 if end[0] > 0 else -1.0
        depth = PROUD + TAPER * L  # from ±length/2 back into the tapered end, so no gap opens behind the lamp
        x = sign * (L / 2 - depth / 2)
        bottom, belt, w = end[1] * H, end[2] * H, end[4] * W / 2
        z_lamp = bottom + 0.72 * (belt - bottom)
        lamp_w, lamp_h = min(0.30, 0.35 * w), min(0.12, 0.22 * (belt - bottom))
        for s in (-1.0, 1.0):
            out.append(box_mesh((depth, lamp_w, lamp_h), lamp, center=(x, s * (0.80 * w - lamp_w / 2), z_lamp)))
        z_plate = bottom + 0.30 * (belt - bottom)
        out.append(box_mesh((depth, min(0.52, 0.6 * w), min(0.12, 0.2 * (belt - bottom))), PLATE, center=(x, 0.0, z_plate)))
    return out


def _rear(body: BodyType) -> list[Mesh]:
    """The cargo box, trailer or pickup bed behind the cab, with its tail lamps and plate."""
    if body.rear is None:
        return []
    L, W, H = body.size
    (x0, x1), h_share, material, kind = body.rear
    x0, x1 = x0 * L, x1 * L
    floor = 0.16 * H + 0.02
    parts: list[Mesh] = []
    x0 += PROUD  # the tail lamps and the plate stand proud of the rear face
    if kind == "box":
        parts.append(box_mesh((x1 - x0, W, H - floor), material, center=((x0 + x1) / 2, 0.0, (H + floor) / 2)))
    else:  # an open bed: floor and three walls
        top = h_share * H
        t = 0.06
        parts += [box_mesh((x1 - x0, 0.93 * W, t), BODY, center=((x0 + x1) / 2, 0.0, floor + t / 2)),
                  box_mesh((t, 0.93 * W, top - floor), BODY, center=(x0 + t / 2, 0.0, (top + floor) / 2))]  # fmt: skip
        for s in (-1, 1):
            parts.append(box_mesh((x1 - x0 - t, t, top - floor), BODY,
                                  center=((x0 + x1 + t) / 2, s * (0.93 * W / 2 - t / 2), (top + floor) / 2)))  # fmt: skip
    lamp_z = 0.30 * H if kind == "box" else 0.40 * H
    for s in (-1, 1):  # tail lamps proud of the rear face, inside the box
        parts.append(box_mesh((PROUD, 0.22, 0.12), TAILLAMP, center=(-L / 2 + PROUD / 2, s * (W / 2 - 0.25), lamp_z)))
    parts.append(box_mesh((PROUD, 0.52, 0.12), PLATE, center=(-L / 2 + PROUD / 2, 0.0, lamp_z - 0.2)))
    if kind == "box":  # the cargo box begins a little above the road: underrun bar in the gap
        parts.append(box_mesh((0.10, 0.90 * W, 0.10), TRIM, center=(x0 + 0.05, 0.0, floor - 0.12)))
    return parts


def _wheels(body: BodyType) -> list[Mesh]:
    L, W, H = body.size
    axles, r_share = body.wheels
    r = r_share * H
    width = min(0.24, 0.12 * W)
    out = []
    for ax in axles:
        for s in (-1, 1):
            y = s * (0.93 * W / 2 - width / 2)
            out.append(cylinder(r, width, 12, "y", (ax * L, y, r), TYRE))
            out.append(cylinder(0.55 * r, width + 0.02, 8, "y", (ax * L, y, r), TRIM))  # the rim, proud of the tyre
    return out


def _mirrors(body: BodyType) -> list[Mesh]:
    """Door mirrors where the glasshouse starts at the front: they reach the vehicle's full width."""
    L, W, H = body.size
    st = np.array(body.stations)
    cabin = np.flatnonzero(st[:, 3] - st[:, 2] >= _CABIN)
    x = st[cabin[-1], 0] * L - 0.15  # just behind the windscreen's base
    z = st[cabin[-1], 2] * H + 0.06
    arm = W / 2 - 0.93 * W / 2
    return [box_mesh((0.12, arm, 0.14), TRIM, center=(x, s * (W / 2 - arm / 2), z)) for s in (-1, 1)]


@functools.lru_cache(maxsize=None)
def body_mesh(name: str) -> Mesh:
    """The body type ``name`` at its nominal size (:data:`BODY_TYPES`), built once per process."""
    if name not in BODY_TYPES:
        raise ValueError(f"body type must be one of {sorted(BODY_TYPES)}, got {name!r}")
    body = BODY_TYPES[name]
    return Mesh.join(_hull(body), *_lamps(body), *_rear(body), *_wheels(body), *_mirrors(body))
