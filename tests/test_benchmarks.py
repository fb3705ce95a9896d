"""The benchmark script keeps working as the library changes: its cheap parts run in --quick mode and report
finite, positive numbers. (Speed itself is measured by ``bash scripts/dev.sh bench``, never asserted here.)"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: The cheap benchmarks (a few seconds each with --quick), in two halves that the test workers run side by side, each
#: with the first words of the rows it must report.
CHEAP = {"simulation, encoding, start-up": (
             ["particles", "ivp", "rigid", "contacts", "lean", "ledger", "joints", "pool", "encode", "startup"],
             {"particle", "solve_ivp", "rigid", "contacts", "only", "accuracy", "joints", "encode", "start-up"}),
         "drawing": (["render", "stream"], {"render"})}


@pytest.mark.slow
@pytest.mark.parametrize("half", list(CHEAP))
def test_the_cheap_benchmarks_run_and_report_every_number(tmp_path, half):
    names, reported = CHEAP[half]
    rows_file = tmp_path / "rows.json"
    command = [sys.executable, str(ROOT / "benchmarks" / "run.py"), "--quick", "--json", str(rows_file)]
    for name in names:
        command += ["--only", name]
    finished = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert finished.returncode == 0, finished.stderr[-3000:]
    rows = json.loads(rows_file.read_text())
    assert {row["benchmark"].split()[0] for row in rows} >= reported
    for row in rows:
        value = row["value"]
        if isinstance(value, (int, float)):
            assert math.isfinite(value) and value >= 0, row
    # the table on stdout lists every row
    assert len([line for line in finished.stdout.splitlines() if line.strip()]) >= len(rows) + 3
