"""Atomic file output: write to a hidden temporary file in the same folder, then rename over the target.

A rename within one file system is atomic, so a reader (or a later run) sees either the old file or the complete new
one, never a half-written file. An interrupted or failed write leaves no target and removes its temporary file.
Temporary names start with a dot and keep the suffix (``.clip.mp4.partial-123.mp4``), so that tools which infer the
format from the suffix still work, and ``frame_*.png`` globs never match them.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any


def partial_path(target: Path) -> Path:
    """The temporary name used while ``target`` is being written."""
    return target.with_name(f".{target.name}.partial-{os.getpid()}{target.suffix}")


@contextlib.contextmanager
def atomic_path(target: str | Path) -> Iterator[Path]:
    """Yield a temporary path to write; on success it is renamed to ``target``, on error it is removed."""
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    temporary = partial_path(target)
    try:
        yield temporary
        os.replace(temporary, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            temporary.unlink()
        raise


def write_text_atomic(target: str | Path, text: str) -> None:
    with atomic_path(target) as temporary:
        temporary.write_text(text, encoding="utf-8")


def write_json_atomic(target: str | Path, data: Any) -> None:
    write_text_atomic(target, json.dumps(data, indent=2, sort_keys=False, default=str) + "\n")
