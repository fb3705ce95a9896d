"""The benchmark script keeps working as the library changes: its cheap parts run in --quick mode and report
finite, positive numbers. (Speed itself is measured by ``bash scripts/dev.sh bench``, never asserted here.)"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CHEAP = ["particles", "ivp", "rigid", "contacts", "render", "encode", "lean", "ledger", "joints", "startup", "stream", "pool"]  # a few seconds each with --quick


def test_the_cheap_benchmarks_run_and_report_every_number(tmp_path):
    rows_file = tmp_path / "rows.json"
    command = [sys.executable, str(ROOT / "benchmarks" / "run.py"), "--quick", "--json", str(rows_file)]
    for name in CHEAP:
        command += ["--only", name]
    finished = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert finished.returncode == 0, finished.stderr[-3000:]
    rows = json.loads(rows_file.read_text())
    assert {row["benchmark"].split()[0] for row in rows} >= {"particle", "solve_ivp", "rigid", "contacts", "render",
                                                              "encode", "only", "accuracy", "joints",
                                                              "start-up"}
    for row in rows:
        value = row["value"]
        if isinstance(value, (int, float)):
            assert math.isfinite(value) and value >= 0, row
    # the table on stdout lists every row
    assert len([line for line in finished.stdout.splitlines() if line.strip()]) >= len(rows) + 3
