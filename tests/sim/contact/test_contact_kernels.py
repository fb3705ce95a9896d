"""The compiled contact-impulse sweeps against the numpy solver itself, on a pile of balls and boxes (the closed
forms of test_contacts.py run with both sweeps, through its ``sweeps`` fixture)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from animbatch.sim import kernels
from support.scenes import run

pytest.importorskip("numba", reason="numba is not installed: numpy solves every contact")


def pile() -> str:
    """144 balls in a loose jittered grid and 4 turned crates above a floor and a half-buried stone."""
    rng = np.random.default_rng(2)
    lines = []
    for i, (x, y, z) in enumerate(np.stack(np.meshgrid(np.arange(6), np.arange(4), np.arange(6)), -1).reshape(-1, 3)):
        dx, dz = rng.uniform(-0.004, 0.004, 2)
        lines.append(f"  - {{name: ball{i}, radius: 0.03, mass: 0.05, material: rubber, "
                     f"position: [{0.065 * x + dx:.4f}, {0.3 + 0.065 * y:.4f}, {0.065 * z + dz:.4f}]}}")
    for i, (x, z) in enumerate([(0, 0), (0.2, 0), (0, 0.2), (0.2, 0.2)]):
        lines.append(f"  - {{name: crate{i}, type: rigid, shape: {{type: box, size: [0.12, 0.08, 0.1]}}, density: 500, "
                     f"material: wood, position: [{x + 0.05}, 0.7, {z + 0.05}], "
                     f"orientation: {{axis: [1, 1, 0], angle: {30 + 10 * i}}}}}")
    bodies = "\n".join(lines)
    return f"""
duration: 0.25
fps: 20
solver: {{method: symplectic_euler, dt: 0.002}}
bodies:
{bodies}
colliders:
  - {{type: plane, material: wood}}
  - {{type: sphere, position: [0.15, 0, 0.15], radius: 0.12, material: steel}}
fields: [{{type: gravity}}]
"""


@pytest.mark.slow
def test_compiled_sweeps_give_the_numpy_solver_s_pile(monkeypatch):
    """144 balls and 4 turned crates dropped on a floor and a half-buried stone: the same motion, to round-off, with
    the compiled sweeps as with the numpy ones (a quarter second, while the pile forms)."""
    monkeypatch.setenv(kernels.KERNELS_VARIABLE, "numpy")
    _, plain = run(pile())
    monkeypatch.setenv(kernels.KERNELS_VARIABLE, "numba")
    _, compiled = run(pile())
    assert np.abs(plain.positions[-1] - plain.positions[0]).max() > 0.1  # things fell and met
    assert np.abs(compiled.positions - plain.positions).max() < 1e-8
    assert np.abs(compiled.angular_velocities - plain.angular_velocities).max() < 1e-5
    impacts, expected = np.array(compiled.solver_stats["impacts"]), np.array(plain.solver_stats["impacts"])
    assert impacts.shape == expected.shape and len(expected) > 10
    assert np.array_equal(impacts[:, 1], expected[:, 1]) and np.abs(impacts[:, 0] - expected[:, 0]).max() < 1e-12


@pytest.mark.slow
def test_kernels_that_fail_to_build_leave_the_contacts_to_numpy_and_say_so(monkeypatch):
    """numba loads but cannot compile the contact sweeps: the solve warns and gives the numpy solver's result."""
    from numba.core.errors import TypingError

    from animbatch.sim.contact import impulses
    from animbatch.sim.kernels import contact_impulses

    def broken(*args, **kwargs):
        raise TypingError("no implementation for this machine")

    monkeypatch.setenv(kernels.KERNELS_VARIABLE, "numpy")
    _, reference = run(pile())
    monkeypatch.setenv(kernels.KERNELS_VARIABLE, "numba")
    monkeypatch.setattr(contact_impulses, "solve_contacts", broken)
    impulses.build_contact_kernels.cache_clear()
    try:
        with pytest.warns(RuntimeWarning, match=r"compiled contact solver could not be built \(TypingError"):
            _, fallen = run(pile())
    finally:
        impulses.build_contact_kernels.cache_clear()
    np.testing.assert_array_equal(fallen.positions, reference.positions)


@pytest.mark.slow
def test_kernels_are_cached_in_their_folder_even_when_numba_was_imported_first(tmp_path):
    """numba reads NUMBA_CACHE_DIR once, when it is first imported. A program that imports numba before animbatch (a
    notebook) must still find the kernels in animbatch's cache folder: otherwise numba compiles every kernel again
    (a minute and more) into a __pycache__ beside the sources. In a fresh process that imports numba first, with an
    empty cache, a kernel's first call writes its machine code under animbatch's folder."""
    import subprocess
    import sys
    import textwrap

    program = textwrap.dedent(f"""
        import os
        os.environ.pop("NUMBA_CACHE_DIR", None)
        os.environ["XDG_CACHE_HOME"] = {str(tmp_path)!r}
        import numba
        assert not numba.config.CACHE_DIR
        import numpy as np
        from animbatch.sim import kernels
        from animbatch.sim.kernels import rigid_motion
        q = np.array([2.0, 0.0, 0.0, 0.0])
        rigid_motion.normalise(q)
        assert q[0] == 1.0
        print(kernels.kernel_cache_folder())
    """)
    done = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    folder = Path(done.stdout.strip())
    assert folder.is_relative_to(tmp_path)
    assert [path.name for path in folder.rglob("*.nbi") if "normalise" in path.name]
