"""Atomic file output: write to a hidden temporary file in the same folder, then rename over the target.

A rename within one file system is atomic, so a reader (or a later run) sees either the old file or the complete new
one, never a half-written file. An interrupted or failed write leaves no target and removes its temporary file.
Temporary names start with a dot, name the host and process writing them, and keep the suffix
(``.clip.mp4.partial-node7-123.mp4``), so that tools which infer the format from the suffix still work,
``frame_*.png`` globs never match them, and a later run can tell a writer that was killed (its process is gone from
this host) from one still writing (:func:`sweep_partials`).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import socket
from collections.abc import Iterator
from pathlib import Path
from typing import Any


def _host() -> str:
    """This host's name as temporary names carry it (no dashes or dots: the name is split on them)."""
    return re.sub(r"[^A-Za-z0-9_]", "_", socket.gethostname()) or "host"


def partial_path(target: Path) -> Path:
    """The temporary name used while ``target`` is being written by this process."""
    return target.with_name(f".{target.name}.partial-{_host()}-{os.getpid()}{target.suffix}")


#: A temporary name: ``.<target>.partial-<host>-<pid><suffix>`` (or, written by older versions, without the host).
_PARTIAL = re.compile(r"^\..+\.partial-(?:(?P<host>[A-Za-z0-9_]+)-)?(?P<pid>\d+)(?:\.[^.]*)?$")


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def sweep_partials(folder: str | Path) -> list[Path]:
    """Delete the temporary files in ``folder`` whose writer was killed (a process of this host that is gone), and
    return them; those of running writers, and of other hosts sharing the folder, are kept."""
    removed: list[Path] = []
    folder = Path(folder)
    if not folder.is_dir():
        return removed
    host = _host()
    for path in folder.iterdir():
        found = _PARTIAL.match(path.name)
        if found is None or found["host"] not in (None, host) or _running(int(found["pid"])):
            continue
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
            removed.append(path)
    return removed


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
