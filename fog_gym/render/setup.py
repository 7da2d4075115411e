"""Face set-up of the rasteriser: per camera, every primitive's visible surface as convex screen polygons.

A box (mesh 0) gives at most three front faces; a mesh (:mod:`fog_gym.world.meshlib`) each front-facing triangle,
placed by the primitive's pose and scaled to its box. Each face is clipped against the near plane and projected, with
its inverse depth as an affine function of the pixel coordinates, its shaded colour (albedo, or a material's share
of the primitive's colour, times ambient plus Lambert sun), semantic tag (a material's or the primitive's), instance,
world normal and night emission — what :mod:`fog_gym.render.raster`'s band pass scan-converts.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym._numba import serial_twin
from fog_gym.geometry import BOX_CORNER_SIGNS as _CORNER_SIGNS

# Box faces: corner indices (geometry.BOX_CORNER_SIGNS order) and local outward normals.
_FACE_CORNERS = np.array(
    [[0, 1, 5, 4], [2, 3, 7, 6], [0, 4, 7, 3], [1, 2, 6, 5], [4, 5, 6, 7], [0, 3, 2, 1]], dtype=np.int64
)
_FACE_NORMALS = np.array(
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=np.float64
)
MAX_VERTS = 8
NEAR = 0.05
#: A mesh whose bounding sphere spans fewer pixels than this is drawn as its box (far trees on a 64×64 camera).
LOD_PIXELS = 3.0
#: A mesh triangle whose normal and the direction to the camera make a cosine below minus this, in the mesh's
#: normalised frame (L1 norms), is culled before it is placed: the placed triangle's exact test would cull it too.
BACK_MARGIN = 1e-6


@njit(cache=True, nogil=True)
def _pixel_span(umin, umax, vmin, vmax, width, height):
    """The rows and columns (y0, y1, x0, x1, inclusive) whose pixel centres lie within the screen bounds, and whether
    any of them is in the image."""
    y0 = int(np.ceil(vmin - 0.5))
    y1 = int(np.floor(vmax - 0.5))
    x0 = int(np.ceil(umin - 0.5))
    x1 = int(np.floor(umax - 0.5))
    return y0, y1, x0, x1, not (y1 < 0 or x1 < 0 or y0 > height - 1 or x0 > width - 1 or y1 < y0 or x1 < x0)


@njit(cache=True, nogil=True)
def _emit(c, n_out, poly, k, ncx, ncy, ncz, d0, nwx, nwy, nwz, r, g, b, emis, tag, inst, prim, side, fx, fy, cx, cy,
          width, height, far, clipped, verts, nverts, planes, face_rgb, face_tag, face_inst, bounds, face_nrm,
          face_emis, face_prim, face_side):  # fmt: skip
    """Clip the camera-frame polygon ``poly[:k]`` at the near plane, project it and, if it lands in the image within
    ``far``, write face ``n_out`` of camera ``c`` (screen polygon, inverse-depth plane from the camera-frame normal
    ``nc`` and offset ``d0``, colour, tag, instance, world normal, emissive, primitive, side); returns 1 if written."""
    # clip against z >= NEAR (Sutherland-Hodgman, one plane)
    m = 0
    zmin = 1e30
    for q in range(k):  # (the vertices read as numbers: a row taken as a view is a reference numba counts)
        q1 = (q + 1) % k
        a0x, a0y, a0z = poly[q, 0], poly[q, 1], poly[q, 2]
        a1x, a1y, a1z = poly[q1, 0], poly[q1, 1], poly[q1, 2]
        in0 = a0z >= NEAR
        in1 = a1z >= NEAR
        if in0:
            clipped[m, 0] = a0x
            clipped[m, 1] = a0y
            clipped[m, 2] = a0z
            m += 1
        if in0 != in1:
            s = (NEAR - a0z) / (a1z - a0z)
            clipped[m, 0] = a0x + s * (a1x - a0x)
            clipped[m, 1] = a0y + s * (a1y - a0y)
            clipped[m, 2] = NEAR
            m += 1
    if m < 3:
        return 0
    umin = 1e30
    umax = -1e30
    vmin = 1e30
    vmax = -1e30
    area = 0.0
    for q in range(m):
        zk = clipped[q, 2]
        if zk < zmin:
            zmin = zk
        u = fx * clipped[q, 0] / zk + cx
        v = fy * clipped[q, 1] / zk + cy
        verts[c, n_out, q, 0] = u
        verts[c, n_out, q, 1] = v
        umin = min(umin, u)
        umax = max(umax, u)
        vmin = min(vmin, v)
        vmax = max(vmax, v)
    if zmin > far:
        return 0
    for q in range(m):
        q1 = (q + 1) % m
        area += verts[c, n_out, q, 0] * verts[c, n_out, q1, 1] - verts[c, n_out, q1, 0] * verts[c, n_out, q, 1]
    if area < 0.0:  # make orientation positive (interior where every edge function >= 0)
        for q in range(m // 2):
            q2 = m - 1 - q
            tu = verts[c, n_out, q, 0]
            tv = verts[c, n_out, q, 1]
            verts[c, n_out, q, 0] = verts[c, n_out, q2, 0]
            verts[c, n_out, q, 1] = verts[c, n_out, q2, 1]
            verts[c, n_out, q2, 0] = tu
            verts[c, n_out, q2, 1] = tv
    y0, y1, x0, x1, inside = _pixel_span(umin, umax, vmin, vmax, width, height)
    if not inside:
        return 0
    bounds[c, n_out, 0] = max(y0, 0)
    bounds[c, n_out, 1] = min(y1, height - 1)
    bounds[c, n_out, 2] = max(x0, 0)
    bounds[c, n_out, 3] = min(x1, width - 1)
    nverts[c, n_out] = m
    # inverse depth as an affine function of (u, v)
    planes[c, n_out, 0] = ncx / fx / d0
    planes[c, n_out, 1] = ncy / fy / d0
    planes[c, n_out, 2] = (ncz - ncx * cx / fx - ncy * cy / fy) / d0
    face_rgb[c, n_out, 0] = np.uint8(min(max(r, 0.0), 255.0))
    face_rgb[c, n_out, 1] = np.uint8(min(max(g, 0.0), 255.0))
    face_rgb[c, n_out, 2] = np.uint8(min(max(b, 0.0), 255.0))
    face_tag[c, n_out] = tag
    face_inst[c, n_out] = inst
    face_nrm[c, n_out, 0] = nwx
    face_nrm[c, n_out, 1] = nwy
    face_nrm[c, n_out, 2] = nwz
    face_emis[c, n_out] = emis
    face_prim[c, n_out] = prim
    face_side[c, n_out] = side
    return 1


@njit(cache=True, nogil=True)
def _covers_pixel(poly, k, fx, fy, cx, cy, width, height):
    """Whether the camera-frame polygon ``poly[:k]`` may cover a pixel centre of the image: False only when it lies
    wholly in front of the near plane and its projected bounds contain no pixel centre (exactly :func:`_emit`'s own
    test, done first because a call of ``_emit`` with its many array arguments costs far more; most faces of a small
    image's far scenery are sub-pixel)."""
    umin = 1e30
    umax = -1e30
    vmin = 1e30
    vmax = -1e30
    for q in range(k):
        z = poly[q, 2]
        if z < NEAR:
            return True
        u = fx * poly[q, 0] / z + cx
        v = fy * poly[q, 1] / z + cy
        umin = min(umin, u)
        umax = max(umax, u)
        vmin = min(vmin, v)
        vmax = max(vmax, v)
    return _pixel_span(umin, umax, vmin, vmax, width, height)[4]


@njit(cache=True, nogil=True)
def _cull(cam_rot, cam_trans, cam_k, width, height, far, centers, halves, meshes):
    """Per camera and primitive: 0 when its bounding sphere lies wholly behind the near plane, beyond ``far`` or
    outside a side of the view; 2 for a mesh at least :data:`LOD_PIXELS` across; else 1 (its box)."""
    n_cam = cam_rot.shape[0]
    n_prim = centers.shape[0]
    mode = np.zeros((n_cam, n_prim), dtype=np.int8)
    for c in range(n_cam):
        R = cam_rot[c]
        T = cam_trans[c]
        fx, fy, cx, cy = cam_k[c, 0], cam_k[c, 1], cam_k[c, 2], cam_k[c, 3]
        # the frustum's side planes through the camera centre (unit normals in the camera frame, pointing out)
        nl = np.sqrt(fx * fx + cx * cx)
        nr = np.sqrt(fx * fx + (width - cx) * (width - cx))
        nt = np.sqrt(fy * fy + cy * cy)
        nb = np.sqrt(fy * fy + (height - cy) * (height - cy))
        for p in range(n_prim):
            hx, hy, hz = halves[p, 0], halves[p, 1], halves[p, 2]
            radius = np.sqrt(hx * hx + hy * hy + hz * hz)
            pcz = R[2, 0] * centers[p, 0] + R[2, 1] * centers[p, 1] + R[2, 2] * centers[p, 2] + T[2]
            if pcz + radius < NEAR or pcz - radius > far:
                continue
            pcx = R[0, 0] * centers[p, 0] + R[0, 1] * centers[p, 1] + R[0, 2] * centers[p, 2] + T[0]
            pcy = R[1, 0] * centers[p, 0] + R[1, 1] * centers[p, 1] + R[1, 2] * centers[p, 2] + T[1]
            if ((-pcx * fx - pcz * cx) / nl > radius or (pcx * fx - pcz * (width - cx)) / nr > radius
                    or (-pcy * fy - pcz * cy) / nt > radius or (pcy * fy - pcz * (height - cy)) / nb > radius):
                continue  # wholly outside a side of the view
            # a mesh a few pixels across is drawn as its box (level of detail)
            mode[c, p] = 2 if meshes[p] != 0 and radius * fx >= LOD_PIXELS * pcz else 1
    return mode


@njit(cache=True, nogil=True, parallel=True, fastmath=False)  # cameras in parallel (a serial twin for small frames)
def setup_faces(
    cam_rot, cam_trans, cam_k, width, height, far,
    centers, halves, yaws, colors, tags, insts, emissive, meshes,
    lib_v, lib_t, lib_m, tri_start, tri_geom, mat_albedo, mat_paint, mat_tag, mat_emis,
    sun_dir, ambient, sun_intensity,
):  # fmt: skip
    """Every camera's faces (see the module docstring), the cameras in parallel. A mesh's triangle that faces away
    from the camera is culled in the mesh's normalised frame first (the camera centre taken there once per
    primitive; ``tri_geom``'s first vertex and normal), before its vertices are placed; only a clear back face
    (:data:`BACK_MARGIN`) is, so what is drawn is what the test on the placed triangle alone draws."""
    n_cam = cam_rot.shape[0]
    n_prim = centers.shape[0]
    # first pass: what each camera draws of each primitive (0 nothing, 1 its box, 2 its triangles), so the face
    # buffers are sized to what is in view rather than to the whole scene
    mode = _cull(cam_rot, cam_trans, cam_k, width, height, far, centers, halves, meshes)
    max_faces = 0
    for c in range(n_cam):
        n_c = 0
        for p in range(n_prim):
            if mode[c, p] == 1:
                n_c += 3
            elif mode[c, p] == 2:
                n_c += tri_start[meshes[p] + 1] - tri_start[meshes[p]]
        max_faces = max(max_faces, n_c)
    # only the first counts[c] faces of a camera are ever read
    verts = np.empty((n_cam, max_faces, MAX_VERTS, 2))
    nverts = np.empty((n_cam, max_faces), dtype=np.int64)
    planes = np.empty((n_cam, max_faces, 3))
    face_rgb = np.empty((n_cam, max_faces, 3), dtype=np.uint8)
    face_tag = np.empty((n_cam, max_faces), dtype=np.uint8)
    face_inst = np.empty((n_cam, max_faces), dtype=np.uint16)
    bounds = np.empty((n_cam, max_faces, 4), dtype=np.int64)  # y0, y1, x0, x1 inclusive
    face_nrm = np.empty((n_cam, max_faces, 3), dtype=np.float32)  # world-frame outward normal
    face_emis = np.empty((n_cam, max_faces), dtype=np.bool_)
    face_prim = np.empty((n_cam, max_faces), dtype=np.int32)
    face_side = np.empty((n_cam, max_faces), dtype=np.int32)  # a box's face 0–5; a mesh's triangle k: −1 − k
    counts = np.zeros(n_cam, dtype=np.int64)
    for c in prange(n_cam):
        corners_c = np.empty((8, 3))
        poly = np.empty((MAX_VERTS, 3))
        clipped = np.empty((MAX_VERTS, 3))
        wv = np.empty((3, 3))
        R = cam_rot[c]
        T = cam_trans[c]
        fx, fy, cx, cy = cam_k[c, 0], cam_k[c, 1], cam_k[c, 2], cam_k[c, 3]
        # camera centre in world: -R^T T
        ccx = -(R[0, 0] * T[0] + R[1, 0] * T[1] + R[2, 0] * T[2])
        ccy = -(R[0, 1] * T[0] + R[1, 1] * T[1] + R[2, 1] * T[2])
        ccz = -(R[0, 2] * T[0] + R[1, 2] * T[1] + R[2, 2] * T[2])
        n_out = 0
        for p in range(n_prim):
            if mode[c, p] == 0:
                continue
            cyaw = np.cos(yaws[p])
            syaw = np.sin(yaws[p])
            hx, hy, hz = halves[p, 0], halves[p, 1], halves[p, 2]
            if mode[c, p] == 2:  # a mesh: each front-facing triangle is a face
                sx, sy, sz = 2.0 * hx, 2.0 * hy, 2.0 * hz
                # the camera centre in the mesh's normalised frame: n·(cc − v0) there has the sign of the world's
                dcx, dcy = ccx - centers[p, 0], ccy - centers[p, 1]
                elx = (cyaw * dcx + syaw * dcy) / sx
                ely = (cyaw * dcy - syaw * dcx) / sy
                elz = (ccz - centers[p, 2]) / sz
                for t in range(tri_start[meshes[p]], tri_start[meshes[p] + 1]):
                    gx, gy, gz = elx - tri_geom[t, 0], ely - tri_geom[t, 1], elz - tri_geom[t, 2]
                    nlx, nly, nlz = tri_geom[t, 9], tri_geom[t, 10], tri_geom[t, 11]
                    if nlx * gx + nly * gy + nlz * gz < -BACK_MARGIN * ((abs(nlx) + abs(nly) + abs(nlz))
                                                                       * (abs(gx) + abs(gy) + abs(gz))):
                        continue  # a clear back face
                    for q in range(3):
                        v = lib_t[t, q]
                        lx = lib_v[v, 0] * sx
                        ly = lib_v[v, 1] * sy
                        wv[q, 0] = centers[p, 0] + lx * cyaw - ly * syaw
                        wv[q, 1] = centers[p, 1] + lx * syaw + ly * cyaw
                        wv[q, 2] = centers[p, 2] + lib_v[v, 2] * sz
                    e1x, e1y, e1z = wv[1, 0] - wv[0, 0], wv[1, 1] - wv[0, 1], wv[1, 2] - wv[0, 2]
                    e2x, e2y, e2z = wv[2, 0] - wv[0, 0], wv[2, 1] - wv[0, 1], wv[2, 2] - wv[0, 2]
                    nwx = e1y * e2z - e1z * e2y
                    nwy = e1z * e2x - e1x * e2z
                    nwz = e1x * e2y - e1y * e2x
                    if nwx * (ccx - wv[0, 0]) + nwy * (ccy - wv[0, 1]) + nwz * (ccz - wv[0, 2]) <= 1e-12:
                        continue  # back face
                    inv = 1.0 / np.sqrt(nwx * nwx + nwy * nwy + nwz * nwz)
                    nwx *= inv
                    nwy *= inv
                    nwz *= inv
                    for q in range(3):
                        poly[q, 0] = R[0, 0] * wv[q, 0] + R[0, 1] * wv[q, 1] + R[0, 2] * wv[q, 2] + T[0]
                        poly[q, 1] = R[1, 0] * wv[q, 0] + R[1, 1] * wv[q, 1] + R[1, 2] * wv[q, 2] + T[1]
                        poly[q, 2] = R[2, 0] * wv[q, 0] + R[2, 1] * wv[q, 1] + R[2, 2] * wv[q, 2] + T[2]
                    ncx = R[0, 0] * nwx + R[0, 1] * nwy + R[0, 2] * nwz
                    ncy = R[1, 0] * nwx + R[1, 1] * nwy + R[1, 2] * nwz
                    ncz = R[2, 0] * nwx + R[2, 1] * nwy + R[2, 2] * nwz
                    d0 = ncx * poly[0, 0] + ncy * poly[0, 1] + ncz * poly[0, 2]
                    if d0 > -1e-12:
                        continue
                    if not _covers_pixel(poly, 3, fx, fy, cx, cy, width, height):
                        continue
                    mat = lib_m[t]
                    emis = mat_emis[mat] and emissive[p]
                    if emis:
                        shade = 1.0
                    else:
                        lam = nwx * sun_dir[0] + nwy * sun_dir[1] + nwz * sun_dir[2]
                        shade = ambient + sun_intensity * max(lam, 0.0)
                    k = mat_paint[mat]
                    r = (mat_albedo[mat, 0] * (1.0 - k) + colors[p, 0] * k) * shade * 255.0
                    g = (mat_albedo[mat, 1] * (1.0 - k) + colors[p, 1] * k) * shade * 255.0
                    b = (mat_albedo[mat, 2] * (1.0 - k) + colors[p, 2] * k) * shade * 255.0
                    tag = tags[p] if mat_tag[mat] == 255 else mat_tag[mat]
                    n_out += _emit(c, n_out, poly, 3, ncx, ncy, ncz, d0, nwx, nwy, nwz, r, g, b, emis, tag, insts[p], p,
                                   -1 - (t - tri_start[meshes[p]]), fx, fy, cx, cy, width, height, far, clipped, verts, nverts, planes, face_rgb,
                                   face_tag, face_inst, bounds, face_nrm, face_emis, face_prim, face_side)  # fmt: skip
                continue
            for k in range(8):
                lx = _CORNER_SIGNS[k, 0] * hx
                ly = _CORNER_SIGNS[k, 1] * hy
                wx = centers[p, 0] + lx * cyaw - ly * syaw
                wy = centers[p, 1] + lx * syaw + ly * cyaw
                wz = centers[p, 2] + _CORNER_SIGNS[k, 2] * hz
                corners_c[k, 0] = R[0, 0] * wx + R[0, 1] * wy + R[0, 2] * wz + T[0]
                corners_c[k, 1] = R[1, 0] * wx + R[1, 1] * wy + R[1, 2] * wz + T[1]
                corners_c[k, 2] = R[2, 0] * wx + R[2, 1] * wy + R[2, 2] * wz + T[2]
            if not _covers_pixel(corners_c, 8, fx, fy, cx, cy, width, height):
                continue  # the whole box between pixel centres, so each of its faces (far scenery on small images)
            for f in range(6):
                ln0, ln1, ln2 = _FACE_NORMALS[f, 0], _FACE_NORMALS[f, 1], _FACE_NORMALS[f, 2]
                nwx = ln0 * cyaw - ln1 * syaw
                nwy = ln0 * syaw + ln1 * cyaw
                nwz = ln2
                # face centre in world
                fcx = centers[p, 0] + (ln0 * hx) * cyaw - (ln1 * hy) * syaw
                fcy = centers[p, 1] + (ln0 * hx) * syaw + (ln1 * hy) * cyaw
                fcz = centers[p, 2] + ln2 * hz
                if nwx * (ccx - fcx) + nwy * (ccy - fcy) + nwz * (ccz - fcz) <= 1e-9:
                    continue  # back face
                # camera-frame normal and plane offset
                ncx = R[0, 0] * nwx + R[0, 1] * nwy + R[0, 2] * nwz
                ncy = R[1, 0] * nwx + R[1, 1] * nwy + R[1, 2] * nwz
                ncz = R[2, 0] * nwx + R[2, 1] * nwy + R[2, 2] * nwz
                i0 = _FACE_CORNERS[f, 0]
                d0 = ncx * corners_c[i0, 0] + ncy * corners_c[i0, 1] + ncz * corners_c[i0, 2]
                if d0 > -1e-9:
                    continue
                for k in range(4):
                    ik = _FACE_CORNERS[f, k]
                    poly[k, 0] = corners_c[ik, 0]
                    poly[k, 1] = corners_c[ik, 1]
                    poly[k, 2] = corners_c[ik, 2]
                if not _covers_pixel(poly, 4, fx, fy, cx, cy, width, height):
                    continue
                if emissive[p]:
                    shade = 1.0
                else:
                    lam = nwx * sun_dir[0] + nwy * sun_dir[1] + nwz * sun_dir[2]
                    shade = ambient + sun_intensity * max(lam, 0.0)
                n_out += _emit(c, n_out, poly, 4, ncx, ncy, ncz, d0, nwx, nwy, nwz, colors[p, 0] * shade * 255.0,
                               colors[p, 1] * shade * 255.0, colors[p, 2] * shade * 255.0, emissive[p], tags[p],
                               insts[p], p, f, fx, fy, cx, cy, width, height, far, clipped, verts, nverts, planes,
                               face_rgb, face_tag, face_inst, bounds, face_nrm, face_emis, face_prim, face_side)  # fmt: skip
        counts[c] = n_out
    return verts, nverts, planes, face_rgb, face_tag, face_inst, bounds, counts, face_nrm, face_emis, face_prim, face_side


setup_faces_serial = serial_twin(setup_faces)
