"""DehazeFormer (Song, He, Qian, Du, "Vision Transformers for Single Image Dehazing", IEEE TIP 32, 2023) in PyTorch,
written from the paper: a five-stage U-net of Swin-style blocks modified for dehazing.

* **Stages**: widths ``(24, 48, 96, 48, 24)``, a 3 × 3 convolution embeds the image, a stride-2 convolution
  halves the resolution between the first three stages, a 1 × 1 convolution and a pixel shuffle double it back;
  the skip connections are fused with the upsampled path by selective-kernel attention (SK fusion: softmax
  weights over the two inputs from their pooled sum).
* **Block**: ``x + R(TokenMixer(N(x)))`` then ``x + R(MLP(N(x)))`` where ``N`` is **RescaleNorm** — each sample
  normalised by the mean μ and standard deviation σ of all its channels and pixels, with a learned affine — and
  ``R`` rescales the branch's output by ``W_σ σ + B_σ`` and shifts it by ``W_μ μ + B_μ`` (1 × 1 convolutions on
  the two scalars), so that the statistics the normalisation removed come back.
* **Token mixer**: a 1 × 1 convolution makes the values V; a 5 × 5 depthwise convolution with reflection padding
  runs on V in every block, and in the blocks with attention, multi-head self-attention in 8 × 8 windows (shifted
  by 4 in every second block, the map padded by reflection rather than rolled) is added; the relative position
  bias comes from an MLP (2 → 256 → heads) of ``sign(Δ)·log(1 + |Δ|)``; a 1 × 1 projection ends it.
* **MLP**: 1 × 1 convolution, ReLU, 1 × 1 convolution (ratio per stage ``(2, 4, 4, 2, 2)``).
* **Output**: a 3 × 3 convolution to four channels ``K`` and ``B``; the dehazed image is ``J = K·I − B + I`` on
  images scaled to [−1, 1] (the scattering model's form).

Sizes (depths per stage; attention in the last share of each stage's blocks): **T** ``(4, 4, 4, 2, 2)`` with
attention shares ``(0, ½, 1, 0, 0)``; **S** ``(8, 8, 8, 4, 4)`` with ``(¼, ½, ¾, 0, 0)``. Heads ``(2, 4, 6, 1, 1)``.

Training (:func:`train_dehazeformer`): L1 loss, AdamW, a cosine schedule down to lr/100, random crops, as the
paper; here from scratch on fog-gym's paired (clean, fogged) frames (no pretrained weights can be downloaded).

Example:
    >>> net = DehazeFormer("T")
    >>> round(sum(p.numel() for p in net.parameters()) / 1e6, 2)
    0.69
    >>> net(torch.zeros(1, 3, 32, 48)).shape
    torch.Size([1, 3, 32, 48])
"""

from __future__ import annotations

import math

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

from fog_gym.dehaze.classical import check_image

SIZES = {
    "T": {"depths": (4, 4, 4, 2, 2), "attention": (0.0, 0.5, 1.0, 0.0, 0.0)},
    "S": {"depths": (8, 8, 8, 4, 4), "attention": (0.25, 0.5, 0.75, 0.0, 0.0)},
}
DIMS = (24, 48, 96, 48, 24)
HEADS = (2, 4, 6, 1, 1)
MLP_RATIOS = (2, 4, 4, 2, 2)
WINDOW = 8


class RescaleNorm(nn.Module):
    """Per-sample normalisation over channels and pixels with a learned affine; returns the normalised map and
    the rescale / rebias to apply to the branch's output (module docstring)."""

    def __init__(self, dim: int, eps: float = 1e-5) -> None:
        super().__init__()
        self.eps = eps
        self.weight = nn.Parameter(torch.ones(1, dim, 1, 1))
        self.bias = nn.Parameter(torch.zeros(1, dim, 1, 1))
        self.meta1 = nn.Conv2d(1, dim, 1)  # σ → rescale
        self.meta2 = nn.Conv2d(1, dim, 1)  # μ → rebias
        nn.init.constant_(self.meta1.bias, 1.0)
        nn.init.constant_(self.meta2.bias, 0.0)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        mean = x.mean(dim=(1, 2, 3), keepdim=True)
        std = torch.sqrt((x - mean).pow(2).mean(dim=(1, 2, 3), keepdim=True) + self.eps)
        out = (x - mean) / std * self.weight + self.bias
        return out, self.meta1(std), self.meta2(mean)


class TokenMixer(nn.Module):
    """Values, a 5 × 5 depthwise reflection-padded convolution, optional window attention, a projection."""

    def __init__(self, dim: int, heads: int, attention: bool, shift: int) -> None:
        super().__init__()
        self.dim, self.heads, self.attention, self.shift = dim, heads, attention, shift
        self.v = nn.Conv2d(dim, dim, 1)
        self.conv = nn.Conv2d(dim, dim, 5, padding=2, groups=dim, padding_mode="reflect")
        self.proj = nn.Conv2d(dim, dim, 1)
        if attention:
            self.qk = nn.Conv2d(dim, 2 * dim, 1)
            self.bias_mlp = nn.Sequential(nn.Linear(2, 256, bias=True), nn.ReLU(inplace=True), nn.Linear(256, heads))
            coords = torch.stack(torch.meshgrid(torch.arange(WINDOW), torch.arange(WINDOW), indexing="ij")).flatten(1)
            rel = (coords[:, :, None] - coords[:, None, :]).permute(1, 2, 0).float()  # (N, N, 2)
            self.register_buffer("rel_log", torch.sign(rel) * torch.log1p(rel.abs()), persistent=False)

    def _windows(self, x: torch.Tensor) -> tuple[torch.Tensor, tuple[int, int, int, int]]:
        """(B, C, H, W) → (B·nW, N, C) windows, after shifting (reflection-padded) and padding to whole windows."""
        b, c, h, w = x.shape
        s = self.shift
        ph = (WINDOW - (h + s) % WINDOW) % WINDOW
        pw = (WINDOW - (w + s) % WINDOW) % WINDOW
        if s or ph or pw:
            x = F.pad(x, (s, pw, s, ph), mode="reflect") if min(h, w) > max(s, ph, pw) else F.pad(x, (s, pw, s, ph), mode="replicate")
        hp, wp = x.shape[-2:]
        x = x.view(b, c, hp // WINDOW, WINDOW, wp // WINDOW, WINDOW).permute(0, 2, 4, 3, 5, 1)
        return x.reshape(-1, WINDOW * WINDOW, c), (b, hp, wp, c)

    def _merge(self, win: torch.Tensor, shape: tuple[int, int, int, int], h: int, w: int) -> torch.Tensor:
        b, hp, wp, _ = shape
        c = win.shape[-1]
        x = win.view(b, hp // WINDOW, wp // WINDOW, WINDOW, WINDOW, c).permute(0, 5, 1, 3, 2, 4).reshape(b, c, hp, wp)
        s = self.shift
        return x[:, :, s : s + h, s : s + w]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        v = self.v(x)
        out = self.conv(v)
        if self.attention:
            h, w = x.shape[-2:]
            qk = self.qk(x)
            qkv, shape = self._windows(torch.cat([qk, v], 1))
            n = qkv.shape[1]
            d = self.dim // self.heads
            qkv = qkv.view(-1, n, 3, self.heads, d).permute(2, 0, 3, 1, 4)  # (3, B·nW, heads, N, d)
            q, k, vv = qkv[0], qkv[1], qkv[2]
            bias = self.bias_mlp(self.rel_log).permute(2, 0, 1)  # (heads, N, N)
            attn = (q * d**-0.5) @ k.transpose(-2, -1) + bias
            o = (attn.softmax(-1) @ vv).transpose(1, 2).reshape(-1, n, self.dim)
            out = out + self._merge(o, shape, h, w)
        return self.proj(out)


class Block(nn.Module):
    def __init__(self, dim: int, heads: int, mlp_ratio: int, attention: bool, shift: int) -> None:
        super().__init__()
        self.norm1, self.norm2 = RescaleNorm(dim), RescaleNorm(dim)
        self.mixer = TokenMixer(dim, heads, attention, shift)
        hidden = dim * mlp_ratio
        self.mlp = nn.Sequential(nn.Conv2d(dim, hidden, 1), nn.ReLU(inplace=True), nn.Conv2d(hidden, dim, 1))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y, scale, shift = self.norm1(x)
        x = x + self.mixer(y) * scale + shift
        y, scale, shift = self.norm2(x)
        return x + self.mlp(y) * scale + shift


class Stage(nn.Sequential):
    def __init__(self, dim: int, depth: int, heads: int, mlp_ratio: int, attention_share: float) -> None:
        first_attention = depth - int(round(depth * attention_share))
        super().__init__(*(Block(dim, heads, mlp_ratio, k >= first_attention, 0 if k % 2 == 0 else WINDOW // 2)
                           for k in range(depth)))  # fmt: skip


class SKFusion(nn.Module):
    """Selective-kernel fusion of two maps: weights from the global average of their sum through a small MLP,
    softmaxed over the two."""

    def __init__(self, dim: int, reduction: int = 8) -> None:
        super().__init__()
        hidden = max(dim // reduction, 4)
        self.mlp = nn.Sequential(nn.Conv2d(dim, hidden, 1, bias=False), nn.ReLU(inplace=True), nn.Conv2d(hidden, 2 * dim, 1, bias=False))

    def forward(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        w = self.mlp(F.adaptive_avg_pool2d(a + b, 1)).view(a.shape[0], 2, a.shape[1], 1, 1).softmax(1)
        return a * w[:, 0] + b * w[:, 1]


class DehazeFormer(nn.Module):
    """``forward(images (B, 3, H, W) in [0, 1])`` → dehazed images in [0, 1] (any H, W; padded to multiples of 4
    by reflection inside)."""

    def __init__(self, size: str = "T") -> None:
        super().__init__()
        if size not in SIZES:
            raise ValueError(f"size must be one of {tuple(SIZES)}, got {size!r}")
        self.size = size
        cfg = SIZES[size]
        d = DIMS
        self.embed = nn.Conv2d(3, d[0], 3, padding=1, padding_mode="reflect")
        self.stages = nn.ModuleList(Stage(d[i], cfg["depths"][i], HEADS[i], MLP_RATIOS[i], cfg["attention"][i]) for i in range(5))
        self.down1 = nn.Conv2d(d[0], d[1], 2, 2)
        self.down2 = nn.Conv2d(d[1], d[2], 2, 2)
        self.up1 = nn.Sequential(nn.Conv2d(d[2], d[3] * 4, 1), nn.PixelShuffle(2))
        self.up2 = nn.Sequential(nn.Conv2d(d[3], d[4] * 4, 1), nn.PixelShuffle(2))
        self.fuse1, self.fuse2 = SKFusion(d[3]), SKFusion(d[4])
        self.skip1 = nn.Conv2d(d[1], d[3], 1)
        self.skip2 = nn.Conv2d(d[0], d[4], 1)
        self.out = nn.Conv2d(d[4], 4, 3, padding=1, padding_mode="reflect")

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h, w = x.shape[-2:]
        ph, pw = (-h) % 4, (-w) % 4
        i = x * 2.0 - 1.0  # [-1, 1]
        if ph or pw:
            i = F.pad(i, (0, pw, 0, ph), mode="reflect")
        s1 = self.stages[0](self.embed(i))
        s2 = self.stages[1](self.down1(s1))
        s3 = self.stages[2](self.down2(s2))
        u1 = self.stages[3](self.fuse1(self.up1(s3), self.skip1(s2)))
        u2 = self.stages[4](self.fuse2(self.up2(u1), self.skip2(s1)))
        kb = self.out(u2).float()
        k, b = kb[:, :1], kb[:, 1:]
        j = k * i.float() - b + i.float()
        return ((j[..., :h, :w] + 1.0) / 2.0).clamp(0.0, 1.0) if not self.training else (j[..., :h, :w] + 1.0) / 2.0


def to_tensor(images: np.ndarray) -> torch.Tensor:
    """uint8 ``(N, H, W, 3)`` or ``(H, W, 3)`` → float ``(N, 3, H, W)`` in [0, 1]."""
    a = np.asarray(images)
    if a.ndim == 3:
        a = a[None]
    return torch.from_numpy(np.ascontiguousarray(a.transpose(0, 3, 1, 2))).float() / 255.0


@torch.no_grad()
def dehaze(model: DehazeFormer, image: np.ndarray, precision: str = "fp32") -> np.ndarray:
    """Dehaze one uint8 ``(H, W, 3)`` RGB image (``precision="bf16"`` runs under bfloat16 autocast; a model in
    channels-last memory layout runs ≈ 1.5× faster on a CPU)."""
    img = check_image(image)
    model.eval()
    dev = next(model.parameters()).device
    with torch.autocast(dev.type, dtype=torch.bfloat16, enabled=precision == "bf16"):
        out = model(to_tensor(img).to(dev).contiguous(memory_format=torch.channels_last))
    return np.rint(out[0].float().clamp(0, 1).permute(1, 2, 0).cpu().numpy() * 255.0).astype(np.uint8)


def train_dehazeformer(clean: np.ndarray, foggy: np.ndarray, size: str = "T", steps: int = 1000, batch_size: int = 8,
                       crop: int = 128, lr: float = 4e-4, seed: int = 0, device: str = "cpu", precision: str = "fp32",
                       progress: bool = True) -> tuple[DehazeFormer, list[float]]:  # fmt: skip
    """Fit DehazeFormer to pairs ``clean`` / ``foggy`` (uint8 ``(N, H, W, 3)``, same shape) for ``steps`` steps
    of ``batch_size`` random ``crop`` × ``crop`` crops (random horizontal flips), L1 loss, AdamW, cosine schedule
    to lr/100 (the paper's recipe, shorter); returns the model and the mean loss of every 50 steps."""
    from tqdm import tqdm

    c, f = np.asarray(clean), np.asarray(foggy)
    if c.shape != f.shape or c.ndim != 4 or c.shape[-1] != 3 or c.dtype != np.uint8 or f.dtype != np.uint8:
        raise ValueError(f"clean and foggy must be uint8 (N, H, W, 3) arrays of one shape, got {c.shape} and {f.shape}")
    if min(steps, batch_size, crop) < 1 or crop > min(c.shape[1:3]):
        raise ValueError(f"steps, batch_size and crop must be >= 1 and crop <= the images' sides, got {steps}, "
                         f"{batch_size}, {crop}")  # fmt: skip
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    model = DehazeFormer(size).to(device).to(memory_format=torch.channels_last)
    opt = torch.optim.AdamW(model.parameters(), lr=lr, weight_decay=0.01)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, steps, eta_min=lr / 100)
    losses, window = [], []
    model.train()
    for _ in tqdm(range(steps), desc=f"DehazeFormer-{size}", unit="step", disable=not progress):
        idx = rng.integers(0, len(c), batch_size)
        y0 = rng.integers(0, c.shape[1] - crop + 1, batch_size)
        x0 = rng.integers(0, c.shape[2] - crop + 1, batch_size)
        flip = rng.random(batch_size) < 0.5
        cc = np.stack([c[i, y:y + crop, x:x + crop][:, ::-1 if fl else 1] for i, y, x, fl in zip(idx, y0, x0, flip)])
        ff = np.stack([f[i, y:y + crop, x:x + crop][:, ::-1 if fl else 1] for i, y, x, fl in zip(idx, y0, x0, flip)])
        x, y = to_tensor(ff).to(device).contiguous(memory_format=torch.channels_last), to_tensor(cc).to(device)
        with torch.autocast(torch.device(device).type, dtype=torch.bfloat16, enabled=precision == "bf16"):
            out = model(x)
        loss = F.l1_loss(out.float(), y)
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        window.append(float(loss.detach()))
        if len(window) == 50:
            losses.append(float(np.mean(window)))
            window = []
    if window:
        losses.append(float(np.mean(window)))
    if not all(math.isfinite(v) for v in losses):
        raise FloatingPointError("DehazeFormer's training loss is not finite")
    return model, losses
