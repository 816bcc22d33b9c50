"""artmotion.pose: joint angles of an articulated tool from its bounding-box crop.

Gaussian-process regression on HOG/LBP features (thesis Sec. 3.4) with a per-angle
constant-velocity Kalman filter (Sec. 3.5). See docs/pose.md.
"""

__all__ = ["PoseFilter", "PoseRegressor"]


def __getattr__(name):  # lazy: the root CLI imports artmotion.pose.cli without the numeric stack
    if name in __all__:
        from artmotion.pose import model

        return getattr(model, name)
    raise AttributeError(name)
