"""PyTorch, imported with the terminal's signals held back (:func:`artmotion._native.signals_held`):
a Ctrl-C during torch's native start-up aborted the process with a C++ stack dump. Modules that
use torch import it from here (``from artmotion._torch import nn, torch``)."""

from __future__ import annotations

from artmotion._native import signals_held

with signals_held():
    import torch as torch
    from torch import nn as nn

__all__ = ["nn", "torch"]
