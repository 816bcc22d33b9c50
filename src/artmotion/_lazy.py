"""Lazy package attributes (PEP 562): ``artmotion --help`` must not import the numeric stack.

A package lists which of its modules defines each public name; the module is imported the first
time the name is used (``from artmotion.tracking import track`` works as usual)."""

from __future__ import annotations

import importlib


def lazy_attributes(package: str, where: dict[str, str]):
    """A module ``__getattr__`` for ``package`` that imports ``package.<where[name]>`` on demand."""

    def __getattr__(name: str):
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f"{package}.{module}"), name)

    return __getattr__
