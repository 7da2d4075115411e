"""Experiment 2 end to end: defog-then-detect vs train-on-fog on the front and left cameras (paper §5).

Pipelines, with one detector architecture and one set of hyper-parameters throughout:

* **A** clean → clean: a detector trained on clean frames, tested on clean frames (the upper bound);
* **B** clean → fog: the same detector on fogged frames (the degradation baseline);
* **C** clean → dehazer → detector: the same detector on dehazed fogged frames, for each dehazer — Dark Channel
  Prior (:func:`fog_gym.perception.dehaze.dcp`), AOD-Net trained from scratch on the train split's (clean, fog) pairs (the
  paper's "fine-tuned" variant; no pretrained weights can be downloaded here) and, beyond the paper, the
  Koschmieder oracle (:func:`fog_gym.perception.dehaze.oracle`, the exact inverse from depth, α and airlight: the upper
  bound of any dehazer);
* **D** fog → fog: a separate detector trained on each fog level, tested on that level.

Scenes are subsampled uniformly per split (paper 15 / 20 / 20 % of train / val / test); every ``every``-th sample
of a chosen scene is used, from each camera. Dehazers work on the full-resolution frame; then every image is
resized to the detector's input size, where detection runs and PSNR / SSIM against the paired clean frame are
measured. Each detector keeps its best-mAP@0.5 epoch on its own validation input (early stopping's
selection). A trained model is kept in ``out/models/<name>.pt`` with its settings, and a second run with the same
settings reuses it (a long run survives interruption).

The oracle needs the airlight the fog was made with: by day fog-gym estimates it from the first clean frame of
the episode (:func:`fog_gym.fog.atmospheric_light`), at night from that frame and its depth
(:func:`fog_gym.fog.night_airlight`), and sample 0 of a scene is that frame, so the oracle recomputes it exactly;
the night glow around lamps (:func:`fog_gym.fog.add_glow`) is not inverted.
"""

from __future__ import annotations

import copy
import json
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import torch

from fog_gym.dataset.access import FogDrive
from fog_gym.dataset.decode import load_channel
from fog_gym.experiments.defog.model import STRIDE, CenterNet2D, decode, loss_fn, make_targets
from fog_gym.experiments.detection3d.model import optimizer_step

CAMERAS = ("CAM_FRONT", "CAM_LEFT")
LEVELS = ("light", "moderate", "dense")
DEHAZERS = ("DCP", "AOD-Net", "oracle")
FOV = 100.0  # the FogDrive cameras' horizontal field of view [deg] (supplementary D5)
METRICS = ("mAP50", "mAP50_95", "precision", "recall")


@dataclass(frozen=True)
class Exp2Config:
    """Budget and optimisation settings (AdamW with a one-cycle learning rate)."""

    epochs: int = 20
    batch_size: int = 16
    lr: float = 2e-3
    weight_decay: float = 1e-4
    every: int = 2  # every n-th sample of a train / val scene (samples are 0.1 s apart)
    test_every: int = 2
    eval_every: int = 1
    input_size: tuple[int, int] = (320, 240)  # detector input (W, H)
    width: int = 24
    train_fraction: float = 0.15
    val_fraction: float = 0.2
    test_fraction: float = 0.2
    aod_epochs: int = 10
    aod_pairs: int = 600  # (clean, fog) training pairs for AOD-Net, random crops of the full frame
    cameras: tuple[str, ...] = CAMERAS
    seed: int = 0
    device: str = "auto"
    threshold: float = 0.001  # detections kept for COCO evaluation (the paper's validation confidence)
    #: Ground-truth boxes lower than this many pixels *at the detector input* are ignore regions in evaluation
    #: (COCO crowd: neither hit nor miss); 0 evaluates every box, as the paper does at 1280 × 960.
    min_height: float = 0.0
    #: Photometric augmentation of the detectors' training images: random hue, saturation and value gains within
    #: ±(h, s, v) — Ultralytics' defaults (0.015, 0.7, 0.4), part of the paper's "default augmentations"; zeros
    #: switch it off (horizontal flips always apply).
    hsv: tuple[float, float, float] = (0.015, 0.7, 0.4)

    def __post_init__(self) -> None:
        for name in ("epochs", "batch_size", "every", "test_every", "eval_every", "width", "aod_epochs", "aod_pairs"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        w, h = self.input_size
        if w % (4 * STRIDE) or h % (4 * STRIDE) or w < 32 or h < 32:
            raise ValueError(f"input_size must be (W, H), both multiples of 16 and >= 32, got {self.input_size}")
        for name in ("train_fraction", "val_fraction", "test_fraction"):
            if not 0 < getattr(self, name) <= 1:
                raise ValueError(f"{name} must lie in (0, 1], got {getattr(self, name)}")
        if not self.lr > 0:
            raise ValueError(f"lr must be > 0, got {self.lr}")
        if len(self.hsv) != 3 or not all(isinstance(g, (int, float)) and 0 <= g <= 1 for g in self.hsv):
            raise ValueError(f"hsv must be three gains in [0, 1] (hue, saturation, value), got {self.hsv!r}")
        object.__setattr__(self, "hsv", tuple(float(g) for g in self.hsv))
        if not (isinstance(self.min_height, (int, float)) and 0 <= self.min_height < h):
            raise ValueError(f"min_height must lie in [0, input height {h}), got {self.min_height!r}")
        bad = [c for c in self.cameras if c not in ("CAM_FRONT", "CAM_BACK", "CAM_LEFT", "CAM_RIGHT")]
        if bad or not self.cameras:
            raise ValueError(f"cameras must name FogDrive cameras, got {list(self.cameras)}")


@dataclass(frozen=True)
class Frame:
    """One camera image of one sample, and the first sample of its scene (the airlight's frame)."""

    scene: str
    sample: str
    first: str
    camera: str


def choose_scenes(names: Sequence[str], fraction: float, seed: int) -> list[str]:
    """A uniform random ``fraction`` of the scenes (at least one), sorted.

    >>> choose_scenes([f"s{i}" for i in range(10)], 0.2, 0)
    ['s4', 's6']
    """
    names = sorted(names)
    if not names:
        raise ValueError("the split has no scenes")
    k = max(1, int(round(len(names) * fraction)))
    return sorted(names[i] for i in np.random.default_rng(seed).permutation(len(names))[:k])


def frames(ds: FogDrive, scenes: Sequence[str], every: int, cameras: Sequence[str]) -> list[Frame]:
    out = []
    for name in scenes:
        samples = ds.get_samples_for_scene(ds.get_scene_by_name(name)["token"])
        out += [Frame(name, s["token"], samples[0]["token"], cam) for s in samples[::every] for cam in cameras]
    return out


def channel(camera: str, level: str) -> str:
    """The image channel of a camera at a fog level ("clean" or a level name)."""
    return camera if level == "clean" else f"{camera}_FOG_{level.upper()}"


def load_image(ds: FogDrive, f: Frame, level: str) -> np.ndarray:
    ch = channel(f.camera, level)
    return load_channel(ch, ds.get_sample_paths(f.sample, [ch])[ch])


def load_boxes(ds: FogDrive, f: Frame) -> tuple[np.ndarray, np.ndarray]:
    """Ground-truth boxes ``(N, 4)`` ``[x0, y0, x1, y1]`` in pixels (edges; the file's corners are inclusive pixel
    indices) and their classes."""
    ch = f"{f.camera}_BBOX"
    b = load_channel(ch, ds.get_sample_paths(f.sample, [ch])[ch])
    corners = b["bboxes"].reshape(-1, 4).astype(np.float64)
    return corners + np.array([0.0, 0.0, 1.0, 1.0]), b["vehicle_class"]


def resize(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    return image if image.shape[1::-1] == tuple(size) else cv2.resize(image, size, interpolation=cv2.INTER_AREA)


def intrinsic(width: int, height: int) -> np.ndarray:
    """K of a FogDrive camera of this size (square pixels, principal point at the centre)."""
    f = width / (2.0 * math.tan(math.radians(FOV) / 2.0))
    return np.array([[f, 0.0, width / 2.0], [0.0, f, height / 2.0], [0.0, 0.0, 1.0]])


class OracleDehazer:
    """The exact inverse of fog-gym's camera fog for frames of a dataset (module docstring)."""

    def __init__(self, ds: FogDrive) -> None:
        self.ds = ds
        self._airlight: dict[tuple[str, str], np.ndarray] = {}

    def airlight(self, f: Frame) -> np.ndarray:
        from fog_gym.fog import atmospheric_light, night_airlight

        key = (f.first, f.camera)
        if key not in self._airlight:
            first = Frame(f.scene, f.first, f.first, f.camera)
            rgb = load_image(self.ds, first, "clean")
            if "_night_" in f.scene:
                depth_ch = f"{f.camera}_DEPTH"
                depth = load_channel(depth_ch, self.ds.get_sample_paths(f.first, [depth_ch])[depth_ch])
                self._airlight[key] = night_airlight(rgb, depth)
            else:
                self._airlight[key] = atmospheric_light(rgb)
        return self._airlight[key]

    def __call__(self, fogged: np.ndarray, f: Frame, level: str) -> np.ndarray:
        from fog_gym.perception.dehaze import oracle
        from fog_gym.fog import parse_fog

        depth_ch = f"{f.camera}_DEPTH"
        depth = load_channel(depth_ch, self.ds.get_sample_paths(f.sample, [depth_ch])[depth_ch])
        h, w = depth.shape
        return oracle(fogged, depth, intrinsic(w, h), parse_fog(level).alpha, self.airlight(f))


# -- detector training and evaluation ----------------------------------------------------------------------------
def augment_hsv(image: np.ndarray, gains: Sequence[float], rng: np.random.Generator) -> np.ndarray:
    """Ultralytics-style colour jitter of a uint8 RGB image: hue, saturation and value multiplied by random gains
    in ``1 ± gains`` (hue wraps around), through lookup tables.

    >>> img = np.full((2, 2, 3), 128, np.uint8)  # grey has no hue or saturation to change
    >>> out = augment_hsv(img, (0.5, 0.5, 0.0), np.random.default_rng(0))
    >>> bool((out == img).all())
    True
    """
    r = rng.uniform(-1.0, 1.0, 3) * np.asarray(gains, np.float64) + 1.0
    hue, sat, val = cv2.split(cv2.cvtColor(image, cv2.COLOR_RGB2HSV))
    x = np.arange(256, dtype=np.float64)
    lut_h = ((x * r[0]) % 180).astype(np.uint8)
    lut_s = np.clip(x * r[1], 0, 255).astype(np.uint8)
    lut_v = np.clip(x * r[2], 0, 255).astype(np.uint8)
    hsv = cv2.merge((cv2.LUT(hue, lut_h), cv2.LUT(sat, lut_s), cv2.LUT(val, lut_v)))
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)


class ImageSet(torch.utils.data.Dataset):
    """Frames at a fog level, resized to the input size, with CenterNet targets; horizontal flips and the ``hsv``
    colour jitter (:func:`augment_hsv`) when ``augment``."""

    def __init__(self, ds: FogDrive, items: Sequence[Frame], level: str, size: tuple[int, int], augment: bool = False,
                 seed: int = 0, hsv: Sequence[float] = (0.0, 0.0, 0.0)) -> None:  # fmt: skip
        self.ds, self.items, self.level, self.size, self.augment = ds, list(items), level, tuple(size), augment
        self.hsv = tuple(hsv)
        self.rng = np.random.default_rng(seed)

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, i: int):
        f = self.items[i]
        img = load_image(self.ds, f, self.level)
        boxes, classes = load_boxes(self.ds, f)
        h0, w0 = img.shape[:2]
        w, h = self.size
        img = resize(img, self.size)
        boxes = boxes * np.array([w / w0, h / h0, w / w0, h / h0])
        if self.augment and any(self.hsv):
            img = augment_hsv(img, self.hsv, self.rng)
        if self.augment and self.rng.random() < 0.5:
            img = np.ascontiguousarray(img[:, ::-1])
            boxes = np.stack([w - boxes[:, 2], boxes[:, 1], w - boxes[:, 0], boxes[:, 3]], 1)
        return img, make_targets(boxes, classes, (h // STRIDE, w // STRIDE))


def collate(batch):
    """Images ``(B, 3, H, W)`` in [0, 1], heatmaps, and the flat indices and regression targets of every centre."""
    imgs = torch.from_numpy(np.stack([b[0] for b in batch]).transpose(0, 3, 1, 2).copy()).float() / 255.0
    heat = torch.from_numpy(np.stack([b[1]["heatmap"] for b in batch]))
    bidx = torch.cat([torch.full((len(b[1]["index"]),), i, dtype=torch.long) for i, b in enumerate(batch)])
    cidx = torch.from_numpy(np.concatenate([b[1]["index"] for b in batch]).astype(np.int64))
    wh = torch.from_numpy(np.concatenate([b[1]["wh"] for b in batch]).reshape(-1, 2))
    off = torch.from_numpy(np.concatenate([b[1]["offset"] for b in batch]).reshape(-1, 2))
    return imgs, heat, bidx, cidx, wh, off


@torch.no_grad()
def detect(model: torch.nn.Module, images: Sequence[np.ndarray], scale: Sequence[tuple[float, float]],
           device: torch.device, threshold: float, batch_size: int = 32) -> list[dict[str, np.ndarray]]:  # fmt: skip
    """Detections per input-size image; boxes multiplied by each image's ``scale`` (back to original pixels)."""
    model.eval()
    out: list[dict[str, np.ndarray]] = []
    for i in range(0, len(images), batch_size):
        chunk = np.stack(images[i : i + batch_size])
        x = torch.from_numpy(chunk.transpose(0, 3, 1, 2).copy()).float().div(255.0).to(device)
        o = model(x)
        for k, d in enumerate(decode(o, threshold)):
            sx, sy = scale[i + k]
            d["boxes"] = d["boxes"] * np.array([sx, sy, sx, sy])
            out.append(d)
    return out


def train_detector(train: ImageSet, val_images: list[np.ndarray], val_gt: list[dict], val_scale: list,
                   config: Exp2Config, device: torch.device, name: str, tb_dir: Path | None = None,
                   progress: bool = True) -> tuple[CenterNet2D, dict[str, Any]]:  # fmt: skip
    """Train on ``train``; keep the epoch with the best validation mAP@0.5. Returns the model and a summary."""
    from tqdm import tqdm

    from fog_gym.metrics.detection2d import evaluate_coco

    torch.manual_seed(config.seed)
    model = CenterNet2D(width=config.width).to(device)
    loader = torch.utils.data.DataLoader(train, config.batch_size, shuffle=True, collate_fn=collate,
                                         generator=torch.Generator().manual_seed(config.seed))  # fmt: skip
    opt = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, config.lr, total_steps=config.epochs * len(loader))
    tb = None
    if tb_dir is not None:
        from torch.utils.tensorboard import SummaryWriter

        tb = SummaryWriter(str(tb_dir))
    best, best_state, history, step, t0 = -1.0, None, [], 0, time.perf_counter()
    bar = tqdm(total=config.epochs * len(loader), desc=f"train {name} ({len(train)} images)", unit="batch",
               disable=not progress)  # fmt: skip
    for epoch in range(config.epochs):
        model.train()
        for imgs, heat, bidx, cidx, wh, off in loader:
            o = model(imgs.to(device))
            loss, _ = loss_fn(o, heat.to(device), bidx.to(device), cidx.to(device), wh.to(device), off.to(device))
            value = optimizer_step(loss, opt, sched, bar)
            step += 1
            if tb is not None:
                tb.add_scalar("loss", value, step)
        if (epoch + 1) % config.eval_every and epoch + 1 != config.epochs:
            continue
        r = evaluate_coco(val_gt, detect(model, val_images, val_scale, device, config.threshold))
        score = r["mAP50"] if not math.isnan(r["mAP50"]) else -1.0
        history.append({"epoch": epoch + 1, "val_mAP50": score})
        if tb is not None:
            tb.add_scalar("val/mAP50", score, epoch + 1)
        if score > best:
            best, best_state = score, copy.deepcopy(model.state_dict())
    bar.close()
    if tb is not None:
        tb.close()
    model.load_state_dict(best_state)
    best_epoch = max(history, key=lambda h: h["val_mAP50"])["epoch"]
    return model, {"images": len(train), "seconds": time.perf_counter() - t0, "best_epoch": best_epoch,
                   "val_mAP50": best, "history": history}  # fmt: skip


# -- the protocol -------------------------------------------------------------------------------------------------
def _device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(name)


def _settings(config: Exp2Config) -> dict[str, Any]:
    kept = {k: v for k, v in asdict(config).items() if k != "device"}
    return json.loads(json.dumps(kept))


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def _eval_set(ds: FogDrive, items: list[Frame], level: str, size: tuple[int, int],
              transform: Callable[[np.ndarray, Frame], np.ndarray] | None = None, desc: str | None = None,
              progress: bool = False, min_height: float = 0.0) -> tuple[list, list, list]:  # fmt: skip
    """Input-size images (optionally transformed at full resolution first), ground truth (boxes lower than
    ``min_height`` input pixels marked ``ignore``) and scales."""
    from tqdm import tqdm

    images, gts, scales = [], [], []
    for f in tqdm(items, desc=desc, disable=not (progress and desc)):
        img = load_image(ds, f, level)
        if transform is not None:
            img = transform(img, f)
        h0, w0 = img.shape[:2]
        boxes, classes = load_boxes(ds, f)
        images.append(resize(img, size))
        gts.append({"boxes": boxes, "classes": classes, "ignore": (boxes[:, 3] - boxes[:, 1]) * size[1] / h0 < min_height})
        scales.append((w0 / size[0], h0 / size[1]))
    return images, gts, scales


def run_experiment2(root: str | Path, out: str | Path, config: Exp2Config = Exp2Config(), progress: bool = True,
                    log=print) -> dict[str, Any]:  # fmt: skip
    """Run pipelines A–D on the dataset at ``root``; writes ``results.json``, ``exp2.md``, ``exp2.png`` and
    TensorBoard logs under ``out``; returns the results."""
    from tqdm import tqdm

    from fog_gym.perception.dehaze import dcp
    from fog_gym.perception.aodnet import AODNet, dehaze as aod_dehaze, train_aodnet
    from fog_gym.metrics.detection2d import evaluate_coco
    from fog_gym.metrics.image_quality import psnr, ssim

    out = Path(out)
    ds = FogDrive(root)
    splits = ds.splits or {}
    if not all(splits.get(s) for s in ("train", "val", "test")):
        raise ValueError(f"{root}: Experiment 2 needs train, val and test scenes in index/splits.json")
    missing = [c for cam in config.cameras for c in (cam, f"{cam}_BBOX", f"{cam}_DEPTH", *(channel(cam, lv) for lv in LEVELS))
               if c not in ds.list_channels()]  # fmt: skip
    if missing:
        raise ValueError(f"{root}: Experiment 2 needs the camera channels {missing} (generate with --modality full)")
    device = _device(config.device)
    size = tuple(config.input_size)
    chosen = {s: choose_scenes(splits[s], getattr(config, f"{s}_fraction"), config.seed + i)
              for i, s in enumerate(("train", "val", "test"))}  # fmt: skip
    train_f = frames(ds, chosen["train"], config.every, config.cameras)
    val_f = frames(ds, chosen["val"], config.every, config.cameras)
    test_f = frames(ds, chosen["test"], config.test_every, config.cameras)
    (out / "models").mkdir(parents=True, exist_ok=True)
    settings = _settings(config)
    results: dict[str, Any] = {"config": settings, "device": str(device), "scenes": chosen,
                               "images": {"train": len(train_f), "val": len(val_f), "test": len(test_f)},
                               "detectors": {}, "detection": {}, "image_quality": {}}  # fmt: skip

    def detector(name: str, level: str) -> CenterNet2D:
        path, meta_path = out / "models" / f"detector_{name}.pt", out / "models" / f"detector_{name}.json"
        model = CenterNet2D(width=config.width).to(device)
        if path.exists() and meta_path.exists():
            meta = json.loads(meta_path.read_text())
            if meta["config"] != settings or meta["scenes"] != chosen:
                raise ValueError(f"{meta_path} was written with other settings or scenes; use another --out")
            model.load_state_dict(torch.load(path, map_location=device))
            results["detectors"][name] = meta["summary"]
            log(f"detector {name}: kept from {path}")
            return model
        vi, vg, vs = _eval_set(ds, val_f, level, size, min_height=config.min_height)
        model, summary = train_detector(ImageSet(ds, train_f, level, size, augment=True, seed=config.seed, hsv=config.hsv), vi, vg, vs,
                                        config, device, name, out / "tb" / name, progress)  # fmt: skip
        torch.save(model.state_dict(), path)
        _write_atomic(meta_path, json.dumps({"config": settings, "scenes": chosen, "summary": summary}, indent=1))
        results["detectors"][name] = summary
        log(f"detector {name}: {summary['images']} images, {summary['seconds']:.0f} s, val mAP@0.5 "
            f"{summary['val_mAP50']:.3f} at epoch {summary['best_epoch']}")  # fmt: skip
        return model

    def score(model: CenterNet2D, images, gts, scales) -> dict[str, Any]:
        r = evaluate_coco(gts, detect(model, images, scales, device, config.threshold))
        return {k: r[k] for k in (*METRICS, "n_gt", "n_pred")} | {"AP50": {str(c): v for c, v in r["AP50"].items()}}

    # AOD-Net on the train split's (clean, fog) pairs: random full-resolution crops, every level
    aod_path, aod_meta = out / "models" / "aodnet.pt", out / "models" / "aodnet.json"
    aod = AODNet().to(device)
    aod_keys = ("aod_epochs", "aod_pairs", "batch_size", "seed", "input_size", "every", "train_fraction", "cameras")
    aod_settings = {k: settings[k] for k in aod_keys}
    if aod_path.exists() and aod_meta.exists() and {k: json.loads(aod_meta.read_text())["config"].get(k) for k in aod_keys} == aod_settings:
        aod.load_state_dict(torch.load(aod_path, map_location=device))
        log(f"AOD-Net: kept from {aod_path}")
    else:
        rng = np.random.default_rng(config.seed)
        n_all = len(train_f) * len(LEVELS)  # every (frame, level) pair once at most
        clean, foggy = [], []
        for i in tqdm(rng.choice(n_all, min(config.aod_pairs, n_all), replace=False), desc="AOD-Net pairs",
                      disable=not progress):  # fmt: skip
            f, lv = train_f[i % len(train_f)], LEVELS[i // len(train_f)]
            c, g = load_image(ds, f, "clean"), load_image(ds, f, lv)
            ch, cw = min(c.shape[0], size[1]), min(c.shape[1], size[0])
            y, x = rng.integers(0, c.shape[0] - ch + 1), rng.integers(0, c.shape[1] - cw + 1)
            clean.append(c[y : y + ch, x : x + cw])
            foggy.append(g[y : y + ch, x : x + cw])
        t0 = time.perf_counter()
        aod, losses = train_aodnet(np.stack(clean), np.stack(foggy), epochs=config.aod_epochs,
                                   batch_size=config.batch_size, seed=config.seed, device=str(device), progress=progress)  # fmt: skip
        torch.save(aod.state_dict(), aod_path)
        _write_atomic(aod_meta, json.dumps({"config": settings, "losses": losses, "seconds": time.perf_counter() - t0}))
        log(f"AOD-Net: {len(clean)} pairs, {time.perf_counter() - t0:.0f} s, final loss {losses[-1]:.4f}")
    oracle_fn = OracleDehazer(ds)
    dehazers: dict[str, Callable[[np.ndarray, Frame, str], np.ndarray]] = {
        "DCP": lambda img, f, lv: dcp(img),
        "AOD-Net": lambda img, f, lv: aod_dehaze(aod, img),
        "oracle": oracle_fn,
    }

    clean_model = detector("clean", "clean")
    clean_set = _eval_set(ds, test_f, "clean", size, min_height=config.min_height)
    results["detection"]["A"] = {"clean": score(clean_model, *clean_set)}
    results["detection"].update({"B": {}, **{f"C-{d}": {} for d in DEHAZERS}, "D": {}})
    for lv in LEVELS:
        fog_set = _eval_set(ds, test_f, lv, size, min_height=config.min_height)
        results["detection"]["B"][lv] = score(clean_model, *fog_set)
        iq = {"foggy": _quality(fog_set[0], clean_set[0], psnr, ssim)}
        for name, fn in dehazers.items():
            t0 = time.perf_counter()
            deh = _eval_set(ds, test_f, lv, size, transform=lambda img, f, fn=fn, lv=lv: fn(img, f, lv),
                            desc=f"{name} on {lv}", progress=progress, min_height=config.min_height)  # fmt: skip
            iq[name] = _quality(deh[0], clean_set[0], psnr, ssim) | {"seconds_per_image": (time.perf_counter() - t0) / max(1, len(test_f))}
            results["detection"][f"C-{name}"][lv] = score(clean_model, *deh)
        results["image_quality"][lv] = iq
        results["detection"]["D"][lv] = score(detector(lv, lv), *fog_set)
        log(f"{lv}: mAP@0.5 B {results['detection']['B'][lv]['mAP50']:.3f}, "
            + ", ".join(f"C-{d} {results['detection'][f'C-{d}'][lv]['mAP50']:.3f}" for d in DEHAZERS)
            + f", D {results['detection']['D'][lv]['mAP50']:.3f}")  # fmt: skip
    _write_atomic(out / "results.json", json.dumps(results, indent=1))
    _write_atomic(out / "exp2.md", markdown(results))
    figure(results, out / "exp2.png")
    return results


def _quality(images: list[np.ndarray], reference: list[np.ndarray], psnr, ssim) -> dict[str, float]:
    """Mean PSNR (finite values; identical pairs are left out) and SSIM against the paired clean frames."""
    p = [psnr(a, b) for a, b in zip(images, reference, strict=True)]
    finite = [v for v in p if math.isfinite(v)]
    return {"PSNR": float(np.mean(finite)) if finite else float("inf"),
            "SSIM": float(np.mean([ssim(a, b) for a, b in zip(images, reference, strict=True)]))}  # fmt: skip


PIPELINE_NAMES = {"A": "A (clean→clean)", "B": "B (clean→fog)", "C-DCP": "C – DCP", "C-AOD-Net": "C – AOD-Net (trained here)",
                  "C-oracle": "C – oracle", "D": "D (fog→fog)"}  # fmt: skip


def markdown(results: dict[str, Any]) -> str:
    """The detection table and the image-quality table, shaped like the paper's."""
    det = results["detection"]
    lines = ["**Detection** (COCO evaluation; P and R at confidence 0.25; AP@0.5 per class)", "",
             "| Pipeline | Fog | mAP@0.5 | mAP@.5:.95 | P | R | car | truck | bigger car |", "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for key, name in PIPELINE_NAMES.items():
        for lv, r in det.get(key, {}).items():
            ap = {int(k): v for k, v in r["AP50"].items()}
            cls = [f"{ap[c]:.3f}" if c in ap else "–" for c in (0, 1, 4)]
            lines.append(f"| {name} | {lv} | {r['mAP50']:.3f} | {r['mAP50_95']:.3f} | {r['precision']:.3f} | "
                         f"{r['recall']:.3f} | " + " | ".join(cls) + " |")  # fmt: skip
    iq = results["image_quality"]
    levels = list(iq)
    lines += ["", "**Image quality** against the paired clean frame (at the detector's input size)", "",
              "| Method | " + " | ".join(f"PSNR {lv}" for lv in levels) + " | " + " | ".join(f"SSIM {lv}" for lv in levels) + " |",
              "|---|" + "---|" * (2 * len(levels))]  # fmt: skip
    for method in ("foggy", *DEHAZERS):
        lines.append(f"| {method} | " + " | ".join(f"{iq[lv][method]['PSNR']:.2f}" for lv in levels) + " | "
                     + " | ".join(f"{iq[lv][method]['SSIM']:.3f}" for lv in levels) + " |")  # fmt: skip
    return "\n".join(lines) + "\n"


def figure(results: dict[str, Any], path: Path) -> None:
    """mAP@0.5 per pipeline and level (bars) and image quality against detection (scatter)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    det, iq = results["detection"], results["image_quality"]
    levels = list(iq)
    keys = ["B", "C-DCP", "C-AOD-Net", "C-oracle", "D"]
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 4))
    width = 0.8 / len(keys)
    for i, k in enumerate(keys):
        ax.bar(np.arange(len(levels)) + i * width, [det[k][lv]["mAP50"] for lv in levels], width, label=PIPELINE_NAMES[k])
    ax.axhline(det["A"]["clean"]["mAP50"], color="k", ls="--", lw=1, label="A (clean→clean)")
    ax.set_xticks(np.arange(len(levels)) + 0.4 - width / 2, levels)
    ax.set_ylabel("mAP@0.5")
    ax.set_title("Detection per pipeline and fog level")
    ax.legend(fontsize=7)
    markers = {"light": "o", "moderate": "s", "dense": "^"}
    for method, key in (("foggy", "B"), ("DCP", "C-DCP"), ("AOD-Net", "C-AOD-Net"), ("oracle", "C-oracle")):
        for lv in levels:
            ax2.scatter(iq[lv][method]["PSNR"], det[key][lv]["mAP50"], marker=markers.get(lv, "o"),
                        color=f"C{['foggy', 'DCP', 'AOD-Net', 'oracle'].index(method)}",
                        label=f"{method}" if lv == levels[0] else None)  # fmt: skip
    ax2.set_xlabel("PSNR against the clean frame [dB]  (○ light, □ moderate, △ dense)")
    ax2.set_ylabel("mAP@0.5 of the clean-trained detector")
    ax2.set_title("Image quality vs detection")
    ax2.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
