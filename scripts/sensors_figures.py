"""The figures of docs/sensors.md's "Sensors like real ones": LiDAR return modes in dense fog, a sweep that takes
time at speed (and deskewed), a night frame with camera noise, anti-aliasing against a supersampled reference.

Usage::

    python scripts/sensors_figures.py --out docs/images      # about a minute on two cores
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from fog_gym.channels.packing import unpack_points  # noqa: E402
from fog_gym.envs.fogdrive import FogDriveEnv  # noqa: E402
from fog_gym.geometry import sensor_to_world  # noqa: E402
from fog_gym.sensors import CameraRig, deskew  # noqa: E402
from fog_gym.wrappers import FogWrapper  # noqa: E402


def returns_figure(out: Path) -> dict[str, int]:
    sweeps, counts = {}, {}
    for mode in ("strongest", "last", "dual"):
        env = FogWrapper(FogDriveEnv(town="merge", resolution=(64, 48), cameras=["CAM_FRONT"], lidar_returns=mode),
                         fog=["dense"])  # fmt: skip
        obs, _ = env.reset(seed=7)
        for _ in range(5):
            obs, *_ = env.step(env.unwrapped.idle_action)
        ch = next(k for k in obs if k.startswith("LIDAR_TOP") and k.endswith("FOG_DENSE"))
        sweeps[mode] = unpack_points(obs, ch)
        counts[mode] = len(sweeps[mode])
    fig, axes = plt.subplots(1, 3, figsize=(15, 5.2))
    for ax, (mode, pts) in zip(axes, sweeps.items()):
        r = np.linalg.norm(pts[:, :2], axis=1)
        if mode == "dual":
            ax.scatter(pts[pts[:, 4] == 0, 0], pts[pts[:, 4] == 0, 1], s=0.3, c="tab:blue", label="strongest (return 0)")
            ax.scatter(pts[pts[:, 4] == 1, 0], pts[pts[:, 4] == 1, 1], s=0.6, c="tab:red", label="last, not strongest (1)")
            ax.legend(loc="lower left", fontsize=8, markerscale=8)
        else:
            ax.scatter(pts[:, 0], pts[:, 1], s=0.3, c=np.minimum(r, 60), cmap="viridis")
        far = int((r > 35).sum())
        ax.set_title(f"{mode}: {len(pts)} points, {far} beyond 35 m", fontsize=10)
        ax.set_xlim(-60, 60)
        ax.set_ylim(-30, 30)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m] (forward)")
    axes[0].set_ylabel("y [m]")
    fig.suptitle("Dense fog (50 m), one sweep of FogDrive's LiDAR: the fog's own echoes hide the targets behind them "
                 "in strongest mode; last and dual keep the targets whose echo clears the detection floor", fontsize=10)
    fig.tight_layout()
    fig.savefig(out / "lidar_returns.png", dpi=110)
    plt.close(fig)
    return counts


def motion_figure(out: Path) -> dict[str, float]:
    env = FogDriveEnv(town="highway", resolution=(64, 48), cameras=["CAM_FRONT"], lidar_motion="continuous", labels=None)
    obs, info = env.reset(seed=3)
    for _ in range(6):
        obs, _, _, _, info = env.step(env.idle_action)
    pts = unpack_points(obs, "LIDAR_TOP_MOTION")
    # the instantaneous sweep of the same scene
    from fog_gym.sensors import LidarSensor

    inst = LidarSensor(replace(env.config.rig.lidar, motion="instant"), env.config.simulation_frequency).measure(
        env.scene, env.cameras.primitives(env.scene, in_view=False), np.random.default_rng(0), 3)["LIDAR_TOP"]
    mount = sensor_to_world(env.config.rig.lidar.pose)
    fixed = deskew(pts, info["lidar_ego_poses"], mount)
    speed = float(info["speed"])
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6), gridspec_kw={"width_ratios": [2.2, 1, 1]})
    up = lambda p: p[:, 2] > -1.5  # noqa: E731  (the world above the road)
    ax = axes[0]
    keep = up(pts) & (np.abs(pts[:, 1]) < 28) & (pts[:, 0] > -45) & (pts[:, 0] < 45)
    sc = ax.scatter(pts[keep, 0], pts[keep, 1], s=0.5, c=pts[keep, 4] * 1000, cmap="plasma", vmin=-50, vmax=0)
    ax.set_title(f"one continuous sweep at {speed:.0f} m/s, by firing time", fontsize=10)
    ax.set_aspect("equal")
    fig.colorbar(sc, ax=ax, label="ms before the keyframe", shrink=0.8)
    # a zoom on an object fired early in the sweep (the largest shift)
    early = up(pts) & (pts[:, 4] < -0.04) & (np.linalg.norm(pts[:, :2], axis=1) > 8)
    e = pts[early, :2]
    dense = (np.hypot(*(e[:, None, :] - e[None, :, :]).transpose(2, 0, 1)) < 1.5).sum(axis=1)  # a compact object
    cx, cy = e[np.argmax(dense)]
    for ax, (title, p) in zip(axes[1:], (("continuous (colour) over instantaneous (grey)", pts),
                                         ("deskewed (colour) over instantaneous (grey)", fixed))):  # fmt: skip
        win = lambda q: up(q) & (np.abs(q[:, 0] - cx) < 4) & (np.abs(q[:, 1] - cy) < 4)  # noqa: E731
        ax.scatter(inst[win(inst), 0], inst[win(inst), 1], s=3, c="0.6")
        ax.scatter(p[win(p), 0], p[win(p), 1], s=2, c=p[win(p), 4] * 1000, cmap="plasma", vmin=-50, vmax=0)
        ax.set_title(title, fontsize=9)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
    axes[0].set_xlabel("x [m] (forward)")
    axes[0].set_ylabel("y [m]")
    fig.suptitle("A sweep that takes time: what was fired first sits where the sensor was then, up to 1.25 m ahead of "
                 "its keyframe place; deskew moves every point to the keyframe's LiDAR frame", fontsize=10)
    fig.savefig(out / "lidar_motion.png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return {"speed": speed}


def noise_figure(out: Path) -> dict[str, float]:
    env = FogWrapper(FogDriveEnv(town="merge", resolution=(640, 480), cameras=["CAM_FRONT"], time_of_day="night",
                                 camera_noise="default"), fog=["dense"])  # fmt: skip
    obs, _ = env.reset(seed=5)
    for _ in range(3):
        obs, *_ = env.step(env.unwrapped.idle_action)
    base = env.unwrapped
    clean = base.frames["CAM_FRONT"].rgb
    gain = base.cameras.exposure["CAM_FRONT"]
    crop = (slice(150, 390), slice(160, 480))
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    for ax, (title, img) in zip(axes, (("noise-free (FogDrive's)", clean), ("camera_noise='default'", obs["CAM_FRONT"]),
                                       ("dense fog, then the sensor", obs["CAM_FRONT_FOG_DENSE"]))):  # fmt: skip
        ax.imshow(img[crop])
        ax.set_title(title, fontsize=10)
        ax.axis("off")
    d = obs["CAM_FRONT"].astype(float) - clean
    fig.suptitle(f"Night, auto-exposure gain {gain:.1f} (total gain {8 * gain:.0f}×): noise σ {d.std():.1f} DN over the "
                 "frame", fontsize=10)
    fig.tight_layout()
    fig.savefig(out / "camera_noise.png", dpi=110)
    plt.close(fig)
    return {"gain": gain, "sigma": float(d.std())}


def antialias_figure(out: Path) -> dict[str, float]:
    env = FogDriveEnv(town="highway", resolution=(1280, 960), cameras=["CAM_FRONT"], labels=None)
    env.reset(seed=1)
    for _ in range(3):
        env.step(env.idle_action)
    scene, cam, far = env.scene, env.config.rig.cameras[0], env.config.far_distance

    def render(c):
        rig = CameraRig([c], far=far)
        return rig.render(scene, rig.in_view(rig.primitives(scene, in_view=False), scene))[c.name].rgb

    plain, smooth = render(cam), render(replace(cam, antialias=True))
    big = render(replace(cam, width=4 * cam.width, height=4 * cam.height))
    ref = big.reshape(cam.height, 4, cam.width, 4, 3).astype(np.float64).mean(axis=(1, 3))

    def psnr(a):
        return float(10 * np.log10(255.0**2 / np.mean((a.astype(np.float64) - ref) ** 2)))

    crop = (slice(440, 560), slice(560, 800))
    fig, axes = plt.subplots(1, 3, figsize=(15, 3.6))
    for ax, (title, img) in zip(axes, ((f"point-sampled: PSNR {psnr(plain):.1f} dB", plain),
                                       (f"antialias=True: {psnr(smooth):.1f} dB", smooth),
                                       ("reference: 4× supersampled, area-averaged", ref.round().astype(np.uint8)))):  # fmt: skip
        ax.imshow(img[crop], interpolation="nearest")
        ax.set_title(title, fontsize=10)
        ax.axis("off")
    fig.suptitle("Far cars and the ground ahead (a 240 × 120 crop of CAM_FRONT at 1280 × 960, shown 4× larger); PSNR of "
                 "the whole frame against the reference", fontsize=10)
    fig.tight_layout()
    fig.savefig(out / "antialias.png", dpi=110)
    plt.close(fig)
    return {"plain": psnr(plain), "antialias": psnr(smooth)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("docs/images"), help="folder for the PNGs (default docs/images)")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    print("returns", returns_figure(args.out))
    print("motion", motion_figure(args.out))
    print("noise", noise_figure(args.out))
    print("antialias", antialias_figure(args.out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
