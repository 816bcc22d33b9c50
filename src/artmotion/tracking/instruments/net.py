"""A small fully convolutional network that finds instrument heads (PyTorch, CPU, trained here).

The thesis learns HOG templates of the tool tip (Fig. 2.7); here a network of seven 3×3
convolutions learns, from annotated frames, what a head looks like and what is around it. It runs
on the frame at half resolution and predicts, on a grid of cells of ``STRIDE`` frame pixels (the
"centre" formulation of CenterNet, Zhou et al. 2019):

* a heat map: the probability that a head lies in the cell (focal loss on a Gaussian target);
* the head's offset inside the cell (2), for sub-cell position;
* the shaft's direction ``(cos a, sin a)`` (2), from the image: the angle is read off the pixels;
* the head's log size (1).

Only this module imports torch (the ``tools`` extra); nothing here is imported by ``--help``.
"""

from __future__ import annotations

import math

import numpy as np

from artmotion._torch import nn, torch

#: frame pixels per output cell (the network sees the frame at half size and downsamples by 4)
STRIDE = 8
CHANNELS = 6  # heat, dx, dy, cos, sin, log size


def _block(cin: int, cout: int, stride: int = 1, dilation: int = 1) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, 3, stride=stride, padding=dilation, dilation=dilation, bias=False),
                         nn.BatchNorm2d(cout), nn.ReLU(inplace=True))


class HeadNet(nn.Module):
    """Half-resolution BGR in, ``CHANNELS`` maps of stride ``STRIDE`` (frame pixels) out."""

    def __init__(self, width: int = 32):
        super().__init__()
        w = width
        self.body = nn.Sequential(
            _block(3, w // 2), _block(w // 2, w, 2), _block(w, w), _block(w, w, 2),
            _block(w, w, dilation=2), _block(w, w, dilation=4), _block(w, w, dilation=8),
        )
        self.head = nn.Conv2d(w, CHANNELS, 1)
        bias = self.head.bias
        assert bias is not None
        with torch.no_grad():  # start with few heads everywhere (focal-loss practice)
            bias.zero_()
            bias[0] = -math.log((1 - 0.01) / 0.01)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.body(x))


def to_tensor(frames: list[np.ndarray]) -> torch.Tensor:
    """Frames (BGR uint8, all the same size) at half size, as a float batch in [-1, 1]."""
    import cv2

    half = [cv2.resize(f, (f.shape[1] // 2, f.shape[0] // 2), interpolation=cv2.INTER_AREA) for f in frames]
    x = torch.from_numpy(np.stack(half)).permute(0, 3, 1, 2).float()
    return x / 127.5 - 1.0


def targets(heads: list[np.ndarray], grid: tuple[int, int], sigma: float = 1.0) -> torch.Tensor:
    """Training maps ``(n, CHANNELS + 1, gh, gw)`` for annotated heads ``(k, 4)`` (x, y, size,
    angle, frame pixels): Gaussian heat, and the regression targets plus their mask (last channel)
    at the cell of each head."""
    gh, gw = grid
    out = np.zeros((len(heads), CHANNELS + 1, gh, gw), dtype=np.float32)
    yy, xx = np.mgrid[0:gh, 0:gw]
    for i, H in enumerate(heads):
        for x, y, size, ang in np.asarray(H, dtype=float).reshape(-1, 4):
            cx, cy = x / STRIDE - 0.5, y / STRIDE - 0.5
            ix, iy = int(round(cx)), int(round(cy))
            if not (0 <= ix < gw and 0 <= iy < gh):
                continue
            g = np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * sigma**2))
            out[i, 0] = np.maximum(out[i, 0], g)
            out[i, 0, iy, ix] = 1.0
            out[i, 1:, iy, ix] = (cx - ix, cy - iy, math.cos(ang), math.sin(ang), math.log(max(size, 1.0)), 1.0)
    return torch.from_numpy(out)


def loss(pred: torch.Tensor, tgt: torch.Tensor) -> torch.Tensor:
    """Focal loss on the heat map (CenterNet's, alpha 2, beta 4) plus L1 on the regressions at
    the heads' cells."""
    p = torch.sigmoid(pred[:, 0]).clamp(1e-4, 1 - 1e-4)
    t = tgt[:, 0]
    pos = (t == 1.0).float()
    npos = pos.sum().clamp(min=1.0)
    focal = -(pos * (1 - p) ** 2 * torch.log(p) + (1 - pos) * (1 - t) ** 4 * p**2 * torch.log(1 - p)).sum() / npos
    mask = tgt[:, CHANNELS:CHANNELS + 1]
    reg = (torch.abs(pred[:, 1:CHANNELS] - tgt[:, 1:CHANNELS]) * mask).sum() / npos
    return focal + reg


def decode(maps: np.ndarray, threshold: float, top: int = 6) -> np.ndarray:
    """Heads ``(k, 5)``: x, y (frame pixels), size, angle (radians in [0, 2 pi)), score — the local
    maxima of one frame's heat map (``maps``: ``(CHANNELS, gh, gw)``, raw outputs) above
    ``threshold``, best first."""
    heat = 1.0 / (1.0 + np.exp(-maps[0]))
    gh, gw = heat.shape
    pad = np.pad(heat, 1, constant_values=-1.0)
    peak = np.ones_like(heat, dtype=bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dy or dx:
                peak &= heat >= pad[1 + dy:1 + dy + gh, 1 + dx:1 + dx + gw]
    iy, ix = np.nonzero(peak & (heat > threshold))
    order = np.argsort(-heat[iy, ix])[:top]
    iy, ix = iy[order], ix[order]
    x = (ix + maps[1, iy, ix] + 0.5) * STRIDE
    y = (iy + maps[2, iy, ix] + 0.5) * STRIDE
    ang = np.mod(np.arctan2(maps[4, iy, ix], maps[3, iy, ix]), 2 * np.pi)
    size = np.exp(np.clip(maps[5, iy, ix], 0.0, 8.0))
    return np.column_stack([x, y, size, ang, heat[iy, ix]]).astype(float)
