"""artmotion.tracking.instruments: surgical instruments in laparoscopic video (thesis Sec. 2.6.1).

* :mod:`~artmotion.tracking.instruments.annotations` — ``tools.csv`` annotations and prediction files;
* :mod:`~artmotion.tracking.instruments.evaluate` — heads within a radius, shaft angles, identities;
* :mod:`~artmotion.tracking.instruments.detector` — a head detector learnt from annotated frames;
* :mod:`~artmotion.tracking.instruments.track` — instruments tracked with the camera's motion taken out.
"""

from artmotion._lazy import lazy_attributes

_WHERE = {
    "read_tools_csv": "annotations",
    "read_predictions": "annotations",
    "write_predictions": "annotations",
    "evaluate_tools": "evaluate",
}
__all__ = sorted(_WHERE)
__getattr__ = lazy_attributes(__name__, _WHERE)
