"""Fuzzing: mutated scenes never get a traceback or a hang, only a located SceneError or a documented refusal.

The CI profile runs a bounded number of mutants (seconds); ``bash scripts/dev.sh fuzz`` runs 10 000 of them and
prints what happened to each (see ``benchmarks/fuzz.py``). The mutations are described in ``tests/fuzzing.py``.
"""

from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, given, settings

from support.fuzzing import check, mutants

EXAMPLES = int(os.environ.get("ANIMBATCH_FUZZ_EXAMPLES", "120"))


@pytest.mark.slow
@settings(max_examples=EXAMPLES, deadline=None, derandomize=EXAMPLES <= 200, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(mutants())
def test_mutated_scenes_load_or_fail_with_a_located_error_and_simulate_or_refuse(mutant):
    base, text = mutant
    check(base, text)
