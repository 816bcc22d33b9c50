"""artmotion.tracking: people tracking through occlusions (thesis Ch. 2).

``track(source)`` runs the Product of Tracking Experts (Sec. 2.4) inside the group-node
multi-object tracker (Sec. 2.5) and returns the tracks (MOTChallenge rows) and events.
Names are imported on first use (the command line stays fast).
"""

from artmotion._lazy import lazy_attributes

_WHERE = {
    "DEFAULT_EXPERTS": "api",
    "TrackResult": "api",
    "run_tracker": "api",
    "track": "api",
    "EXPERTS": "experts",
    "Expert": "experts",
    "Gaussian": "experts",
    "box_gaussian": "experts",
    "register_expert": "experts",
    "TrackerConfig": "config",
    "MultiObjectTracker": "mot",
    "PoTE": "pote",
    "fuse": "pote",
    "Sequence": "api",
    "open_sequence": "api",
    "evaluate": "metrics",
}
__all__ = sorted(_WHERE)
__getattr__ = lazy_attributes(__name__, _WHERE)
