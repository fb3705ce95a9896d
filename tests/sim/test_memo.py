"""The per-key memo that moving colliders and keyframed paths answer repeated instants from."""

from __future__ import annotations

import gc
import weakref
from dataclasses import dataclass

import numpy as np
import pytest

from animbatch.sim.memo import remembered


class Owner:
    pass


@dataclass
class Pair:
    first: np.ndarray
    second: np.ndarray


def test_a_key_asked_again_gets_the_same_read_only_answer_and_a_new_key_its_own():
    owner, calls = Owner(), []

    def compute(t: float) -> tuple[np.ndarray, np.ndarray]:
        calls.append(t)
        return np.full(3, t), np.full(3, 2 * t)

    first = remembered(owner, "motion", 0.5, lambda: compute(0.5))
    assert remembered(owner, "motion", 0.5, lambda: compute(0.5)) is first and calls == [0.5]
    np.testing.assert_array_equal(remembered(owner, "motion", 0.25, lambda: compute(0.25))[1], 0.5)
    assert calls == [0.5, 0.25]
    assert remembered(owner, "other", 0.5, lambda: compute(0.5)) is not first  # names are apart
    for array in (*first, remembered(owner, "pair", 0, lambda: Pair(np.zeros(2), np.ones(2))).second,
                  remembered(owner, "array", 0, lambda: np.zeros(2))):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 1.0


def test_past_its_size_the_memo_forgets_and_held_objects_live_as_long_as_their_entry():
    owner, calls = Owner(), []
    for t in (0.0, 1.0, 0.0):
        remembered(owner, "place", t, lambda t=t: calls.append(t) or np.zeros(1), keep=1)
    assert calls == [0.0, 1.0, 0.0]  # one instant remembered: the first was forgotten for the second

    class Rest:
        pass

    rest = Rest()
    alive = weakref.ref(rest)
    remembered(owner, "held", (id(rest), 0.0), lambda: np.zeros(1), keep=1, hold=rest)
    del rest
    gc.collect()
    assert alive() is not None  # the key holds its identity: the object must outlive the entry
    remembered(owner, "held", (0, 1.0), lambda: np.zeros(1), keep=1)
    gc.collect()
    assert alive() is None
