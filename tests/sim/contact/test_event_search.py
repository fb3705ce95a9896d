"""The one-dimensional search the adaptive contact events use to find a hop's apex and a gap's dip between samples
(:func:`animbatch.sim.contact.impact_events._golden_section`)."""

from __future__ import annotations

import math

import pytest

from animbatch.sim.contact.impact_events import _golden_section


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
