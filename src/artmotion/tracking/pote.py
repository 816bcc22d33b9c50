"""Product of Tracking Experts: fuse the experts' Gaussians (thesis Eq. 2.1-2.3).

The product of Gaussian densities is (up to normalisation, Eq. 2.1-2.2) the Gaussian with
``Σ⁻¹ = Σ_k Σ_k⁻¹`` and ``μ = Σ Σ_k Σ_k⁻¹ μ_k`` (Eq. 2.3).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np

from artmotion.errors import InputError
from artmotion.tracking.experts import (
    EXPERTS,
    BlobExpert,
    DetectionExpert,
    Entity,
    Expert,
    FlowExpert,
    Frame,
    Gaussian,
    KLTExpert,
    MotionExpert,
    asymmetric,
    belief_problem,
    check_experts,
)

__all__ = ["PoTE", "fuse"]

_INF = float("inf")


def fuse(gaussians: Iterable[Gaussian | None]) -> Gaussian | None:
    """Product of Gaussian experts (Eq. 2.3); ``None`` entries (no opinion) are left out.

    Returns ``None`` when no expert has an opinion. A belief whose covariance is not finite and
    positive definite (a zero one would be a certain expert, which the product cannot hold; a
    negative or NaN one is no belief) or whose mean is not finite is an
    :class:`~artmotion.errors.InputError`.
    """
    info = np.zeros((2, 2))
    vec = np.zeros(2)
    n = 0
    for g in gaussians:
        if g is None:
            continue
        P = _information(g.cov)
        info += P
        vec += P @ g.mean
        n += 1
    if n == 0:
        return None
    cov = _inv2(info)
    cov = 0.5 * (cov + cov.T)
    mean = cov @ vec
    if not math.isfinite(mean[0] + mean[1]):     # some belief's mean was not finite
        raise InputError(_mean_problem(gaussians))
    return Gaussian(mean, cov)


def _information(a: np.ndarray) -> np.ndarray:
    """Inverse of a belief's 2x2 covariance (closed form), which must be finite and positive
    definite (checked on the way: a positive determinant and first entry, a finite determinant)
    and symmetric (:func:`~artmotion.tracking.experts.asymmetric`)."""
    det = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    if not (0.0 < det < _INF and a[0, 0] > 0):
        raise InputError("a belief's covariance is not finite and positive definite: "
                         f"[[{a[0, 0]:g}, {a[0, 1]:g}], [{a[1, 0]:g}, {a[1, 1]:g}]]")
    if asymmetric(a):
        raise InputError(f"a belief's covariance is not symmetric: its off-diagonal entries {a[0, 1]:.7g} and "
                         f"{a[1, 0]:.7g} differ")
    return np.array([[a[1, 1], -a[0, 1]], [-a[1, 0], a[0, 0]]]) / det


def _mean_problem(gaussians) -> str:
    """Why :func:`fuse` gave no finite mean (the beliefs are read again where they can be: a list
    or a dict's values)."""
    for i, g in enumerate(gaussians):
        if g is not None and not np.isfinite(g.mean).all():
            return f"belief {i} has a mean that is not finite ({g.mean[0]:g}, {g.mean[1]:g})"
    return "a belief's mean is not finite (or the product of the beliefs overflows)"


def _inv2(a: np.ndarray) -> np.ndarray:
    """Inverse of a 2x2 matrix (closed form; these are tiny and many)."""
    det = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    if not det > 0:
        return np.linalg.pinv(a)
    return np.array([[a[1, 1], -a[0, 1]], [-a[1, 0], a[0, 0]]]) / det


class PoTE:
    """A set of experts and their product.

    ``experts`` are :class:`~artmotion.tracking.experts.Expert` instances or registered names.
    :meth:`opinions` asks every expert; :meth:`estimate` fuses them (optionally leaving some out,
    e.g. the motion expert when its prior is applied by a Kalman update instead).
    """

    def __init__(self, experts: Sequence[Expert | str], calibrate: bool = True, prior_std: float = 0.05,
                 prior_weight: float = 10.0):
        if isinstance(experts, str):
            experts = check_experts(experts)
        try:
            experts = list(experts)
        except TypeError:
            raise InputError(f"experts must be a list of experts or their names, got {type(experts).__name__}") from None
        check_experts([e for e in experts if not isinstance(e, Expert)])
        self.experts: list[Expert] = [e if isinstance(e, Expert) else EXPERTS[e]() for e in experts]
        #: experts not built in (registered by the user): their beliefs are checked (the built-in
        #: ones give finite means and positive definite covariances by construction)
        self._unchecked = frozenset(e.name for e in self.experts if type(e) not in _BUILT_IN)
        #: learn each image expert's error online (Sec. 2.7.1: an expert's variance should match
        #: its actual performance): squared error relative to the box size against the detector
        self.calibrate = calibrate
        self.prior = np.array([prior_std ** 2, prior_std ** 2]) * prior_weight
        self.prior_weight = prior_weight
        self._sq: dict[str, np.ndarray] = {}
        self._n: dict[str, float] = {}

    def relative_variance(self, name: str) -> np.ndarray:
        """Current estimate of an expert's error variance, relative to the box's ``(w², h²)``."""
        return (self._sq.get(name, 0.0) + self.prior) / (self._n.get(name, 0.0) + self.prior_weight)

    def observe(self, opinions: dict, reference: np.ndarray, size) -> None:
        """Score the experts' opinions against a reference centre (an assigned detection)."""
        w, h = float(size[0]), float(size[1])
        for name, g in opinions.items():
            if g is None or name in ("det", "motion"):
                continue
            e = (g.mean - reference) / np.array([w, h])
            e2 = np.minimum(e ** 2, 0.25)   # one gross failure must not dominate
            self._sq[name] = self._sq.get(name, 0.0) + e2
            self._n[name] = self._n.get(name, 0.0) + 1.0

    def _calibrated(self, name: str, g: Gaussian | None, box) -> Gaussian | None:
        if g is None or not self.calibrate or name in ("det", "motion"):
            return g
        v = self.relative_variance(name) * np.asarray(box[2:4], dtype=float) ** 2
        cov = g.cov.copy()
        cov[0, 0] = max(cov[0, 0], v[0])
        cov[1, 1] = max(cov[1, 1], v[1])
        return Gaussian(g.mean, cov)

    @property
    def names(self) -> list[str]:
        return [e.name for e in self.experts]

    def opinions(self, frame: Frame, prev: Frame | None, entity: Entity,
                 skip: Iterable[str] = ()) -> dict[str, Gaussian | None]:
        skip = set(skip)
        ops = {}
        for e in self.experts:
            if e.name not in skip:
                g = e.propose(frame, prev, entity)
                if e.name in self._unchecked:
                    self._check(e.name, (g,), frame)
                ops[e.name] = self._calibrated(e.name, g, entity.box)
        return self._temper(ops)

    @staticmethod
    def _check(name: str, beliefs, frame: Frame) -> None:
        """The opinions of an expert of the user's must be ``None`` or a :class:`Gaussian` with a
        finite mean and a finite positive definite covariance (calibration would hide a zero or
        negative variance, and the product with a NaN belief is nothing)."""
        for g in beliefs:
            problem = None if g is None else belief_problem(g)
            if problem is not None:
                raise InputError(f"frame {frame.number}: expert {name!r} gave {problem}")

    def _temper(self, ops: dict) -> dict:
        # the product assumes independent experts; k experts of one family (same evidence)
        # count together as one: each one's covariance is multiplied by k
        fam: dict[str, int] = {}
        for e in self.experts:
            if e.family and ops.get(e.name) is not None:
                fam[e.family] = fam.get(e.family, 0) + 1
        for e in self.experts:
            g = ops.get(e.name)
            if g is not None and fam.get(e.family, 1) > 1:
                ops[e.name] = Gaussian(g.mean, g.cov * fam[e.family])
        return ops

    def estimate_many(self, frame: Frame, prev: Frame | None, entities: list,
                      skip: Iterable[str] = ()) -> list:
        """:meth:`estimate` for several entities, letting experts batch their work."""
        skip = set(skip)
        per: list[dict[str, Gaussian | None]] = [{} for _ in entities]
        for e in self.experts:
            if e.name in skip:
                continue
            beliefs = e.propose_many(frame, prev, entities)
            if e.name in self._unchecked:
                beliefs = list(beliefs)
                self._check(e.name, beliefs, frame)
            for d, ent, g in zip(per, entities, beliefs):
                d[e.name] = self._calibrated(e.name, g, ent.box)
        out = []
        for d in per:
            d = self._temper(d)
            out.append((fuse(d.values()), d))
        return out

    def estimate(self, frame: Frame, prev: Frame | None, entity: Entity,
                 skip: Iterable[str] = ()) -> tuple[Gaussian | None, dict[str, Gaussian | None]]:
        ops = self.opinions(frame, prev, entity, skip)
        return fuse(ops.values()), ops


#: the experts of this package, whose beliefs need no check
_BUILT_IN = frozenset({BlobExpert, DetectionExpert, FlowExpert, KLTExpert, MotionExpert})
