"""The application: one command from a video to an HTML report and a searchable event index,
and batch processing of whole archives on Dask (thesis 6.2.1)."""

from artmotion.app.batch import BatchReport, find_items, run_batch
from artmotion.app.index import EventIndex, parse_query
from artmotion.app.pipeline import RunResult, load_run, run_pipeline

__all__ = ["BatchReport", "EventIndex", "RunResult", "find_items", "load_run", "parse_query", "run_batch", "run_pipeline"]
