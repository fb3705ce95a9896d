"""Observed order of convergence of each fixed-step method, and tolerance-driven accuracy of adaptive ones."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch.sim.integrators import FIXED_STEP_SCHEMES
from support.scenarios import oscillator_exact, oscillator_scene
from support.scenes import ADAPTIVE, body, run

EXPECTED_ORDER = {"euler": 1, "midpoint": 2, "symplectic_euler": 1, "verlet": 2, "backward_euler": 1}


def final_error(method: str, dt: float) -> float:
    """Largest position error over all frames on the damped oscillator (a velocity-dependent force)."""
    _, trajectory = run(oscillator_scene(0.2, method=method, dt=dt, duration=2.0, fps=10))
    x, _ = body(trajectory, "mass")
    exact = oscillator_exact(trajectory.times, 0.2, 5.0, 0.2)
    return float(np.abs(x[:, 0] - 1.0 - exact).max())


def test_every_fixed_step_method_has_an_expected_order():
    """The table of expected orders covers exactly the registered methods."""
    assert set(EXPECTED_ORDER) == set(FIXED_STEP_SCHEMES)


@pytest.mark.slow
@pytest.mark.parametrize("method", sorted(EXPECTED_ORDER))
def test_fixed_step_methods_converge_at_their_order(method):
    """Halving dt divides the error by 2^order (order 1: Euler variants; order 2: midpoint, Verlet) — with damping,
    so a Verlet that ignored the velocity dependence of the force would show order 1 here."""
    steps = [0.1 / 2**k for k in range(4, 8)]  # all divide the frame interval 1/10 s
    errors = [final_error(method, dt) for dt in steps]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    expected = EXPECTED_ORDER[method]
    assert np.all(np.abs(orders - expected) < 0.15), f"observed orders {orders} for {method}"


@pytest.mark.slow
@pytest.mark.parametrize("method", ADAPTIVE)
def test_adaptive_methods_get_more_accurate_with_tighter_tolerance(method):
    """Tightening rtol/atol by 10⁴ reduces the error at least 30-fold, and the tight run is accurate to 1e-6."""
    errors = []
    for tolerance in (1e-4, 1e-8):
        _, trajectory = run(oscillator_scene(0.2, duration=2.0, fps=10), f"solver.method={method}",
                            f"solver.rtol={tolerance}", f"solver.atol={tolerance * 1e-2}")
        x, _ = body(trajectory, "mass")
        errors.append(np.abs(x[:, 0] - 1.0 - oscillator_exact(trajectory.times, 0.2, 5.0, 0.2)).max())
    assert errors[1] < errors[0] / 30
    assert errors[1] < 1e-6
