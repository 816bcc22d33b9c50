"""Writing benchmark figures into docs/: one block between ``<!-- name -->`` and ``<!-- /name -->``."""

from __future__ import annotations

import re
from pathlib import Path


def replace_block(path: Path, name: str, text: str) -> None:
    """Replace the text between ``<!-- name -->`` and ``<!-- /name -->`` in ``path`` (atomically)."""
    from artmotion.io import atomic_write

    doc = path.read_text(encoding="utf-8")
    pat = re.compile(rf"(<!-- {name} -->\n).*?(<!-- /{name} -->)", re.S)
    if not pat.search(doc):
        raise SystemExit(f"error: {path}: no <!-- {name} --> ... <!-- /{name} --> block")
    with atomic_write(path) as fh:
        fh.write(pat.sub(lambda m: m.group(1) + text.strip() + "\n" + m.group(2), doc))
