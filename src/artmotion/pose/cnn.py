"""A small convolutional network that learns pose features from rendered crops (PyTorch, CPU).

Sec. 3.3 describes a crop by a generic feature (HOG, LBP) and lets the GP find the pose in it.
A generic feature carries the jaw opening weakly, and a GP on it interpolates between training
poses but does not extrapolate to new combinations of pose, background and light. Here a small
network (four 3×3 convolution blocks, a fully connected layer) is trained on the training crops
to regress the standardised angles, under appearance augmentation (gain, contrast, gamma, tint,
blur, noise, specular glints, box jitter, occluding bars): what it learns is pose, not
appearance. Given the tool's keypoints (hinge, clevis, jaw tips), it also learns where they lie
in the crop, an auxiliary task whose read-out is dropped once it is trained. Its last hidden
layer is the feature the GP (Eq. 3.1-3.5) regresses the angles on, so the prediction keeps the
GP's variance (the thesis' reason for a GP).

No downloaded weights: the network is trained here (3000 mini-batches): 1 to 2.5 minutes on two
CPU cores, depending on the CPU.
Only this module imports torch (the ``tools`` extra); the HOG and LBP models do not need it.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Callable

import cv2
import numpy as np

from artmotion._torch import nn, torch
from artmotion.io.sequence import prefetched
from artmotion.pose.features import VIEW_DIM

#: width of the feature the GP sees
DIM = 64


def _block(cin: int, cout: int) -> nn.Sequential:
    """A 3×3 convolution of stride 2 (3.7× cheaper to train here than a convolution and a pooling)."""
    return nn.Sequential(nn.Conv2d(cin, cout, 3, stride=2, padding=1, bias=False), nn.BatchNorm2d(cout),
                         nn.ReLU(inplace=True))


def _cells(n: int, blocks: int = 4) -> int:
    """Cells along a side of ``n`` pixels after ``blocks`` convolutions of stride 2."""
    for _ in range(blocks):
        n = (n + 1) // 2
    return n


class CropNet(nn.Module):
    """``(n, 3, 48, 64)`` crops (each standardised to zero mean and unit variance), and ``extra``
    more inputs per crop, → ``(n, dim)`` features and ``(n, k)`` standardised angles."""

    def __init__(self, k: int, width: int = 16, dim: int = DIM, size: tuple[int, int] = (64, 48), extra: int = 0):
        super().__init__()
        w = width
        self.extra = extra  # inputs besides the crop (4 with box views, else 0)
        self.body = nn.Sequential(_block(3, w), _block(w, 2 * w), _block(2 * w, 4 * w), _block(4 * w, 4 * w),
                                  nn.Flatten(), nn.Dropout(0.2))
        cells = _cells(size[0]) * _cells(size[1])
        self.embed = nn.Sequential(nn.Linear(4 * w * cells + extra, dim), nn.ReLU(inplace=True))
        self.head = nn.Linear(dim, k)

    def features(self, x: torch.Tensor, e: torch.Tensor | None = None) -> torch.Tensor:
        h = self.body(x)
        return self.embed(h if e is None else torch.cat([h, e], 1))

    def forward(self, x: torch.Tensor, e: torch.Tensor | None = None) -> torch.Tensor:
        return self.head(self.features(x, e))


def standardise(batch: np.ndarray) -> np.ndarray:
    """``(n, h, w, 3)`` float crops → ``(n, 3, h, w)``, each crop to zero mean and unit variance
    (a crop's brightness and contrast are not pose)."""
    x = np.ascontiguousarray(batch.transpose(0, 3, 1, 2), dtype=np.float32)
    m = x.mean(axis=(1, 2, 3), keepdims=True)
    s = x.std(axis=(1, 2, 3), keepdims=True)
    return (x - m) / (s + 1e-3)


def _streak(length: float, angle: float) -> np.ndarray:
    """A motion-blur kernel: a line of ``length`` pixels at ``angle`` (radians), summing to 1."""
    k = int(math.ceil(length)) | 1
    kernel = np.zeros((k, k), np.float32)
    c, d = (k - 1) / 2, length / 2
    cv2.line(kernel, (round(c - d * math.cos(angle)), round(c - d * math.sin(angle))),
             (round(c + d * math.cos(angle)), round(c + d * math.sin(angle))), 1.0, 1, cv2.LINE_AA)
    return kernel / kernel.sum()


def augment(batch: np.ndarray, rng: np.random.Generator,
            points: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Appearance changes that do not change the pose, for ``(n, h, w, 3)`` float crops in [0, 1]:
    box jitter (a detector's box is a few per cent off in position and size), motion blur, blur, specular
    glints, an occluding bar (another instrument's shaft), gain, tint, gamma, sensor noise. Returns
    the crops and ``points`` ``(n, 2m)`` (x / width, y / height in each crop) moved with the box jitter."""
    n, h, w, _ = batch.shape
    out = np.empty_like(batch)
    scale = np.asarray(rng.uniform(0.92, 1.08, n))
    shift = np.asarray(rng.uniform(-0.05, 0.05, (n, 2))) * np.array([w, h])
    sigma = np.asarray(rng.uniform(0.0, 1.2, n))
    streak = np.where(rng.random(n) < 0.4, rng.uniform(2.0, 12.0, n), 0.0)  # motion blur: length in pixels
    streak_dir = np.asarray(rng.uniform(0, math.pi, n))
    if points is not None:  # a point at u (a fraction of the width) goes to s u + (1 - s) / 2 + shift / w
        xy = np.arange(points.shape[1]) % 2
        points = (scale[:, None] * points + ((1 - scale)[:, None] / 2 + (shift / (w, h))[:, xy])).astype(np.float32)
    for i in range(n):
        s = scale[i]
        M = np.array([[s, 0, (1 - s) * w / 2 + shift[i, 0]], [0, s, (1 - s) * h / 2 + shift[i, 1]]], np.float32)
        img = cv2.warpAffine(batch[i], M, (w, h), borderMode=cv2.BORDER_REFLECT)
        if streak[i]:
            img = cv2.filter2D(img, -1, _streak(streak[i], streak_dir[i]), borderType=cv2.BORDER_REFLECT)
        out[i] = cv2.GaussianBlur(img, (0, 0), sigma[i]) if sigma[i] > 0.3 else img
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    glint = np.flatnonzero(rng.random(n) < 0.3)  # small saturated blobs
    if len(glint):
        c = rng.uniform((0, 0), (w, h), (len(glint), 2)).astype(np.float32)
        r = rng.uniform(1.0, 4.0, len(glint)).astype(np.float32)
        d2 = (xx - c[:, 0, None, None]) ** 2 + (yy - c[:, 1, None, None]) ** 2
        amp = rng.uniform(0.3, 1.0, len(glint)).astype(np.float32)
        out[glint] += (amp[:, None, None] * np.exp(-d2 / (2 * r[:, None, None] ** 2)))[..., None]
    bars = np.flatnonzero(rng.random(n) < 0.2)
    if len(bars):
        ang = rng.uniform(0, math.pi, len(bars)).astype(np.float32)
        off = rng.uniform(-0.4, 0.4, len(bars)).astype(np.float32) * w
        d = ((xx - w / 2) * np.cos(ang)[:, None, None] + (yy - h / 2) * np.sin(ang)[:, None, None] - off[:, None, None])
        inside = np.abs(d) < rng.uniform(2.0, 6.0, len(bars)).astype(np.float32)[:, None, None]
        level = rng.uniform(0.1, 0.7, len(bars)).astype(np.float32)
        out[bars] = np.where(inside[..., None], level[:, None, None, None], out[bars])
    gain = np.exp(rng.uniform(math.log(0.15), math.log(1.4), (n, 1, 1, 1)))
    tint = rng.uniform(0.8, 1.2, (n, 1, 1, 3))
    gamma = rng.uniform(0.7, 1.4, (n, 1, 1, 1))
    out = np.clip(out * (gain * tint).astype(np.float32), 0, 1) ** gamma.astype(np.float32)
    noise = rng.standard_normal(out.shape, dtype=np.float32) * rng.uniform(0.0, 0.04, (n, 1, 1, 1)).astype(np.float32)
    return (out + noise).astype(np.float32), points


def target_scale(Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation of each angle: :func:`fit_net` trains on ``(Y - mean) / std``,
    so its read-out times ``std`` plus ``mean`` is in degrees again."""
    return Y.mean(0), Y.std(0) + 1e-9


def fit_net(crops: np.ndarray, Y: np.ndarray, steps: int = 3000, batch: int = 64, seed: int = 0, width: int = 16,
            dim: int = DIM, extra: np.ndarray | None = None, augmented: bool = True, weights: np.ndarray | None = None,
            progress: bool = False, beta: float = 0.05, points: np.ndarray | None = None,
            point_weight: float = 0.5) -> CropNet:
    """Train :class:`CropNet` on ``(n, h, w, 3)`` float crops and angles ``Y`` (n, k), standardised
    here, for ``steps`` mini-batches of augmented crops (the cost does not grow with n); ``extra``
    ``(n, e)``: inputs joined to the convolutional features (where the box lies in its frame);
    ``weights`` ``(k,)``: each angle's weight in the loss (default equal); ``beta``: the smooth L1
    loss's quadratic zone in standard deviations (:class:`~artmotion.pose.model.PoseRegressor`'s
    ``net_beta``).

    ``points`` ``(n, 2m)``: the tool's keypoints in each crop (x / width, y / height; NaN where not
    known), auxiliary targets of weight ``point_weight`` each (against ``weights``): the network
    also learns where the hinge and the jaw tips are, which ties its feature to the tool's geometry
    rather than its look (multi-task learning; docs/pose.md). They are read out by ``2m`` more
    outputs of its head, dropped once it is trained: the network returned predicts the angles only."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    mu, sd = target_scale(Y)
    T = torch.from_numpy(((Y - mu) / sd).astype(np.float32))
    k = Y.shape[1]
    W = np.ones(k, np.float32) if weights is None else np.asarray(weights, np.float32)
    P = mask = None
    if points is not None:
        known = np.isfinite(points)
        P = np.where(known, points, 0.0).astype(np.float32)
        mask = torch.from_numpy(np.concatenate([np.ones((len(P), k), bool), known], 1))  # a row's known targets
        p_mu = np.array([P[known[:, j], j].mean() if known[:, j].any() else 0.0 for j in range(P.shape[1])], np.float32)
        p_sd = np.array([P[known[:, j], j].std() + 1e-6 if known[:, j].any() else 1.0 for j in range(P.shape[1])],
                        np.float32)
        W = np.concatenate([W, np.full(P.shape[1], point_weight, np.float32)])
    W_t = torch.from_numpy(W / W.sum())
    E = None if extra is None else torch.from_numpy(np.asarray(extra, np.float32))
    net = CropNet(len(W), width, dim, (crops.shape[2], crops.shape[1]), 0 if E is None else E.shape[1])
    # channels-last tensors take oneDNN's faster convolutions (a step 42-46 against 50-56 ms on one
    # machine, 23 against 28-30 ms on another; other weights, within another seed's spread: docs/pose.md)
    net = net.to(memory_format=torch.channels_last)  # type: ignore[call-overload]
    opt = torch.optim.AdamW(net.parameters(), lr=3e-3, weight_decay=1e-4)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=3e-3, total_steps=steps)
    net.train()
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=steps, desc="train network", unit="batch", disable=None)

    def batches():
        order: list[int] = []
        for _ in range(steps):
            if len(order) < batch:  # epochs of shuffled crops
                order += rng.permutation(len(crops)).tolist()
            idx, order = np.array(order[:batch]), order[batch:]
            x, pts = crops[idx], None if P is None else P[idx]
            if augmented:
                x, pts = augment(x, rng, pts)
            yield idx, standardise(x), pts

    # the next mini-batches are augmented on another thread while the network trains on this one
    # with one thread of its own (OpenCV and NumPy release Python's lock; the same batches as in
    # line, and here the same weights: 400 mini-batches 21.6-22.4 s against 23.8-25.8 s in line
    # with torch on two threads, 29-31 s with both on two)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        for idx, xb, pts in prefetched(batches(), 2):
            x = torch.from_numpy(xb).contiguous(memory_format=torch.channels_last)
            target = T[idx] if pts is None else torch.cat([T[idx], torch.from_numpy((pts - p_mu) / p_sd)], 1)
            loss = nn.functional.smooth_l1_loss(net(x, None if E is None else E[idx]), target, beta=beta,
                                                reduction="none") * W_t
            loss = (loss if mask is None else loss * mask[idx]).sum(1).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            if bar is not None:
                bar.update()
    finally:
        torch.set_num_threads(threads)
        if bar is not None:
            bar.close()
    if P is not None:  # the keypoints' read-out is dropped: the head reads out the angles only
        head = nn.Linear(dim, k)
        with torch.no_grad():
            head.weight.copy_(net.head.weight[:k])
            head.bias.copy_(net.head.bias[:k])
        net.head = head
    return net.to(memory_format=torch.contiguous_format).eval()


def state_arrays(net: CropNet) -> dict[str, np.ndarray]:
    """The network's weights as NumPy arrays (for a model file)."""
    return {k: v.detach().cpu().numpy() for k, v in net.state_dict().items()}


def from_arrays(arrays: dict[str, np.ndarray], k: int, size: tuple[int, int]) -> CropNet:
    """A :class:`CropNet` for ``k`` angles and ``size`` crops from :func:`state_arrays`' output;
    a ``ValueError`` when the arrays do not make one."""
    try:
        width = int(arrays["body.0.0.weight"].shape[0])
        lin = arrays["embed.0.weight"]
        flat = 4 * width * _cells(size[0]) * _cells(size[1])
        extra = int(lin.shape[1]) - flat
        if extra not in (0, VIEW_DIM):
            raise ValueError(f"the network takes {extra} inputs besides the crop, not 0 or {VIEW_DIM}")
        net = CropNet(k, width, int(lin.shape[0]), size, extra)
        net.load_state_dict({n: torch.from_numpy(np.array(a)) for n, a in arrays.items()}, strict=True)
    except (KeyError, IndexError, RuntimeError, TypeError) as exc:
        raise ValueError(f"the network's weights do not fit: {str(exc).splitlines()[0]}") from None
    return net.eval()


#: each trained network's layers for :func:`embed`, folded once (see :func:`_folded`)
_FOLDED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _folded(net: CropNet) -> Callable[[torch.Tensor, torch.Tensor | None], torch.Tensor]:
    """:meth:`CropNet.features` in eval mode as one function: each convolution with its batch
    normalisation folded into its weights and bias (``torch.nn.utils.fusion``; the same numbers
    up to float rounding, 5e-7 on features of size ~3) and no module dispatch, which is most of
    the cost of one crop (0.50 -> 0.36 ms). Built on the first call for a network and kept: a
    network is embedded only once trained (:func:`fit_net`, :func:`from_arrays` give new ones)."""
    fn = _FOLDED.get(net)
    if fn is None:
        from torch.nn.utils.fusion import fuse_conv_bn_eval

        pairs = [(block[0], block[1]) for block in net.body if isinstance(block, nn.Sequential)]
        convs = [fuse_conv_bn_eval(c, bn) for c, bn in pairs
                 if isinstance(c, nn.Conv2d) and isinstance(bn, nn.BatchNorm2d)]
        layers = [(c.weight.detach(), None if c.bias is None else c.bias.detach()) for c in convs]
        lin = net.embed[0]
        assert isinstance(lin, nn.Linear) and len(layers) == 4  # the layers of CropNet
        w_lin, b_lin = lin.weight.detach(), lin.bias.detach()

        def fn(x: torch.Tensor, e: torch.Tensor | None) -> torch.Tensor:
            for w, b in layers:
                x = torch.relu_(nn.functional.conv2d(x, w, b, stride=2, padding=1))
            x = x.flatten(1)
            return torch.relu_(nn.functional.linear(x if e is None else torch.cat([x, e], 1), w_lin, b_lin))

        _FOLDED[net] = fn
    return fn


@torch.inference_mode()
def embed(net: CropNet, crops: np.ndarray, extra: np.ndarray | None = None, batch: int = 512) -> np.ndarray:
    """``(n, dim)`` features of ``(n, h, w, 3)`` float crops (and their ``extra`` inputs), by the
    trained network ``net`` in eval mode."""
    E = None if extra is None else torch.from_numpy(extra.astype(np.float32))
    features = _folded(net)
    parts = [features(torch.from_numpy(standardise(crops[s : s + batch])), None if E is None else E[s : s + batch]).numpy()
             for s in range(0, len(crops), batch)]
    return np.concatenate(parts) if parts else np.empty((0, net.head.in_features), np.float32)
