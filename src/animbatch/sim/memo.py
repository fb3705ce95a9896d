"""What an object computed for a key, remembered on the object: a contact step asks for the same few instants many
times (a moving collider's pose and motion for the reach, the search and the solve; a path's turn for its pose and
its velocity), and each answer costs numpy calls on a few numbers.

Arrays handed out are made read-only (an array, a tuple of them, or a dataclass whose fields they are): every caller
at a key gets the same object, so none may change what the next one reads. Each entry is read and written whole
(runs in threads may share a model)."""

from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import TypeVar

import numpy as np

_T = TypeVar("_T")


def remembered(owner: object, name: str, key: Hashable, compute: Callable[[], _T], *, keep: int = 16,
               hold: object = None) -> _T:
    """``compute()``, or what it gave for the same ``key`` under ``name`` on ``owner``. At most ``keep`` keys per
    name are remembered (then all are forgotten at once). ``hold``: an object the entry keeps alive, for a key that
    holds its identity (so the identity cannot be reused by another object while the entry lives)."""
    memo: dict[Hashable, tuple[_T, object]] = owner.__dict__.setdefault("_remembered", {}).setdefault(name, {})
    entry = memo.get(key)
    if entry is None:
        value = compute()
        for array in _arrays(value):
            array.flags.writeable = False
        if len(memo) >= keep:
            memo.clear()
        entry = memo[key] = (value, hold)
    return entry[0]


def _arrays(value: object) -> list[np.ndarray]:
    parts = value if isinstance(value, tuple) else (value,) if isinstance(value, np.ndarray) else vars(value).values()
    return [part for part in parts if isinstance(part, np.ndarray)]
