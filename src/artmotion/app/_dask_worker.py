"""Preloaded by the worker processes of a batch's local Dask cluster (``LocalCluster(preload=...)``).

A Ctrl-C in the terminal reaches every process of its group; the batch (the parent) handles it:
it stops, cancels the items and closes the cluster. The workers ignore it, so that they print no
``KeyboardInterrupt`` tracebacks while they are being closed.
"""

import signal
import threading

if threading.current_thread() is threading.main_thread():
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def dask_setup(worker) -> None:  # the preload interface: nothing more to do
    pass
