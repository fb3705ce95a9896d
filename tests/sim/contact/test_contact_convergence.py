"""Whether a contact impulse solve met every target, and how far off it left them: each solve says (numpy and
compiled alike), and a run's ledger counts the solves that ran out of iterations."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import api
from animbatch.sim import kernels
from animbatch.sim.contact.impulses import VELOCITY_TOLERANCE, BodyVelocities, solve_impulses
from animbatch.sim.ledger import summary
from support.scenes import box_inverse_inertia, corners_on_floor, scene

MASS, SIZE = 2.0, (0.4, 0.2, 0.3)


def _landing_box() -> tuple[BodyVelocities, np.ndarray, np.ndarray]:
    """A box arriving on its four bottom corners at 1 m/s, spinning and sliding (no friction, no bounce): its
    velocities, centres (the fixed body last) and centre."""
    centre = np.array([0.3, 0.1, -0.2])
    inverse_inertia = np.zeros((2, 3, 3))
    inverse_inertia[0] = box_inverse_inertia(MASS, SIZE)
    bodies = BodyVelocities(np.array([[0.2, -1.0, 0.1], [0.0, 0.0, 0.0]]), np.array([[0.7, 0.3, -0.5], [0, 0, 0]]),
                            np.array([1 / MASS, 0.0]), inverse_inertia)
    return bodies, np.array([centre, np.zeros(3)]), centre


@pytest.mark.parametrize("compiled", [False, True], ids=["numpy", "compiled"])
@pytest.mark.parametrize("iterations", [1, 300])
def test_a_solve_reports_the_violation_its_sweeps_left(compiled, iterations, monkeypatch):
    """One sweep cannot land a spinning box on four corners; three hundred can. What the solve reports is what
    the corners' velocities show afterwards: each corner's normal speed v_n = (v + ω × r)·up must be 0 where it
    pushes (λ > 0) and may only be ≥ 0 where it does not."""
    if compiled:
        pytest.importorskip("numba")
    monkeypatch.setenv(kernels.KERNELS_VARIABLE, "numba" if compiled else "numpy")
    bodies, x, centre = _landing_box()
    contacts = corners_on_floor(0, centre, SIZE, mu=0.0)
    falling = bodies.v[0, 1]
    result = solve_impulses(contacts, bodies, x, 1e-3, iterations=iterations, rest_speed=0.01, slop=1e-4,
                            long_run=compiled)
    speed = (bodies.v[0] + np.cross(bodies.omega[0], contacts.point - centre)) @ np.array([0.0, 1.0, 0.0])
    violation = np.where(result.normal_impulse > 0, np.abs(speed), np.maximum(-speed, 0.0))
    tolerance = VELOCITY_TOLERANCE * (1 + 1.0 + 0.5 * 0.3)  # relative to the fastest corner's approach (≤ 1.15 m/s)
    if iterations == 1:
        assert result.unconverged and result.residual > 1e-4
        assert result.residual == pytest.approx(violation.max(), rel=1e-9)
    else:
        assert not result.unconverged and result.residual <= tolerance
        assert violation.max() <= 10 * tolerance
    # whatever the sweeps reached, the vertical momentum changed by the normal impulses the solve reports (no
    # friction, the floor fixed): the reported impulses are the ones applied
    assert result.normal_impulse.sum() == pytest.approx(MASS * (bodies.v[0, 1] - falling), rel=1e-9)


BOXES = """\
duration: 0.3
fps: 10
solver: {{method: symplectic_euler, dt: 0.001}}
contacts: {{iterations: {iterations}}}
bodies:
{bodies}
colliders: [{{type: plane}}]
fields: [{{type: gravity}}]
"""


def _boxes(count: int, iterations: int) -> str:
    bodies = "\n".join(f"  - {{name: box{i}, type: rigid, shape: {{type: box, size: [0.2, 0.2, 0.2]}}, density: 500, "
                       f"position: [0, {0.1 + 0.2 * i}, 0]}}" for i in range(count))
    return BOXES.format(iterations=iterations, bodies=bodies)


@pytest.mark.slow
def test_the_ledger_counts_the_contact_solves_that_ran_out_of_iterations():
    """A box resting on the floor: at most one solve a step, every one converged, and the summary line says nothing
    of them. A stack of three boxes held to two sweeps a step: the ledger counts the solves that were not enough, and
    the summary line says so with the violation they left."""
    resting = api.simulate(scene(_boxes(1, 300)))
    solves = resting.ledger["work"]["bodies"]["contact_solves"]
    assert 0 < solves["solves"] <= resting.solver_stats["steps"]
    assert solves["unconverged"] == 0 and solves["residual"] == 0.0 and solves["iterations"] == 300
    assert "contacts:" not in summary(resting.ledger)

    stack = api.simulate(scene(_boxes(3, 2)))
    solves = stack.ledger["work"]["bodies"]["contact_solves"]
    assert 0 < solves["unconverged"] <= solves["solves"] <= stack.solver_stats["steps"]
    assert solves["residual"] > 0 and solves["iterations"] == 2
    assert (f"contacts: {solves['unconverged']} of {solves['solves']} solves stopped short (stalled, or at all 2 "
            "iterations), leaving") \
        in summary(stack.ledger)


def test_sweeps_stop_when_their_violation_stops_falling_and_only_then():
    """The stall rule: a violation halving every sweep never stalls; one stuck at a level stalls at the end of the
    second window; one falling 2 % a window (too slowly to be worth the sweeps) stalls; one falling 20 % a window
    goes on."""
    from animbatch.sim.kernels.stall import STALL_WINDOW, stalled

    def first_stall(violations) -> int | None:
        watch = [np.inf, np.inf]
        for iteration, worst in enumerate(violations, start=1):
            if stalled(iteration, worst, watch):
                return iteration
        return None

    sweeps = np.arange(1, 10 * STALL_WINDOW + 1)
    assert first_stall(0.5 ** sweeps) is None
    assert first_stall(np.full(len(sweeps), 3e-3)) == 2 * STALL_WINDOW
    assert first_stall(0.98 ** (sweeps / STALL_WINDOW)) == 2 * STALL_WINDOW
    assert first_stall(0.8 ** (sweeps / STALL_WINDOW)) is None
    # a violation that wanders (Jacobi sweeps over contacts sharing bodies) is judged by its smallest in a window
    wandering = 3e-3 * (1 + 0.5 * np.sin(sweeps)) * 0.7 ** (sweeps / STALL_WINDOW)
    assert first_stall(wandering) is None


def test_the_compiled_sweeps_stall_by_the_numpy_rule():
    """The compiled sweeps' stall test is the numpy sweeps' function compiled, and decides alike on the same
    violations (a level stalls at the end of the second window, a halving never does)."""
    pytest.importorskip("numba")
    from animbatch.sim.contact import impulses
    from animbatch.sim.kernels import contact_impulses
    from animbatch.sim.kernels.stall import STALL_WINDOW

    assert contact_impulses._stalled.py_func is impulses.stalled
    for violations in (np.full(5 * STALL_WINDOW, 3e-3), 0.5 ** np.arange(1, 5 * STALL_WINDOW + 1)):
        numpy_watch, compiled_watch = [np.inf, np.inf], np.full(2, np.inf)
        for iteration, worst in enumerate(violations, start=1):
            assert contact_impulses._stalled(iteration, worst, compiled_watch) == impulses.stalled(iteration, worst,
                                                                                                  numpy_watch)
