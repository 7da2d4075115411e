"""``FogDriveDataset``: a PyTorch dataset over a FogDrive root (needs the ``torch`` extra).

Decoding lives in :mod:`fog_gym.dataset.decode` and :func:`load_sample` (no torch needed): RGB → uint8 (H, W, 3), depth PNG → float32 metres,
segmentation PNG → uint8 tag ids (red channel), ``.npy`` → float32 points, bbox JSON → arrays.
:func:`collate` batches fixed-size images by stacking and keeps variable-size point clouds and box lists as
lists (one entry per sample).

Example:
    >>> from fog_gym.dataset.decode import decode_bbox_json
    >>> decode_bbox_json(b'{"bboxes": [[[1, 2], [3, 4]]], "vehicle_ids": [7], "vehicle_class": [0]}')["bboxes"].shape
    (1, 2, 2)
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from fog_gym.dataset.access import SPLITS, FogDrive
from fog_gym.dataset.decode import load_channel
from fog_gym.dataset.layout import FOGDRIVE_CHANNELS, ChannelSpec

try:  # the torch extra; everything but FogDriveDataset works without it
    import torch
    from torch.utils.data import Dataset as _TorchDataset
except ImportError:  # pragma: no cover - exercised where torch is absent
    torch = None
    _TorchDataset = object


def load_sample(ds: FogDrive, sample_token: str, channels: list[str] | None = None) -> dict[str, Any]:
    """Every requested channel of one sample, decoded as the dataset's layout (``ds.channels``) says."""
    return {c: load_channel(c, p, ds.channels[c]) for c, p in ds.get_sample_paths(sample_token, channels).items()}


class FogDriveDataset(_TorchDataset):
    """Samples of a split (or all) with the chosen channels, decoded; images become tensors (C, H, W).

    >>> # ds = FogDriveDataset("out/fogdrive", split="train", channels=["CAM_FRONT_FOG_DENSE", "BBOX_3D"])
    >>> # loader = torch.utils.data.DataLoader(ds, batch_size=4, collate_fn=ds.collate)
    """

    def __init__(self, dataroot: str | Path, split: str | None = None, channels: list[str] | None = None) -> None:
        if torch is None:
            raise ImportError("FogDriveDataset needs PyTorch: pip install -e '.[torch]'")
        if split is not None and split not in SPLITS:
            raise ValueError(f"split must be one of {SPLITS} or None, got {split!r}")
        self.fogdrive = FogDrive(dataroot)
        #: The dataset's layout (its rig's channels; the FogDrive ones for a FogDrive set).
        self.layout: dict[str, ChannelSpec] = self.fogdrive.channels
        for c in channels or []:
            if c not in self.layout:
                raise ValueError(f"channels must be FogDrive channel names or the dataset's own (its layout, "
                                 f"index/channels.json), got {c!r}; the dataset has {sorted(self.layout)}")  # fmt: skip
        self.channels = list(channels) if channels else sorted(self.layout)
        self.tokens = (self.fogdrive.get_sample_tokens_for_split(split) if split
                       else [s["token"] for s in self.fogdrive.sample])  # fmt: skip

    def __len__(self) -> int:
        return len(self.tokens)

    def __getitem__(self, i: int) -> dict[str, Any]:
        out: dict[str, Any] = {"sample_token": self.tokens[i]}
        for c, value in load_sample(self.fogdrive, self.tokens[i], self.channels).items():
            if isinstance(value, np.ndarray) and value.ndim == 3:  # RGB → (3, H, W) uint8
                out[c] = torch.from_numpy(np.ascontiguousarray(value.transpose(2, 0, 1)))
            elif isinstance(value, np.ndarray):
                out[c] = torch.from_numpy(np.ascontiguousarray(value))
            else:
                out[c] = {k: torch.from_numpy(v) for k, v in value.items()}
        return out


    def collate(self, batch: list[dict[str, Any]]) -> dict[str, Any]:
        """:func:`collate` under this dataset's layout (added cameras' images are stacked too)."""
        return collate(batch, self.layout)


def collate(batch: list[dict[str, Any]], layout: dict[str, ChannelSpec] | None = None) -> dict[str, Any]:
    """Stack images and depth/semantic maps; keep point clouds, box dicts and tokens as per-sample lists.

    ``layout`` (default: the FogDrive channels; a dataset's is ``FogDriveDataset.layout``, or use
    :meth:`FogDriveDataset.collate`) says which keys are images; other keys stay lists."""
    layout = FOGDRIVE_CHANNELS if layout is None else layout
    out: dict[str, Any] = {}
    for key in batch[0]:
        values = [b[key] for b in batch]
        fmt = layout[key].fileformat if key in layout else ""
        out[key] = torch.stack(values) if fmt == "png" else values
    return out
