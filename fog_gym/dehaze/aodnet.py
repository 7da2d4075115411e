"""AOD-Net (Li et al., ICCV 2017) in PyTorch: the 1 761-parameter all-in-one dehazing CNN.

It estimates one map ``K(x)`` from the hazy image with five small convolutions (1×1, 3×3, 5×5, 7×7, 3×3, three
filters each, with the paper's concatenations) and outputs ``J = ReLU(K·I − K + b)``, b = 1, which folds the
transmission and the airlight of the scattering model into K. No pretrained weights can be downloaded here:
:func:`train_aodnet` fits it from scratch on fog-gym's paired (clean, fogged) frames — the paper's "fine-tuned"
variant — with the mean squared error on images in [0, 1].
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn as nn

from fog_gym.dehaze.classical import check_image


class AODNet(nn.Module):
    def __init__(self) -> None:
        super().__init__()
        self.conv1 = nn.Conv2d(3, 3, 1)
        self.conv2 = nn.Conv2d(3, 3, 3, padding=1)
        self.conv3 = nn.Conv2d(6, 3, 5, padding=2)
        self.conv4 = nn.Conv2d(6, 3, 7, padding=3)
        self.conv5 = nn.Conv2d(12, 3, 3, padding=1)
        self.b = 1.0

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``x``: (B, 3, H, W) in [0, 1] → dehazed (B, 3, H, W)."""
        x1 = torch.relu(self.conv1(x))
        x2 = torch.relu(self.conv2(x1))
        x3 = torch.relu(self.conv3(torch.cat([x1, x2], 1)))
        x4 = torch.relu(self.conv4(torch.cat([x2, x3], 1)))
        k = torch.relu(self.conv5(torch.cat([x1, x2, x3, x4], 1)))
        return torch.relu(k * x - k + self.b)


def to_tensor(images: np.ndarray) -> torch.Tensor:
    """uint8 ``(N, H, W, 3)`` or ``(H, W, 3)`` → float ``(N, 3, H, W)`` in [0, 1]."""
    a = np.asarray(images)
    if a.ndim == 3:
        a = a[None]
    return torch.from_numpy(np.ascontiguousarray(a.transpose(0, 3, 1, 2))).float() / 255.0


@torch.no_grad()
def dehaze(model: AODNet, image: np.ndarray) -> np.ndarray:
    """Dehaze one uint8 ``(H, W, 3)`` RGB image."""
    img = check_image(image)
    model.eval()
    dev = next(model.parameters()).device
    out = model(to_tensor(img).to(dev))[0].clamp(0, 1).permute(1, 2, 0).cpu().numpy()
    return np.rint(out * 255.0).astype(np.uint8)


def train_aodnet(clean: np.ndarray, foggy: np.ndarray, epochs: int = 10, batch_size: int = 16, lr: float = 1e-3,
                 seed: int = 0, device: str = "cpu", progress: bool = True) -> tuple[AODNet, list[float]]:  # fmt: skip
    """Fit AOD-Net to pairs ``clean`` / ``foggy`` (uint8 ``(N, H, W, 3)``, same shape); returns the model and the
    mean training loss of each epoch."""
    from tqdm import tqdm

    c, f = np.asarray(clean), np.asarray(foggy)
    if c.shape != f.shape or c.ndim != 4 or c.shape[-1] != 3 or c.dtype != np.uint8 or f.dtype != np.uint8:
        raise ValueError(f"clean and foggy must be uint8 (N, H, W, 3) arrays of one shape, got {c.shape} and {f.shape}")
    if epochs < 1 or batch_size < 1:
        raise ValueError(f"epochs and batch_size must be >= 1, got {epochs} and {batch_size}")
    torch.manual_seed(seed)
    model = AODNet().to(device)
    opt = torch.optim.Adam(model.parameters(), lr=lr, weight_decay=1e-4)
    gen = torch.Generator().manual_seed(seed)
    losses = []
    for _ in tqdm(range(epochs), desc="AOD-Net", unit="epoch", disable=not progress):
        total = 0.0
        for idx in torch.randperm(len(c), generator=gen).split(batch_size):
            x, y = to_tensor(f[idx.numpy()]).to(device), to_tensor(c[idx.numpy()]).to(device)
            loss = nn.functional.mse_loss(model(x), y)
            opt.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(model.parameters(), 0.1)
            opt.step()
            total += float(loss.detach()) * len(idx)
        losses.append(total / len(c))
    return model, losses
