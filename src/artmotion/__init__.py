"""artmotion — vision-based articulated motion understanding.

Capabilities (one subpackage each): :mod:`artmotion.tracking`, :mod:`artmotion.pose`,
:mod:`artmotion.articulation`, :mod:`artmotion.language`, and the application layer
:mod:`artmotion.app`, over shared pieces :mod:`artmotion.geometry`, :mod:`artmotion.filters`
and :mod:`artmotion.io`.
"""

from artmotion.errors import ArtmotionError, InputError

__version__ = "0.1.0"
__all__ = ["ArtmotionError", "InputError", "__version__"]
