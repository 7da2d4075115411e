"""A PointPillars encoder with CenterPoint heads, in pure PyTorch (CPU or CUDA), trained from scratch.

Written from the papers: PointPillars (Lang et al., CVPR 2019) for the encoder and backbone, CenterPoint (Yin,
Zhou, Krähenbühl, CVPR 2021) for the heads and their decoding.

* **Pillar feature net**: every point of a pillar, decorated to nine features (:func:`~.pillars.pillar_points`:
  x, y, z, r, offsets to the pillar's mean and to its centre), goes through a shared linear layer, batch norm and
  ReLU (PointNet); the pillar keeps the maximum over its points of every channel. Computed over the points
  themselves (``scatter_reduce``), not over a zero-padded ``(P, N, 9)`` tensor: the same maximum, without the
  padding's work.
* **Scatter** of the pillars' vectors to a ``(C, H, W)`` pseudo-image at their grid cells.
* **Backbone**: three blocks ``(S, L, F)`` of 3 × 3 convolutions with batch norm and ReLU, the first strided:
  ``(stride, layers[0], widths[0])``, ``(2, layers[1], widths[1])``, ``(2, layers[2], widths[2])``.
* **Neck**: each block's output brought to the output stride by a (transposed) convolution with batch norm and
  ReLU, ``up`` channels each, concatenated (the multi-scale feature map).
* **Heads** (CenterPoint): a shared 1 × 1 then 3 × 3 convolution (``head`` channels), then per output a 3 × 3
  convolution and a 1 × 1 convolution: the class heatmap (Gaussian focal loss, bias −2.19) and the eight regression
  channels at the centre cells — sub-cell offset (2), z (1), log size (3), sin and cos of the yaw (2) — with an L1
  loss weighted ``0.25`` (CenterPoint's). Decoding: 3 × 3 local maxima of the heatmap above a score threshold
  (:func:`~.model.decode`, shared with the small BEV detector).

:class:`PillarConfig` holds the widths, the grid and the range; ``PillarConfig()`` is the CPU configuration and
:data:`GPU_PILLARS` the GPU one.

Example:
    >>> cfg = PillarConfig(range_m=8.0, cell_m=0.5, widths=(8, 8, 8), layers=(1, 1, 1), pfn=8, up=8, head=8)
    >>> net = PillarCenterPoint(cfg)
    >>> feats = torch.zeros(5, 9); pillar = torch.tensor([0, 0, 1, 1, 1]); cells = torch.tensor([3, 40])
    >>> out = net(feats, pillar, cells, torch.tensor([0, 1]), batch_size=2)
    >>> tuple(out["heatmap"].shape), tuple(out["regression"].shape)
    ((2, 3, 16, 16), (2, 8, 16, 16))
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import torch
import torch.nn as nn

from fog_gym.experiments.detection3d.bev import CLASSES, BEVGrid
from fog_gym.experiments.detection3d.pillars import POINT_FEATURES


@dataclass(frozen=True)
class PillarConfig:
    """The pillar detector's grid (``±range_m``, pillars of ``cell_m``, z from ``z_min`` to ``z_max`` in the LiDAR
    frame, outputs every ``stride`` pillars), its caps and its widths. The default is the CPU configuration."""

    range_m: float = 40.0
    cell_m: float = 0.4
    z_min: float = -3.0
    z_max: float = 2.0
    stride: int = 2
    max_points: int = 32
    pfn: int = 32
    widths: tuple[int, int, int] = (32, 64, 128)
    layers: tuple[int, int, int] = (3, 5, 5)
    up: int = 64
    head: int = 64

    def __post_init__(self) -> None:
        for name in ("stride", "max_points", "pfn", "up", "head"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        for name in ("widths", "layers"):
            v = tuple(getattr(self, name))
            if len(v) != 3 or any(isinstance(x, bool) or not isinstance(x, int) or x < 1 for x in v):
                raise ValueError(f"{name} must be three positive integers, got {list(v)!r}")
            object.__setattr__(self, name, v)
        grid = self.grid  # checks range, cell, z and that the grid divides into output cells
        if grid.shape[0] % (4 * self.stride):
            raise ValueError(f"the grid's {grid.shape[0]} pillars across must be a multiple of 4 × stride = "
                             f"{4 * self.stride} (three stride-2 blocks), got range_m {self.range_m} and cell_m "
                             f"{self.cell_m}")  # fmt: skip

    @property
    def grid(self) -> BEVGrid:
        return BEVGrid(self.range_m, self.cell_m, self.z_min, self.z_max, self.stride)

    def settings(self) -> dict:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}


#: The GPU configuration: 0.2 m pillars (400 × 400), PointPillars' widths (64, 128, 256) and 128-channel neck.
GPU_PILLARS = PillarConfig(cell_m=0.2, widths=(64, 128, 256), pfn=64, up=128, head=64)


def _conv(cin: int, cout: int, stride: int = 1, k: int = 3) -> list[nn.Module]:
    return [nn.Conv2d(cin, cout, k, stride, k // 2, bias=False), nn.BatchNorm2d(cout), nn.ReLU(inplace=True)]


def _block(cin: int, cout: int, stride: int, layers: int) -> nn.Sequential:
    mods = _conv(cin, cout, stride)
    for _ in range(layers - 1):
        mods += _conv(cout, cout)
    return nn.Sequential(*mods)


def _up(cin: int, cout: int, factor: int) -> nn.Sequential:
    if factor == 1:
        return nn.Sequential(*_conv(cin, cout, 1, 1))
    return nn.Sequential(nn.ConvTranspose2d(cin, cout, factor, factor, bias=False), nn.BatchNorm2d(cout),
                         nn.ReLU(inplace=True))  # fmt: skip


class PillarCenterPoint(nn.Module):
    """``forward(feats (M, 9), pillar (M,), cells (P,), batch (P,), batch_size)`` → ``{"heatmap": (B, K, H', W')
    logits, "regression": (B, 8, H', W')}``: ``pillar`` is each point's pillar (0 … P − 1), ``cells`` each
    pillar's flat grid cell and ``batch`` its sample."""

    def __init__(self, config: PillarConfig = PillarConfig(), classes: int = len(CLASSES)) -> None:
        super().__init__()
        c = self.config = config
        self.n = config.grid.shape[0]
        self.pfn = nn.Sequential(nn.Linear(POINT_FEATURES, c.pfn, bias=False), nn.BatchNorm1d(c.pfn), nn.ReLU())
        w = c.widths
        self.blocks = nn.ModuleList([_block(c.pfn, w[0], c.stride, c.layers[0]), _block(w[0], w[1], 2, c.layers[1]),
                                     _block(w[1], w[2], 2, c.layers[2])])  # fmt: skip
        self.ups = nn.ModuleList([_up(w[0], c.up, 1), _up(w[1], c.up, 2), _up(w[2], c.up, 4)])
        self.shared = nn.Sequential(*_conv(3 * c.up, c.head, 1, 1), *_conv(c.head, c.head))
        self.heat = nn.Sequential(*_conv(c.head, c.head), nn.Conv2d(c.head, classes, 1))
        self.reg = nn.Sequential(*_conv(c.head, c.head), nn.Conv2d(c.head, 8, 1))
        nn.init.constant_(self.heat[-1].bias, -2.19)  # prior 0.1, as CenterPoint

    def scatter(self, feats: torch.Tensor, pillar: torch.Tensor, cells: torch.Tensor, batch: torch.Tensor,
                batch_size: int) -> torch.Tensor:  # fmt: skip
        """The ``(B, C, H, W)`` pseudo-image (channels-last in memory) of the pillars' max-pooled PFN features."""
        x = self.pfn(feats)
        c = x.shape[1]
        pooled = torch.zeros(len(cells), c, dtype=x.dtype, device=x.device)
        pooled = pooled.scatter_reduce(0, pillar[:, None].expand(-1, c), x, "amax", include_self=False)
        canvas = torch.zeros(batch_size * self.n * self.n, c, dtype=x.dtype, device=x.device)
        canvas[batch * self.n * self.n + cells] = pooled
        return canvas.view(batch_size, self.n, self.n, c).permute(0, 3, 1, 2)

    def forward(self, feats: torch.Tensor, pillar: torch.Tensor, cells: torch.Tensor, batch: torch.Tensor,
                batch_size: int) -> dict[str, torch.Tensor]:  # fmt: skip
        x = self.scatter(feats, pillar, cells, batch, batch_size)
        outs = []
        for block, up in zip(self.blocks, self.ups, strict=True):
            x = block(x)
            outs.append(up(x))
        f = self.shared(torch.cat(outs, 1))
        return {"heatmap": self.heat(f).float(), "regression": self.reg(f).float()}


def macs_per_sweep(config: PillarConfig) -> float:
    """Multiply-accumulates of the 2D part (backbone, neck, heads) for one sweep, in GMAC (the pillar net's
    share depends on the points and is small)."""
    n = config.grid.shape[0]
    s = config.stride
    w, L = config.widths, config.layers
    sizes = [(n // s) ** 2, (n // s // 2) ** 2, (n // s // 4) ** 2]
    total = 0.0
    cin = config.pfn
    for k in range(3):
        total += sizes[k] * 9 * (cin * w[k] + (L[k] - 1) * w[k] * w[k])
        cin = w[k]
    out = sizes[0]
    total += out * (w[0] * config.up + w[1] * config.up + w[2] * config.up)  # 1 × 1, 2 × 2 / 2, 4 × 4 / 4 per output
    total += out * (3 * config.up * config.head + 9 * config.head * config.head * 3)
    return total / 1e9 if math.isfinite(total) else float("nan")
