"""artmotion.pose: joint angles of an articulated tool from its bounding-box crop.

Gaussian-process regression on HOG/LBP features (thesis Sec. 3.4) with a per-angle
constant-velocity Kalman filter (Sec. 3.5). See docs/pose.md.
"""

from artmotion._lazy import lazy_attributes

_WHERE = {"PoseFilter": "filter", "PoseRegressor": "model"}
__all__ = sorted(_WHERE)
__getattr__ = lazy_attributes(__name__, _WHERE)
