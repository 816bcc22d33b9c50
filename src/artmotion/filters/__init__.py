"""The Kalman family and motion models of any order.

Names follow filterpy's textbook convention: state ``x``, covariance ``P``, transition ``F``,
process noise ``Q``, measurement matrix ``H``, measurement noise ``R``.
"""

from artmotion.filters.kalman import KalmanFilter, gaussian_loglik
from artmotion.filters.models import (
    constant_velocity,
    taylor_model,
    taylor_transition,
    white_noise_input,
)

__all__ = [
    "KalmanFilter",
    "constant_velocity",
    "gaussian_loglik",
    "taylor_model",
    "taylor_transition",
    "white_noise_input",
]
