"""The benchmark script keeps working as the library changes: its cheap parts run in --quick mode and report
finite, positive numbers. (Speed itself is measured by ``bash scripts/dev.sh bench``, never asserted here.)"""

from __future__ import annotations

import json
import math
import subprocess
import sys

import pytest

from support.paths import REPO

#: The cheap benchmarks (a few seconds each with --quick), in two halves that the test workers run side by side, each
#: with the first words of the rows it must report.
CHEAP = {"simulation, encoding, start-up": (
             ["particles", "ivp", "rigid", "contacts", "lean", "ledger", "joints", "pool", "encode", "startup", "grade"],
             {"particle", "solve_ivp", "rigid", "contacts", "only", "accuracy", "joints", "encode", "start-up", "grade"}),
         "drawing": (["render", "stream"], {"render"})}


@pytest.mark.slow
@pytest.mark.parametrize("half", list(CHEAP))
def test_the_cheap_benchmarks_run_and_report_every_number(tmp_path, half):
    names, reported = CHEAP[half]
    rows_file = tmp_path / "rows.json"
    command = [sys.executable, str(REPO / "benchmarks" / "run.py"), "--quick", "--json", str(rows_file)]
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


def test_the_peers_benchmark_builds_each_case_twice_from_the_same_numbers():
    """The MuJoCo comparison (benchmarks/peers.py, run only where the bench extra is installed) keeps its two sides
    alike: the animbatch chain and the MJCF chain have the same bars, masses and hinges, and both parse."""
    from xml.etree import ElementTree

    sys.path.insert(0, str(REPO / "benchmarks"))
    import peers
    from animbatch.compile.model import compile_scene
    from animbatch.stages import parse_scene

    model = compile_scene(parse_scene(peers.chain_scene(count=5, mass=0.2), filename="chain.yaml").spec)
    assert model.rigid_count == 5 and model.joints.count == 5
    assert model.rigid.mass == pytest.approx([0.2] * 5)
    xml = ElementTree.fromstring(peers.chain_mjcf(count=5, mass=0.2))
    assert len(xml.findall(".//joint[@type='hinge']")) == 5
    assert [float(geom.get("mass")) for geom in xml.iter("geom")] == pytest.approx([0.2] * 5)
    assert compile_scene(parse_scene(peers.bar_scene(100), filename="bar.yaml").spec).joints.count == 1
    # a 1 m bar about its end: 2π √(2L/3g) for small swings, some 7 % longer at 60°
    assert peers.bar_period() == pytest.approx(2 * math.pi * math.sqrt(2 * 1.0 / (3 * 9.81)) * 1.073, rel=1e-3)
    ElementTree.fromstring(peers.bar_mjcf())
    ElementTree.fromstring(peers.double_pendulum_mjcf())
    # the pile: the same dozen boxes on both sides; the ragdoll: eleven bodies, four ball joints' worth of each side
    pile = compile_scene(parse_scene(peers.pile_scene(duration=0.1), filename="pile.yaml").spec)
    assert pile.rigid_count == peers.PILE_COUNT
    assert pile.rigid.mass == pytest.approx([peers.PILE_DENSITY * peers.PILE_SIDE ** 3] * peers.PILE_COUNT)
    assert len(ElementTree.fromstring(peers.pile_mjcf()).findall(".//freejoint")) == peers.PILE_COUNT
    ragdoll = ElementTree.fromstring(peers.ragdoll_mjcf())
    assert len(ragdoll.findall(".//body")) == 11
    assert len(ragdoll.findall(".//joint[@type='ball']")) == 6
    assert len(ragdoll.findall(".//joint[@type='hinge']")) == 4
