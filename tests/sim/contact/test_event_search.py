"""The one-dimensional searches of the adaptive contact events: a hop's apex and a gap's dip between samples
(:func:`animbatch.sim.contact.impact_events._golden_section`), and where a resting contact's mode changes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from animbatch.sim.contact.impact_events import ContactEvents, _golden_section


@pytest.mark.parametrize("start", [0.0, 1.0e6])  # late in a long run a step is tiny beside t itself
def test_golden_section_finds_a_parabola_s_least_value_to_the_fraction_asked_in_its_count_of_calls(start):
    """(t − c)² on [start, start + h]: the least value's place to 1e-7 of h (at start = 1e6 and h = 1e-6 the bracket
    stops shrinking at the rounding of t, and the search still ends), with one call per step plus two."""
    h = 1e-6 if start else 1.0
    centre = start + 0.3 * h
    calls = []

    def parabola(t: float) -> float:
        calls.append(t)
        return (t - centre) ** 2

    found = _golden_section(parabola, start, start + h, 1e-7)
    assert found == pytest.approx(centre, abs=max(1e-7 * h, 4 * math.ulp(start)))  # (t's rounding near 1e6: 1e-10)
    assert len(calls) == 2 + math.ceil(math.log(1e-7) / math.log((math.sqrt(5) - 1) / 2))  # 36: ternary took 80


class _Step:
    """A solver's last step, from 0 to 1 s, whose dense output is the time itself."""

    t_old, t = 0.0, 1.0

    @staticmethod
    def dense_output():
        return lambda t: np.array([t])


def test_a_mode_function_that_reads_differently_when_asked_again_changes_where_the_fresh_values_say():
    """Two resting contacts sharing one load can take any share of it, and a mode function asked again at the same
    state may read otherwise: a change that is already there at the step's start is at the start; one that is gone
    at its end is none (before: the root search threw "f(a) and f(b) must have different signs"); a true crossing
    is at its root."""
    events = ContactEvents.__new__(ContactEvents)
    # as the last step's end and this one's read them: the first contact's mode function crossed, the others not
    cached_before, cached_after = np.array([1.0, 1.0, 1.0]), np.array([-1.0, 1.0, 1.0])
    fresh = {  # each contact's mode function as asked again along the step
        "at the start already": lambda t: -0.5 + 0 * t,
        "gone at the end": lambda t: 0.5 + 0 * t,
        "a true crossing": lambda t: 0.3 - t,
    }
    for case, expected in (("at the start already", 0.0), ("gone at the end", None), ("a true crossing", 0.3)):
        events._mode_functions = lambda t, y, mode=fresh[case]: np.array([mode(t), 1.0, 1.0])
        found = events._first_mode_change(_Step(), cached_before, cached_after)
        assert found == (pytest.approx(expected, abs=1e-9) if expected is not None else None), case
