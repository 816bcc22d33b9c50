"""CLI commands of :mod:`artmotion.app` (registered on the root app by :func:`register`)."""

from __future__ import annotations

import typer


def register(app: typer.Typer) -> None:
    """Add this capability's commands to the root artmotion app."""
