"""Preloaded by the worker processes of a batch's local Dask cluster (``LocalCluster(preload=...)``).

A Ctrl-C in the terminal reaches every process of its group; the batch (the parent) handles it:
it stops, cancels the items and closes the cluster. The workers ignore it, so that they print no
``KeyboardInterrupt`` tracebacks while they are being closed. Their own log messages are silenced
too: a worker whose scheduler has just been closed logs "Failed to communicate with scheduler
during heartbeat" with a traceback, and an item's failure reaches the batch through its future.
"""

import logging
import signal
import threading

if threading.current_thread() is threading.main_thread():
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def dask_setup(worker) -> None:  # the preload interface, called once the worker's logging is set up
    logging.getLogger("distributed").setLevel(logging.CRITICAL)
