"""artmotion.articulation: how things move (thesis chapter 4).

* :mod:`~artmotion.articulation.models` — configuration fits of point models (Eq. 4.1, 4.3.3);
* :mod:`~artmotion.articulation.rigid` — factorisation ``W = M S`` and rigid-body classification (4.3.2);
* :mod:`~artmotion.articulation.temporal` — Taylor models of any order (4.4), Table 4.1, Fig. 4.5;
* :mod:`~artmotion.articulation.online` — Algorithm 1, online model selection (4.5);
* :mod:`~artmotion.articulation.video` — joints from plain video (4.3.2 on image tracks);
* :mod:`~artmotion.articulation.slam` — EKF SLAM and Articulated EKF SLAM, Algorithm 2 (4.6-4.7);
* :mod:`~artmotion.articulation.trajectory` — trajectory files and ``articulation fit``.
"""

from artmotion._lazy import lazy_attributes

_WHERE = {
    "PlanarModel": "models",
    "PrismaticModel": "models",
    "RevoluteModel": "models",
    "StaticModel": "models",
    "fit_circle_2d": "models",
    "fit_circle_joint": "models",
    "OnlineEstimator": "online",
    "OnlineResult": "online",
    "estimate_online": "online",
    "classify_motion": "rigid",
    "classify_points": "rigid",
    "classify_poses": "rigid",
    "factorize": "rigid",
    "analyze_video": "video",
    "fit_trajectory": "trajectory",
    "read_trajectory": "trajectory",
}
__all__ = sorted(_WHERE)
__getattr__ = lazy_attributes(__name__, _WHERE)
