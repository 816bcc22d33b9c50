"""artmotion.articulation: how things move (thesis chapter 4).

* :mod:`~artmotion.articulation.models` — configuration fits of point models (Eq. 4.1, 4.3.3);
* :mod:`~artmotion.articulation.rigid` — factorisation ``W = M S`` and rigid-body classification (4.3.2);
* :mod:`~artmotion.articulation.temporal` — Taylor models of any order (4.4), Table 4.1, Fig. 4.5;
* :mod:`~artmotion.articulation.online` — Algorithm 1, online model selection (4.5);
* :mod:`~artmotion.articulation.slam` — EKF SLAM and Articulated EKF SLAM, Algorithm 2 (4.6-4.7);
* :mod:`~artmotion.articulation.trajectory` — trajectory files and ``articulation fit``.
"""

from artmotion.articulation.models import (
    PlanarModel,
    PrismaticModel,
    RevoluteModel,
    StaticModel,
    fit_circle_2d,
    fit_circle_joint,
)
from artmotion.articulation.online import OnlineEstimator, OnlineResult, estimate_online
from artmotion.articulation.rigid import classify_motion, classify_points, classify_poses, factorize
from artmotion.articulation.trajectory import fit_trajectory, read_trajectory

__all__ = [
    "OnlineEstimator",
    "OnlineResult",
    "PlanarModel",
    "PrismaticModel",
    "RevoluteModel",
    "StaticModel",
    "classify_motion",
    "classify_points",
    "classify_poses",
    "estimate_online",
    "factorize",
    "fit_circle_2d",
    "fit_circle_joint",
    "fit_trajectory",
    "read_trajectory",
]
