"""The simulator as the augmenter's oracle: fog added by ``fog-gym augment`` to a clear fog-gym frame must reproduce
the simulator's own fogged frame (the same physics, on the same data).

* :func:`lidar_decisions`: for every point of every scan, whether the augmenter and the simulator both kept it or
  both replaced it by a fog return (their range noise comes from different random streams, so only the decision
  and the kept points' values can match exactly; they do, bit for bit);
* :func:`camera_errors`: the augmenter's image against the simulator's, with the true depth (within 1/255) or
  with depth completed from the LiDAR scan (PSNR overall and per band of true distance), with the airlight the
  simulator used, so that only the depth differs.

Example (a FogDrive set ``src`` and its KITTI export ``kitti``)::

    fog-gym augment kitti kitti_dense --format kitti --fog dense
    lidar_decisions(src, "kitti_dense", "kitti", "dense")   # {"points": …, "agree": …}
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

#: Bands of true distance (planar depth) for the camera check [m]; sky is ≥ 1000 m.
BANDS = {"0-20 m": (0.0, 20.0), "20-50 m": (20.0, 50.0), "50-100 m": (50.0, 100.0), "100 m+": (100.0, 999.0),
         "sky": (999.0, math.inf)}  # fmt: skip


def _samples(src: Path, out: Path, fmt: str) -> list[tuple[str, Path | None]]:
    """(FogDrive sample token, the output's LiDAR file) for every sample of the set and its export."""
    from fog_gym.dataset.access import FogDrive

    ds = FogDrive(src)
    if fmt == "fogdrive":
        return [(s["token"], out / Path(ds.get_sample_paths(s["token"])["LIDAR_TOP"]).relative_to(src)) for s in ds.sample]
    if fmt == "kitti":
        rows = [ln.split() for ln in (out / "ImageSets" / "fogdrive_samples.txt").read_text().splitlines() if ln.strip()]
        return [(tok, out / "training" / "velodyne" / f"{fid}.bin") for fid, tok, *_ in rows]
    import json

    version = next(p.parent for p in out.glob("*/sample_data.json"))
    sd = json.loads((version / "sample_data.json").read_text())
    lidar = {r["sample_token"]: out / r["filename"] for r in sd if r["filename"].startswith("samples/LIDAR_TOP")}
    # fog-gym's nuScenes export keeps each sample's token, without its dashes
    return [(s["token"], lidar.get(s["token"].replace("-", ""))) for s in ds.sample]


def to_fogdrive_points(points: np.ndarray, fmt: str) -> np.ndarray:
    """An export's points back in FogDrive's frame and intensity scale (x, y, z, intensity in [0, 1])."""
    p = np.asarray(points, np.float64)
    if fmt in ("kitti", "nuscenes"):
        out = np.c_[p[:, 0], -p[:, 1], p[:, 2], p[:, 3] / (255.0 if fmt == "nuscenes" else 1.0)]
        return out
    return p[:, :4]


def lidar_decisions(src: str | Path, out: str | Path, fmt: str, level: str) -> dict[str, Any]:
    """Agreement of the keep / replace decisions (module docstring) over every scan: counts and the share of
    points where they agree, and whether every point both kept is equal."""
    from fog_gym.augment.run import COLUMNS, read_points
    from fog_gym.dataset.access import FogDrive
    from fog_gym.dataset.decode import load_channel

    src, out = Path(src), Path(out)
    ds = FogDrive(src)
    ch = f"LIDAR_TOP_FOG_{level.upper()}"
    n = agree = replaced_sim = replaced_aug = 0
    kept_equal = True
    for token, path in _samples(src, out, fmt):
        if path is None or not path.exists():
            continue
        p = ds.get_sample_paths(token, ["LIDAR_TOP", ch])
        clean, sim = load_channel("LIDAR_TOP", p["LIDAR_TOP"]), load_channel(ch, p[ch])
        aug = to_fogdrive_points(read_points(path, COLUMNS.get(fmt)), fmt)
        m_sim = (sim[:, :3] != clean[:, :3]).any(1)
        m_aug = np.abs(aug[:, :3] - clean[:, :3]).max(1) > 1e-6
        n += len(m_sim)
        agree += int((m_sim == m_aug).sum())
        replaced_sim += int(m_sim.sum())
        replaced_aug += int(m_aug.sum())
        both = ~m_sim & ~m_aug
        kept_equal &= bool(np.allclose(aug[both, :3], sim[both, :3], atol=1e-5) and
                           np.allclose(aug[both, 3], sim[both, 3], atol=0.5 / 255 if fmt == "nuscenes" else 1e-6))  # fmt: skip
    return {"points": n, "agree": agree, "share": agree / n if n else math.nan, "replaced_simulator": replaced_sim,
            "replaced_augment": replaced_aug, "kept_points_equal": kept_equal}  # fmt: skip


def camera_errors(src: str | Path, level: str, completed: bool, camera: str = "CAM_FRONT",
                  every: int = 1, sky: str = "image") -> dict[str, Any]:  # fmt: skip
    """The augmenter's ``camera`` images at ``level`` against the simulator's, every ``every``-th sample: with the
    true depth, or (``completed``) with depth completed from the clean LiDAR scan (``sky``: the completion's sky
    rule, :func:`fog_gym.augment.image_depth`); the simulator's airlight.
    Returns the max absolute difference, PSNR overall and per band of true distance (:data:`BANDS`)."""
    from fog_gym.augment import fog_image
    from fog_gym.dataset.access import FogDrive
    from fog_gym.dataset.decode import load_channel
    from fog_gym.dataset.layout import extrinsic_key
    from fog_gym.dataset.export.frames import camera_intrinsic as intrinsic
    from fog_gym.fog import atmospheric_light, night_airlight

    ds = FogDrive(src)
    ch = f"{camera}_FOG_{level.upper()}"
    sq = {b: [0.0, 0] for b in BANDS}
    total, count, worst = 0.0, 0, 0
    for scene in ds.scene:
        samples = ds.get_samples_for_scene(scene["token"])
        night = "_night_" in scene["name"]
        first = ds.get_sample_paths(samples[0]["token"], [camera, f"{camera}_DEPTH"])
        rgb0 = load_channel(camera, first[camera])
        airlight = night_airlight(rgb0, load_channel(f"{camera}_DEPTH", first[f"{camera}_DEPTH"])) if night else atmospheric_light(rgb0)
        T = np.asarray(ds.load_extrinsic_config(scene["token"])[extrinsic_key(camera)], np.float64)
        for s in samples[::every]:
            p = ds.get_sample_paths(s["token"], [camera, ch, f"{camera}_DEPTH", "LIDAR_TOP"])
            clean, sim = load_channel(camera, p[camera]), load_channel(ch, p[ch])
            depth = load_channel(f"{camera}_DEPTH", p[f"{camera}_DEPTH"])
            h, w = depth.shape
            K = intrinsic(w, h)
            if completed:
                out = fog_image(clean, K, level, points=load_channel("LIDAR_TOP", p["LIDAR_TOP"]), T_cam_lidar=T,
                                airlight=airlight, glow=night, sky=sky)  # fmt: skip
            else:
                out = fog_image(clean, K, level, depth=depth, airlight=airlight, glow=night)
            d = out.astype(np.float64) - sim
            worst = max(worst, int(np.abs(d).max()))
            e = (d**2).mean(axis=2)
            total += float(e.sum())
            count += e.size
            for b, (lo, hi) in BANDS.items():
                m = (depth >= lo) & (depth < hi)
                sq[b][0] += float(e[m].sum())
                sq[b][1] += int(m.sum())

    def to_psnr(se: float, n: int) -> float:
        return math.inf if n and se == 0 else 10 * math.log10(255.0**2 / (se / n)) if n else math.nan

    return {"max_abs": worst, "psnr": to_psnr(total, count), "bands": {b: to_psnr(*v) for b, v in sq.items()},
            "pixels": {b: v[1] for b, v in sq.items()}}  # fmt: skip
