"""SLAM with articulated landmarks (Sections 4.6-4.7).

* :mod:`~artmotion.articulation.slam.ekf` — robot and observation models (Eq. 4.20-4.28), EKF SLAM
  and Articulated EKF SLAM (Algorithm 2);
* :mod:`~artmotion.articulation.slam.world` — simulated worlds and runs;
* :mod:`~artmotion.articulation.slam.evaluate` — running back ends, pose errors, Monte Carlo, figures.
"""

from artmotion.articulation.slam.ekf import EKFSlam, control_noise, motion_model, observe
from artmotion.articulation.slam.evaluate import monte_carlo, plot_run, pose_errors, run_slam
from artmotion.articulation.slam.world import SimConfig, World, make_world, simulate

__all__ = ["motion_model", "control_noise", "observe", "EKFSlam", "World", "SimConfig", "make_world", "simulate",
           "run_slam", "pose_errors", "monte_carlo", "plot_run"]
