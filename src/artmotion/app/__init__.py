"""The application: one command from a video to an HTML report and a searchable event index,
and batch processing of whole archives on Dask (thesis 6.2.1)."""

from artmotion._lazy import lazy_attributes

_WHERE = {
    "BatchReport": "batch",
    "find_items": "batch",
    "run_batch": "batch",
    "EventIndex": "index",
    "parse_query": "index",
    "RunResult": "pipeline",
    "load_run": "pipeline",
    "run_pipeline": "pipeline",
}
__all__ = sorted(_WHERE)
__getattr__ = lazy_attributes(__name__, _WHERE)
