"""Settings of the multi-object tracker, one set for every sequence.

Times are in seconds and sizes relative to boxes, so that the same settings hold at 7 and at 30
frames per second and at 640×480 and 1920×1080. The defaults were chosen by leave-one-sequence-out
over the five shared sequences (docs/tracking.md, ``benchmarks/tracking_loo.py``); every
component that is off by default is off because the ablation showed it does not raise the mean.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass, fields
from typing import Any

from artmotion.errors import InputError, check_range

__all__ = ["DETECT_EVERY", "TrackerConfig", "check_detect_every"]

#: the built-in detector runs on every this many frames (docs/tracking.md, "Built-in detector")
DETECT_EVERY = 2


def check_detect_every(k, name: str = "detect_every") -> int:
    """``k`` (every k-th frame detected) checked: a whole number in [1, 100]; ``name`` is what the
    message calls it (the Python argument, or a command's ``--detect-every``)."""
    return check_range(name, k, 1, 100, integer=True)


#: what ``experts_when`` may say
EXPERTS_WHEN = ("all", "lost", "none")
#: settings that are scores, IoUs or shares, in [0, 1] (gates that 0 would shut: in (0, 1])
_SHARES = frozenset({"high", "low", "match_iou", "birth_iou", "merge_iou", "join_ratio", "duplicate_share",
                     "min_track_score"})
_OPEN_SHARES = frozenset({"match_iou", "birth_iou", "merge_iou"})
#: the least value of the whole-number settings
_INT_LEAST = {"confirm_hits": 1, "app_parts": 1}
#: the largest value of any other setting (seconds, box sizes, KL divergences, noise levels)
_MAX_VALUE = 1e6


@dataclass
class TrackerConfig:
    """Settings of :class:`~artmotion.tracking.mot.MultiObjectTracker`."""

    # -- detections (Sec. 2.4.1) -------------------------------------------------------------
    high: float = 0.5           #: score of a detection in the first association stage and for a birth
    low: float = 0.2            #: lowest score used at all (second stage: only for tracks seen last frame)
    # -- state (Sec. 2.5.1, Eq. 2.10) ---------------------------------------------------------
    accel: float = 0.5          #: acceleration std of the centre, box sizes per s²
    size_accel: float = 0.1     #: acceleration std of width/height, box sizes per s²
    meas: float = 0.08          #: a detection's centre std, relative to the box size
    size_meas: float = 0.05     #: a detection's width/height std, relative to the box size
    adapt_noise: bool = True    #: estimate both noises from the detections (accel, meas: their priors)
    noise_horizon: float = 1.0  #: seconds over which the estimated acceleration is measured
    camera: bool = True         #: estimate and compensate the camera's motion (camera.py)
    # -- association (Eq. 2.4 with a one-to-one assignment) -----------------------------------
    match_iou: float = 0.2      #: IoU gate between a predicted box and a detection
    app_weight: float = 0.1     #: weight of the histograms' KL divergence next to 1 - IoU
    reacquire_kl: float = 0.0   #: a lost track is re-acquired only by a detection within this KL (0: any)
    app_parts: int = 1          #: horizontal bands of a box with histograms of their own (2: upper body, legs)
    # -- births and deaths (Sec. 2.5.4) ------------------------------------------------------
    birth_iou: float = 0.7      #: no new track on a detection overlapping a live track this much
    confirm_hits: int = 2       #: detections that confirm a tentative track
    tentative_misses: int = 0   #: misses a tentative track survives
    max_lost: float = 1.5       #: seconds an unmatched confirmed track is kept for re-acquisition
    exit_test: bool = False     #: end a lost track early when the appearance test says it left (Sec. 2.5.4)
    exit_kl: float = 1.0        #: KL divergence at which a lost box no longer shows the entity
    # -- groups (Sec. 2.5.2) -----------------------------------------------------------------
    groups: bool = True         #: occlusion groups (merge/split events; members kept while hidden)
    merge_iou: float = 0.3      #: Eq. 2.11 overlap that detects an occlusion
    join_ratio: float = 0.5     #: Eq. 2.12 share of a track inside a group that makes it join
    max_group: float = 3.0      #: seconds a hidden member is kept in its group
    split_app: bool = False     #: re-solve the members' identities by appearance when they reappear
    # -- image experts (Sec. 2.4.2-2.4.5) ----------------------------------------------------
    experts_when: str = "lost"  #: which tracks the image experts predict: "all", "lost" or "none"
    # -- offline pass (Sec. 2.5.3) -----------------------------------------------------------
    smooth: bool = True         #: RTS smoothing of each track (offline); else the filtered boxes
    max_interp: float = 1.0     #: seconds of a gap between detections filled by the smoother
    tail: float = 0.0           #: seconds of lost tail reported after the last detection
    stitch: bool = False        #: join tracklets that motion and appearance connect across a gap
    max_gap: float = 2.0        #: seconds across which tracklets may be stitched
    stitch_dist: float = 0.5    #: stitching tolerance: box heights, plus ...
    stitch_speed: float = 0.5   #: ... box heights per second of gap
    stitch_kl: float = 1.5      #: largest KL divergence of the histograms of stitched tracklets
    min_life: float = 0.6       #: offline: a track shorter than this that appears and vanishes inside the image is dropped
    min_track_score: float = 0.0  #: offline: a track whose detections score less than this on average is dropped
    duplicate_share: float = 0.2  #: offline: a track nested in another on this share of its frames may be a duplicate (0: off)
    duplicate_drift: float = 0.06  #: ... when its centre keeps its place in the other's box (std, box heights)
    # -- online output and events ------------------------------------------------------------
    online_coast: float = 0.0   #: seconds an online result keeps reporting a lost track
    split_hold: float = 0.3     #: seconds a split must hold; a re-merge within it continues the group

    def check(self) -> TrackerConfig:
        """This configuration, or an :class:`~artmotion.errors.InputError` naming the first setting
        out of its range (a NaN gate once gave no tracks without a word; an infinite time a
        deep OverflowError). Whole-number settings given as NumPy integers become ``int``."""
        for f in fields(self):
            v = getattr(self, f.name)
            if f.type in ("bool", bool):
                if not isinstance(v, bool):
                    raise InputError(f"{f.name} must be True or False, got {v!r}")
            elif f.name == "experts_when":
                if v not in EXPERTS_WHEN:
                    raise InputError(f"experts_when must be one of {', '.join(EXPERTS_WHEN)}, got {v!r}")
            elif f.type in ("int", int):
                # a NumPy integer is one (numbers.Integral); a bool is not, nor is 2.0
                if isinstance(v, bool) or not isinstance(v, numbers.Integral):
                    raise InputError(f"{f.name} must be a whole number, got {v!r}")
                setattr(self, f.name, check_range(f.name, v, _INT_LEAST.get(f.name, 0), 1000, integer=True))
            elif f.name in _SHARES:
                check_range(f.name, v, 0.0, 1.0, lo_open=f.name in _OPEN_SHARES)
            else:
                check_range(f.name, v, 0.0, _MAX_VALUE)
        if not self.adapt_noise:
            # a detection known exactly and a motion without noise: the Kalman update would divide
            # by zero (a singular innovation covariance)
            for meas, accel in (("meas", "accel"), ("size_meas", "size_accel")):
                if getattr(self, meas) == 0 and getattr(self, accel) == 0:
                    raise InputError(f"{meas} and {accel} must not both be 0 when adapt_noise is False "
                                     "(a detection known exactly and a motion without noise)")
        return self

    @classmethod
    def names(cls) -> list[str]:
        return [f.name for f in fields(cls)]

    @classmethod
    def textbook(cls, **changes) -> TrackerConfig:
        """Settings that depend on no data: SORT/ByteTrack-like textbook values (ByteTrack's score
        levels 0.6/0.1, an IoU gate of 0.2, 1 s of re-acquisition, 5 % box noise, no appearance,
        no offline filtering of tracks). The leave-one-out search starts here; objects other than
        people, which the defaults were not chosen on, are tracked with these and the noise
        levels estimated from their own detections (``adapt_noise=True``)."""
        base: dict[str, Any]
        base = dict(high=0.6, low=0.1, accel=1.0, size_accel=0.25, meas=0.05, size_meas=0.05, adapt_noise=False,
                    noise_horizon=1.0, camera=True, match_iou=0.2, app_weight=0.0, app_parts=1, reacquire_kl=0.0,
                    birth_iou=0.7, confirm_hits=2, tentative_misses=0, max_lost=1.0, exit_test=False, groups=True,
                    merge_iou=0.3, max_group=3.0, split_app=False, experts_when="lost", smooth=True,
                    max_interp=1.0, tail=0.0, stitch=False, max_gap=2.0, stitch_dist=0.5, stitch_kl=1.5,
                    min_life=0.0, min_track_score=0.0, duplicate_share=0.0)
        return cls(**(base | changes))
