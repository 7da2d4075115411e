"""The ``fog-gym`` command: ``demo``, ``generate``, ``validate``, ``stats``, ``export``, ``audit``, ``view``, ``minari``,
``bench`` and the studies ``exp1``, ``exp2``, ``rl-bench`` and ``bank-study`` (:mod:`fog_gym.experiments.runner`).

Example:
    >>> parser = build_parser()
    >>> parser.parse_args(["demo", "--town", "merge"]).town
    'merge'
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from fog_gym.world.towns import TIMES_OF_DAY, TOWNS
from fog_gym.fog import FOG_PRESETS
from fog_gym.dataset.manifest import FOG_FIELD_KINDS
from fog_gym.dataset.layout import CAMERAS as CAMERA_NAMES


def _fail(command: str, message: str) -> SystemExit:
    """The one form of every command's error: ``fog-gym <command>: <message>`` on stderr, exit status 1."""
    return SystemExit(f"fog-gym {command}: {message}")


def _fog_level(text: str) -> str | float:
    """A fog level for ``--fog``: a preset name or a visibility in metres."""
    from fog_gym.fog import parse_fog

    value: str | float = text
    try:
        value = float(text)
    except ValueError:
        pass
    try:
        level = parse_fog(value)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    if level.is_clear:
        raise argparse.ArgumentTypeError("--fog takes fog levels; clear is always shown")
    return value


def _resolution(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"resolution must look like 1280x960, got {text!r}") from None
    if w <= 0 or h <= 0:
        raise argparse.ArgumentTypeError(f"resolution must be positive, got {text!r}")
    return w, h


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fog-gym", description="fog-gym: driving perception under graded, physically calibrated fog."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser(
        "demo",
        help="drive a short foggy episode; write the fog levels side by side, every camera, and a LiDAR view",
        description="Drive a short FogDrive-v0 episode in paired fog and write PNGs a person can look at: the front camera and "
        "a LiDAR bird's-eye view at clear/light/moderate/dense fog side by side, a contact sheet of all "
        "cameras' RGB / depth / semantic views, the env's render (front camera + bird's-eye view) and one LiDAR sweep "
        "seen from above (intensity; semantic LiDAR by tag).",
    )
    demo.add_argument("--town", choices=TOWNS, default="highway", help="town (default highway)")
    demo.add_argument("--time-of-day", choices=TIMES_OF_DAY, default="day", help="day or night (default day)")
    demo.add_argument("--resolution", type=_resolution, default=(1280, 960), help="camera resolution WxH (default 1280x960)")
    demo.add_argument("--steps", type=int, default=20, help="env steps (0.1 s each) before the snapshot (default 20)")
    demo.add_argument("--seed", type=int, default=0, help="episode seed (default 0)")
    demo.add_argument("--fog", type=_fog_level, nargs="+", default=list(FOG_PRESETS), metavar="LEVEL",
                      help="fog levels shown beside clear: light, moderate, dense or a visibility in metres "
                      "(default: light moderate dense)")
    demo.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder (default out/demo)")
    audit = sub.add_parser(
        "audit",
        help="annotation audit of both visibility rules (precision, recall per distance bin); writes Markdown + PNG",
        description="Drive every town by day and night, label each frame with FogDrive's LiDAR rule and the camera "
        "rule, and report the paper's audit numbers: precision (boxes with >= 10 % vehicle pixels), recall (vehicle "
        "blobs >= 100 px² covered >= 50 % by a box) overall and per distance bin.",
    )
    audit.add_argument("--frames", type=int, default=200, help="frames in all (default 200)")
    audit.add_argument("--resolution", type=_resolution, default=(1280, 960), help="camera resolution WxH (default 1280x960)")
    audit.add_argument("--seed", type=int, default=0, help="base seed (default 0)")
    audit.add_argument("--out", type=Path, default=Path("out/audit"), help="output folder (default out/audit)")
    gen = sub.add_parser(
        "generate",
        help="generate a FogDrive dataset (clean + 3 paired fog levels) in parallel, with index and splits",
        description="Render scenes in the FogDrive layout: per-town budgets in day/night pairs, seeds from (seed, "
        "scene index) so any scene regenerates bit for bit. The settings are written to index/manifest.json first; "
        "--resume continues an interrupted run and refuses settings that differ from the manifest.",
    )
    gen.add_argument("--root", type=Path, required=True, help="dataset root (must be empty unless --resume)")
    gen.add_argument("--scenes", type=int, required=True, help="number of scenes (even: day/night pairs)")
    gen.add_argument("--workers", type=int, default=1, help="worker processes (default 1)")
    gen.add_argument("--resolution", type=_resolution, default=(1280, 960), help="camera resolution WxH (default 1280x960)")
    gen.add_argument("--seconds", type=float, default=20.0, help="scene length in seconds (default 20)")
    gen.add_argument("--seed", type=int, default=0, help="base seed (default 0)")
    gen.add_argument("--towns", nargs="+", choices=TOWNS, default=list(TOWNS), help="towns to use (default all)")
    gen.add_argument("--lidar-only", action="store_true",
                     help="write only the LiDAR, its fog variants, the semantic LiDAR and the 3D boxes (no cameras); "
                     "the same as --modality lidar")
    gen.add_argument("--modality", choices=("full", "lidar", "cameras"), default=None,
                     help="channel set: full (every FogDrive channel, the default), lidar (as --lidar-only) or cameras "
                     "(RGB, its three fog variants, depth and 2D boxes of each camera, and the 3D boxes)")
    gen.add_argument("--cameras", nargs="+", choices=CAMERA_NAMES, default=[], metavar="CAM",
                     help="write only these cameras' channels (e.g. CAM_FRONT CAM_LEFT; default every camera)")
    gen.add_argument("--lidar-returns", choices=("strongest", "last", "dual"), default="strongest",
                     help="the LiDAR's echo in fog: strongest (FogDrive's, the default), last, or dual (both, with a "
                     "return column); the last and dual LiDARs' channels are LIDAR_TOP_LAST / LIDAR_TOP_DUAL")
    gen.add_argument("--lidar-motion", choices=("instant", "continuous"), default="instant",
                     help="the LiDAR's sweep: instant (FogDrive's, the default) or continuous (each azimuth fires at its "
                     "time, ego and vehicles where they are then, a time column; channels LIDAR_TOP_MOTION ...)")
    gen.add_argument("--camera-noise", choices=("default",), default=None,
                     help="record the cameras with sensor noise (shot and read noise, a gain that follows the "
                     "auto-exposure; fog_gym.sensors.camera_noise); default: noise-free, as FogDrive")
    gen.add_argument("--fog-fields", choices=FOG_FIELD_KINDS, default="levels",
                     help="how each scene's three fog levels are laid out: levels (FogDrive's homogeneous fog, the "
                     "default), banks (a fog bank on the road ahead), height (ground fog) or mixed (per scene one of "
                     "these or a bank over ground fog); fields are recorded beside each sample (fog_field/)")
    gen.add_argument("--resume", action="store_true", help="continue an interrupted run in --root (same settings)")
    gen.add_argument("--ray", metavar="ADDRESS", default=None, help="run scenes as Ray tasks on this cluster")
    val = sub.add_parser(
        "validate", help="check a dataset's index, files, shapes and split rules",
        description="Check a FogDrive dataset: the index tables, every file (decodes, shape, size; with a generation "
        "manifest also against its settings), extrinsics and the split rules. Prints one line per problem naming "
        "the file; exit status 0 if the dataset is valid, 1 otherwise.",
    )  # fmt: skip
    val.add_argument("root", type=Path, help="dataset root (holds data_root/ and index/)")
    val.add_argument("--progress", action="store_true", help="show a progress bar over the files")
    st = sub.add_parser(
        "stats", help="files and MB per modality of a dataset (optionally a bar chart)",
        description="Count the files and megabytes of each modality of a FogDrive dataset (the paper's disk table, "
        "supplementary D7) and print a Markdown table; --plot PATH also writes a bar chart.",
    )  # fmt: skip
    st.add_argument("root", type=Path, help="dataset root (holds data_root/ and index/)")
    st.add_argument("--plot", type=Path, default=None, metavar="PATH", help="write a bar chart PNG to PATH")
    _add_view_parser(sub)
    _add_minari_parser(sub)
    _add_export_parser(sub)
    _add_augment_parser(sub)
    bench = sub.add_parser("bench", help="per-stage milliseconds of env, sensors, fog and recording (see fog-gym bench --help)",
                           add_help=False)
    bench.add_argument("args", nargs=argparse.REMAINDER)
    for name, text in STUDIES.items():  # their options live with the study: fog-gym <study> --help
        sub.add_parser(name, help=text, add_help=False).add_argument("args", nargs=argparse.REMAINDER)
    return parser


#: The studies, each run by fog_gym.experiments.runner (seeds, resume, report); ``fog-gym <study> --help``.
STUDIES = {
    "exp1": "Experiment 1: does mixing fog densities in training make a 3D detector robust? (see fog-gym exp1 --help)",
    "exp2": "Experiment 2: defog-then-detect vs train-on-fog, 2D detection (see fog-gym exp2 --help)",
    "rl-bench": "the fog RL benchmark: agents per fog condition, train x test matrix (see fog-gym rl-bench --help)",
    "bank-study": "fog banks: do agents trained on fog, on banks or on a curriculum of banks slow down before one? "
                  "(see fog-gym bank-study --help)",
}


def _study(name: str):
    if name == "exp1":
        from fog_gym.experiments.detection3d.study import Exp1Study

        return Exp1Study
    if name == "exp2":
        from fog_gym.experiments.defog.study import Exp2Study

        return Exp2Study
    if name == "bank-study":
        from fog_gym.experiments.bank_study import BankStudy

        return BankStudy
    from fog_gym.experiments.rl_bench.study import RLStudy

    return RLStudy


def run_demo(args: argparse.Namespace) -> list[Path]:
    import gymnasium as gym
    from tqdm import tqdm

    import fog_gym  # noqa: F401
    from fog_gym.dataset.packing import unpack_points
    from fog_gym.fog import parse_fog
    from fog_gym.viz import figures

    if args.steps < 0:
        raise _fail("demo", "--steps must be >= 0")
    levels = list(dict.fromkeys(args.fog))
    env = gym.make("FogDrive-v0", town=args.town, time_of_day=args.time_of_day, resolution=args.resolution,
                   render_mode="rgb_array", fog=levels)  # paired: clean + every level from one render  # fmt: skip
    obs, info = env.reset(seed=args.seed)
    idle = env.unwrapped.idle_action
    steps = 0
    for _ in tqdm(range(args.steps), desc=f"driving {args.town} ({args.time_of_day})", unit="step"):
        obs, reward, terminated, truncated, info = env.step(idle)
        steps += 1
        if terminated or truncated:
            break
    args.out.mkdir(parents=True, exist_ok=True)
    stem = f"{args.town}_{args.time_of_day}_seed{args.seed}"
    where = f"{args.town}, {args.time_of_day}, seed {args.seed}, after {steps / env.unwrapped.config.keyframe_frequency:g} s"
    w, h = args.resolution
    paths = []
    with tqdm(total=4, desc="drawing figures", unit="figure") as bar:
        columns = {"clear": {"rgb": obs["CAM_FRONT"], "lidar": unpack_points(obs, "LIDAR_TOP")}}
        for lv in (parse_fog(v) for v in levels):
            name = f"{lv.name} ({lv.visibility_m:g} m)" if lv.name[0].isalpha() else f"{lv.visibility_m:g} m"
            columns[name] = {"rgb": obs[f"CAM_FRONT_{lv.channel_suffix}"],
                             "lidar": unpack_points(obs, f"LIDAR_TOP_{lv.channel_suffix}")}  # fmt: skip
        fig = figures.fog_levels_figure(columns, f"The front camera and the LiDAR in fog, paired from one render ({where})",
                                        zoom_row=args.time_of_day == "night")  # fmt: skip
        paths.append(figures.save(fig, args.out / f"fog_levels_{stem}.png"))
        bar.update()
        rows = {name: (obs[name], obs[f"{name}_DEPTH"], obs[f"{name}_SEM"]) for name in env.unwrapped.cameras.names}
        fig = figures.cameras_figure(rows, f"Every camera: RGB, planar depth and semantic tags ({w}×{h}; {where})")
        paths.append(figures.save(fig, args.out / f"contact_sheet_{stem}.png"))
        bar.update()
        fig = figures.render_figure(env.render(), f"env.render() with render_mode='rgb_array' ({where})")
        paths.append(figures.save(fig, args.out / f"render_{stem}.png"))
        bar.update()
        points = env.unwrapped.points
        fig = figures.lidar_figure(points.get("LIDAR_TOP"), points.get("SEM_LIDAR_TOP"),
                                   f"One LiDAR sweep, clear air, from above ({where})")  # fmt: skip
        paths.append(figures.save(fig, args.out / f"lidar_{stem}.png"))
        bar.update()
    env.close()
    return paths


def _stats_figure(rows: list[tuple[str, int, float]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 0.3 * len(rows) + 1.2), dpi=120)
    ax.barh([r[0] for r in rows][::-1], [r[2] for r in rows][::-1])
    ax.set_xlabel("MB")
    ax.set_title("disk footprint per modality")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _add_view_parser(sub) -> None:
    view = sub.add_parser(
        "view", help="look at a recorded scene or a live foggy episode in the Rerun viewer (or save an .rrd)",
        description="Log every sensor to Rerun on a timeline of sample timestamps: the four cameras clean and at each "
        "fog level, depth and semantic images, 2D boxes, LiDAR per fog level coloured by intensity, semantic LiDAR by "
        "tag, radar, 3D boxes in the LiDAR frame, camera frusta and (live) the ego trajectory. Give --root for a "
        "recorded dataset or --town for a live episode; --save FILE.rrd writes a recording without a display "
        "(open it later with `rerun FILE.rrd`), otherwise the viewer opens. Needs the viz extra (rerun-sdk).",
    )  # fmt: skip
    src = view.add_mutually_exclusive_group(required=True)
    src.add_argument("--root", type=Path, help="a recorded FogDrive dataset")
    src.add_argument("--town", choices=TOWNS, help="drive a live paired-fog episode in this town")
    view.add_argument("--scene", default=None, help="scene name of the dataset, e.g. T1_day_scene001 (default: the first)")
    view.add_argument("--fog", type=_fog_level, nargs="+", default=list(FOG_PRESETS), metavar="LEVEL",
                      help="live: fog levels beside clear (default: light moderate dense)")
    view.add_argument("--steps", type=int, default=50, help="live: keyframes to log (default 50)")
    view.add_argument("--time-of-day", choices=TIMES_OF_DAY, default="day", help="live: day or night (default day)")
    view.add_argument("--resolution", type=_resolution, default=(320, 240), help="live: camera resolution (default 320x240)")
    view.add_argument("--seed", type=int, default=0, help="live: episode seed (default 0)")
    view.add_argument("--save", type=Path, default=None, metavar="FILE.rrd", help="write an .rrd instead of opening the viewer")


def _add_minari_parser(sub) -> None:
    mi = sub.add_parser(
        "minari", help="record random-policy episodes of the RL preset into a Minari dataset (offline RL)",
        description="Record --episodes episodes of FogDriveRL-v0 (random actions) in the given fog and town into the "
        "Minari dataset --dataset-id (under MINARI_DATASETS_PATH, default ~/.minari/datasets), losslessly, with "
        "fog level, town, time of day and fog-gym version in its metadata. For a trained policy use "
        "fog_gym.rl.minari.collect from Python. Needs the minari extra.",
    )  # fmt: skip
    mi.add_argument("--dataset-id", required=True, help="Minari id, e.g. fog-gym/highway-dense-random-v0")
    mi.add_argument("--episodes", type=int, default=10, help="episodes to record (default 10)")
    mi.add_argument("--fog", type=str, default="clear", help="fog level: clear, light, moderate, dense or metres (default clear)")
    mi.add_argument("--town", choices=TOWNS, default="highway", help="town (default highway)")
    mi.add_argument("--time-of-day", choices=TIMES_OF_DAY, default="day", help="day or night (default day)")
    mi.add_argument("--episode-seconds", type=float, default=20.0, help="episode length in seconds (default 20)")
    mi.add_argument("--keys", nargs="+", default=None, help="observation keys to keep (default all: CAM_FRONT LIDAR_BEV)")
    mi.add_argument("--seed", type=int, default=0, help="seed of the first episode (default 0)")
    mi.add_argument("--overwrite", action="store_true", help="replace an existing dataset of that id")


def _view(args: argparse.Namespace) -> int:
    from fog_gym.viz import viewer

    if args.save is not None and args.save.suffix != ".rrd":
        raise _fail("view", f"--save must name an .rrd file, got {args.save}")
    try:
        if args.root is not None:
            n = viewer.view_dataset(args.root, scene=args.scene, save=args.save)
        else:
            if args.steps < 1:
                raise _fail("view", "--steps must be >= 1")
            n = viewer.view_live(args.town, list(dict.fromkeys(args.fog)), args.steps, args.resolution,
                                 args.time_of_day, args.seed, save=args.save)  # fmt: skip
    except (ValueError, KeyError, FileNotFoundError, ImportError) as e:
        raise _fail("view", str(e).strip("'\"")) from None
    print(f"logged {n} samples" + (f" to {args.save}" if args.save is not None else ""))
    return 0


def _minari(args: argparse.Namespace) -> int:
    import gymnasium as gym

    from fog_gym.fog import parse_fog
    from fog_gym.rl.minari import collect

    fog: str | float = args.fog
    try:
        fog = float(args.fog)
    except ValueError:
        pass
    try:
        parse_fog(fog)
        if args.episode_seconds <= 0:
            raise ValueError("--episode-seconds must be > 0")
        env = gym.make("FogDriveRL-v0", fog=fog, town=args.town, time_of_day=args.time_of_day,
                       episode_seconds=args.episode_seconds)  # fmt: skip
        ds = collect(env, None, episodes=args.episodes, dataset_id=args.dataset_id, keys=args.keys, seed=args.seed,
                     overwrite=args.overwrite)  # fmt: skip
    except (ValueError, FileExistsError, ImportError) as e:
        raise _fail("minari", str(e)) from None
    print(f"{args.dataset_id}: {ds.total_episodes} episodes, {ds.total_steps} steps; "
          f"load it with minari.load_dataset({args.dataset_id!r})")  # fmt: skip
    return 0


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    if argv[:1] == ["bench"]:
        from fog_gym.experiments.bench.suite import main as bench

        return bench(argv[1:], prog="fog-gym bench")
    if argv[:1] and argv[0] in STUDIES:
        from fog_gym.experiments.runner import main as run_study

        return run_study(_study(argv[0]), argv[1:])
    args = parser.parse_args(argv)
    from fog_gym.checks import command_line

    handler = {"generate": _generate, "validate": _validate, "stats": _stats, "audit": _audit, "demo": _demo,
               "view": _view, "minari": _minari, "export": _export, "augment": _augment}  # fmt: skip
    with command_line():  # error messages name flags (--overwrite), not keywords (overwrite=True)
        return handler[args.command](args)


def _generate(args: argparse.Namespace) -> int:
    from fog_gym.dataset.lock import DatasetLocked, DatasetLockError
    from fog_gym.generate import generate, plan_scenes

    if args.workers < 1:
        raise _fail("generate", "--workers must be >= 1")
    if not args.seconds > 0:
        raise _fail("generate", "--seconds must be > 0")
    if args.lidar_only and args.modality not in (None, "lidar"):
        raise _fail("generate", f"--lidar-only and --modality {args.modality} exclude each other")
    modality = args.modality or ("lidar" if args.lidar_only else "full")
    try:
        plan = plan_scenes(args.scenes, tuple(args.towns), args.seed, args.resolution, args.seconds, modality,
                           args.fog_fields, tuple(args.cameras), args.lidar_returns, args.lidar_motion,
                           args.camera_noise)  # fmt: skip
        tables = generate(args.root, plan, args.workers, args.resume, args.ray)
    except (ValueError, DatasetLocked, DatasetLockError) as e:  # a second writer: one line naming root and holder
        raise _fail("generate", str(e)) from None
    except OSError as e:  # disk full, permission lost: one line, the set resumes with --resume
        raise _fail("generate", _write_failure(e)) from None
    print(f"{len(tables['scene'])} scenes, {len(tables['sample'])} samples in {args.root}")
    return 0


def _write_failure(e: OSError) -> str:
    """``<what failed> (<path>): <reason>`` for a failed write (the data path raises WriteError, already so)."""
    from fog_gym.dataset.writer import WriteError

    return str(WriteError.from_os_error("cannot write", e.filename or "?", e))


EXPORT_DESCRIPTION = (
    "Write a FogDrive set in a format detectors read: nuScenes v1.0 tables (OUT/v1.0-trainval/, OUT/samples/<CHANNEL>/, "
    "the devkit loads it), KITTI object (OUT/training/{image_2,velodyne,calib,label_2}; other cameras under "
    "OUT/<CAMERA>/) or COCO with YOLO labels (OUT/images/, OUT/annotations/instances_<split>.json, OUT/labels/, "
    "OUT/dataset.yaml), with the cameras and LiDAR at one fog level. OUT must be empty (--overwrite replaces an "
    "earlier export, --resume completes an interrupted one), which is checked first; then the set is validated. Frames, class mapping and "
    "limits: docs/exports.md."
)


AUGMENT_DESCRIPTION = (
    "Fog on the data you already have: write a fogged copy of a KITTI object, nuScenes or FogDrive data set, file "
    "for file (same names, dtypes and encodings; every other file hard-linked), with fog-gym's calibrated physics — "
    "Hahner et al. on the LiDAR scans, Koschmieder on the camera images with depth completed from the scan (Ku et "
    "al.; above the scan, the image's sky is far and the rest carried up its column). Deterministic per (seed, file); --resume completes an interrupted run to the same bytes; one writer per "
    "output; a manifest (fog_gym_augment.json) records fog, profile, seed and every source file's hash.\n\n"
    "fog-gym augment kitti/ kitti_dense/ --format kitti --fog dense\n"
    "fog-gym augment nuscenes/ nuscenes_fog/ --format nuscenes --fog light moderate dense --workers 2\n"
    "fog-gym augment kitti/ kitti_bank/ --format kitti --fog bank.json     # a fog field: {\"type\": \"FogBank\", ...}")


def _add_augment_parser(sub) -> None:
    ag = sub.add_parser("augment", help="fog a KITTI, nuScenes or FogDrive data set, file for file",
                        description=AUGMENT_DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    ag.add_argument("src", type=Path, help="the data set's root")
    ag.add_argument("dst", type=Path, help="the output root (created; must be empty unless --resume)")
    ag.add_argument("--format", required=True, choices=("kitti", "nuscenes", "fogdrive"), help="the data set's layout")
    ag.add_argument("--fog", nargs="+", required=True, metavar="FOG",
                    help="light, moderate, dense, clear, a visibility in metres, or a fog field as JSON (text or a "
                         ".json file: {\"type\": \"FogBank\" | \"HeightFog\" | \"FogSum\", ...}); several fogs write "
                         "DST/<fog name>/ each")  # fmt: skip
    ag.add_argument("--sensors", nargs="+", default=["lidar", "cameras"], choices=("lidar", "cameras"),
                    help="which files to fog (default both)")
    ag.add_argument("--profile", default=None,
                    help="LiDAR profile: fogdrive, kitti, nuscenes, or a .json / .toml file (default: the format's)")
    ag.add_argument("--seed", type=int, default=0, help="base seed of the fog draws (default 0)")
    mode = ag.add_mutually_exclusive_group()
    mode.add_argument("--workers", type=int, default=1, help="worker processes (default 1)")
    mode.add_argument("--ray", metavar="ADDRESS", default=None, help="run files as Ray tasks on this cluster")
    ag.add_argument("--resume", action="store_true", help="complete an interrupted run in DST (same settings)")
    ag.add_argument("--on-error", choices=("stop", "skip"), default="stop",
                    help="a bad input file (truncated, missing calibration, undecodable): stop the run naming it "
                         "(default), or skip it and list it in the manifest")  # fmt: skip
    ag.add_argument("--jpeg-quality", type=int, default=95, help="quality of re-encoded JPEG images (default 95)")


def _fog_arg(text: str) -> object:
    """A --fog value: a level name or metres, or a fog field as JSON text or a .json file."""
    import json

    from fog_gym.fog.fields import field_from_info

    t = text.strip()
    if t.startswith("{") or t.endswith(".json"):
        try:
            info = json.loads(Path(t).read_text() if t.endswith(".json") else t)
            return field_from_info(info)
        except (OSError, json.JSONDecodeError, TypeError, KeyError) as e:
            raise ValueError(f"--fog {text!r} is not a fog field ({e})") from None
    try:
        return float(t)
    except ValueError:
        return t


def _augment(args: argparse.Namespace) -> int:
    from fog_gym.augment.run import augment
    from fog_gym.dataset.lock import DatasetLocked, DatasetLockError

    try:
        fogs = [_fog_arg(f) for f in args.fog]
        r = augment(args.src, args.dst, args.format, fogs, tuple(args.sensors), args.seed, args.workers, args.ray,
                    args.resume, args.on_error, args.jpeg_quality, args.profile)  # fmt: skip
    except (ValueError, DatasetLocked, DatasetLockError) as e:
        raise _fail("augment", str(e).split("\n")[0]) from None
    except OSError as e:
        raise _fail("augment", _write_failure(e)) from None
    for name, m in r.items():
        skipped = f", {len(m['skipped'])} skipped (listed in the manifest)" if m["skipped"] else ""
        print(f"{name}: {len(m['files'])} files fogged, {m['linked']} linked{skipped}")
    return 0


def _add_export_parser(sub) -> None:
    help_text = "export a dataset to nuScenes, KITTI or COCO/YOLO at one fog level (for mmdetection3d, YOLO, ...)"
    ex = sub.add_parser("export", help=help_text, description=EXPORT_DESCRIPTION)
    ex.add_argument("root", type=Path, help="dataset root (holds data_root/ and index/)")
    ex.add_argument("out", type=Path, help="output folder (created; must be empty unless --overwrite or --resume)")
    ex.add_argument("--format", required=True, choices=("nuscenes", "kitti", "coco"), help="the export format")
    ex.add_argument("--fog", default="clear", choices=("clear", "light", "moderate", "dense"),
                    help="the fog level of the cameras and LiDAR exported (default clear)")
    ex.add_argument("--split", default="all", choices=("train", "val", "test", "all"),
                    help="FogDrive split to export (default all; nuScenes and KITTI list the splits, COCO writes one "
                    "annotation file per split)")  # fmt: skip
    ex.add_argument("--cameras", nargs="+", default=None, metavar="CAMERA",
                    help="cameras to export (default: all for nuscenes and coco, CAM_FRONT for kitti)")
    mode = ex.add_mutually_exclusive_group()
    mode.add_argument("--overwrite", action="store_true", help="replace an earlier fog-gym export in OUT")
    mode.add_argument("--resume", action="store_true", help="complete an interrupted export in OUT (same settings)")


def _export(args: argparse.Namespace) -> int:
    from fog_gym.dataset.export import export
    from fog_gym.dataset.lock import DatasetLocked, DatasetLockError

    try:
        r = export(args.root, args.out, args.format, args.fog, args.split, args.cameras, args.overwrite, args.resume)
    except (ValueError, DatasetLocked, DatasetLockError) as e:
        raise _fail("export", str(e)) from None
    except OSError as e:
        raise _fail("export", _write_failure(e)) from None
    for note in r["notes"]:
        print(f"note: {note}")
    print(f"{args.format} export of {r['samples']} samples ({r['fog']}) in {args.out}: {r['files']} files in "
          f"{r['seconds']:.1f} s")  # fmt: skip
    return 0


def _validate(args: argparse.Namespace) -> int:
    from fog_gym.dataset.validate import validate

    problems = validate(args.root, progress=args.progress)
    for p in problems:
        print(p)
    n = len(problems)
    print("valid" if not n else f"{n} problem{'s' if n > 1 else ''}")
    return 1 if problems else 0


def _stats(args: argparse.Namespace) -> int:
    from fog_gym.dataset.validate import stats

    try:
        rows = stats(args.root)
    except ValueError as e:
        raise _fail("stats", str(e)) from None
    print("| modality | files | MB |\n|---|---|---|")
    for kind, n, mb in rows:
        print(f"| {kind} | {n} | {mb:.1f} |")
    print(f"| total | {sum(r[1] for r in rows)} | {sum(r[2] for r in rows):.1f} |")
    if args.plot is not None:
        args.plot.parent.mkdir(parents=True, exist_ok=True)
        _stats_figure(rows, args.plot)
        print(f"\nwrote {args.plot}")
    return 0


def _audit(args: argparse.Namespace) -> int:
    from fog_gym.experiments.audit import figure, report, run_audit

    if args.frames < 1:
        raise _fail("audit", "--frames must be >= 1")
    result = run_audit(args.frames, args.resolution, args.seed)
    text = report(result)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "audit.md").write_text(text + "\n")
    figure(result, args.out / "audit.png")
    print(text)
    print(f"\nwrote {args.out / 'audit.md'} and {args.out / 'audit.png'}")
    return 0


def _demo(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    paths = run_demo(args)
    print(f"wrote {', '.join(str(p) for p in paths)} in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
