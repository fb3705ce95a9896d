"""Every integration method, described once: what steps it (a scheme or a scipy solver), its order, its cost per
step, its stability matrix and its kernel for particle pools.

Everything else reads this table: the fixed-step loop and the scipy adapter look up their scheme or solver, the
pre-flight and the step refusal use the stability matrices, the ledger and the cost estimate the orders and costs,
the particle pools the kernels, and the advice which methods are implicit or symplectic. A test checks that the
scene schema's method names are exactly these. Adding an explicit Runge–Kutta method is one entry here made by
:func:`runge_kutta` from its Butcher tableau (scheme, step matrix and particle kernel all follow from it); any other
fixed-step method brings its scheme, its particle kernel and its step matrix.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from animbatch.sim.integrators import particle_kernels as kernels
from animbatch.sim.integrators.fixed_step import (
    EULER,
    MIDPOINT,
    ButcherTableau,
    ExplicitRungeKutta,
    Scheme,
    SymplecticEuler,
    VelocityVerlet,
)
from animbatch.sim.integrators.implicit import BackwardEuler
from animbatch.sim.integrators.particle_kernels import ParticleKernel

if TYPE_CHECKING:
    from scipy.integrate import OdeSolver

#: (h [s], ω [rad/s], decay α [1/s]) -> the matrix of one step on ``x'' = -ω² x - 2 α x'``.
StepMatrix = Callable[[float, float, float], np.ndarray]


def _rate(omega: float, decay: float) -> np.ndarray:
    return np.array([[0.0, 1.0], [-omega**2, -2 * decay]])


def _runge_kutta_matrix(tableau: ButcherTableau) -> StepMatrix:
    """The step matrix of an explicit Runge–Kutta method: with Z = h A, stage ``K_i = Z (I + Σ_j a_ij K_j)`` and
    ``R = I + Σ_i b_i K_i`` (for Euler I + Z; for the midpoint method I + Z + Z²/2)."""

    def matrix(h: float, omega: float, decay: float) -> np.ndarray:
        z = h * _rate(omega, decay)
        stages: list[np.ndarray] = []
        for row in tableau.a:
            stages.append(z @ (np.eye(2) + sum((a_ij * stages[j] for j, a_ij in enumerate(row)), np.zeros((2, 2)))))
        return np.eye(2) + sum((b_i * k for b_i, k in zip(tableau.b, stages)), np.zeros((2, 2)))

    return matrix


def _symplectic_euler_matrix(h: float, omega: float, decay: float) -> np.ndarray:
    kick = np.eye(2) + h * np.array([[0.0, 0.0], _rate(omega, decay)[1]])  # v' = v + h a(x, v)
    return np.array([[1.0, h], [0.0, 1.0]]) @ kick  # x' = x + h v'


def _verlet_matrix(h: float, omega: float, decay: float) -> np.ndarray:
    # Velocity Verlet keeps the rate it evaluated at the predicted motion (x', v + h a) for the next step, so with
    # damping its state is (x, v, a), not (x, v): x' = x + h v + h²/2 a; a' = a(x', v + h a); v' = v + h/2 (a + a').
    position = np.array([1.0, h, 0.5 * h * h])
    predicted = np.array([0.0, 1.0, h])
    new_rate = -omega**2 * position - 2 * decay * predicted
    velocity = np.array([0.0, 1.0, 0.5 * h]) + 0.5 * h * new_rate
    return np.array([position, velocity, new_rate])


def _backward_euler_matrix(h: float, omega: float, decay: float) -> np.ndarray:
    return np.linalg.inv(np.eye(2) - h * _rate(omega, decay))


@dataclass(frozen=True)
class Method:
    """One integration method.

    ``order``: of the error per unit time (fixed-step: a run's drift shrinks as dt to this power; adaptive methods
    with a variable order: a middle value). ``evaluations_per_step``: right-hand sides per step (explicit stages;
    implicit: stages × Newton iterations, roughly), for cost estimates."""

    name: str
    family: Literal["fixed-step", "adaptive"]
    order: int
    evaluations_per_step: int
    summary: str
    scheme: type[Scheme] | None = None  # fixed-step: steps bodies
    solver: str | None = None  # adaptive: the name of the scipy.integrate solver class
    step_matrix: StepMatrix | None = None  # fixed-step: one step on a damped oscillator (stability)
    particle_step: ParticleKernel | None = None  # fixed-step: one step of a pool of independent particles
    symplectic: bool = False
    implicit: bool = False  # implicit (A-stable for the fixed-step ones), or switching to an implicit method
    stability_limit: float | None = None  # explicit adaptive: |h λ| along the negative real axis

    @property
    def fixed_step(self) -> bool:
        return self.family == "fixed-step"

    def solver_class(self) -> type[OdeSolver]:
        """The scipy solver class of an adaptive method (scipy.integrate is imported here, on first use, so that
        reading this table costs validate and --help nothing)."""
        import scipy.integrate

        if self.solver is None:
            raise ValueError(f"{self.name} is a fixed-step method, not a scipy solver")
        return getattr(scipy.integrate, self.solver)


def runge_kutta(name: str, summary: str, tableau: ButcherTableau) -> Method:
    """An explicit Runge–Kutta method, all from its tableau: its scheme, step matrix and particle kernel."""
    return Method(name, "fixed-step", tableau.order, len(tableau.b), summary,
                  scheme=ExplicitRungeKutta.of(name, tableau), step_matrix=_runge_kutta_matrix(tableau),
                  particle_step=kernels.runge_kutta(tableau))


METHODS: dict[str, Method] = {method.name: method for method in (
    Method("RK23", "adaptive", 2, 3, "Bogacki–Shampine 3(2)", solver="RK23", stability_limit=2.5),
    Method("RK45", "adaptive", 4, 6, "Dormand–Prince 5(4)", solver="RK45", stability_limit=3.3),
    Method("DOP853", "adaptive", 7, 12, "Dormand–Prince 8(5,3)", solver="DOP853", stability_limit=6.0),
    Method("Radau", "adaptive", 5, 8, "implicit Runge–Kutta (Radau IIA), order 5", solver="Radau", implicit=True),
    Method("BDF", "adaptive", 3, 3, "backward differentiation, orders 1–5", solver="BDF", implicit=True),
    Method("LSODA", "adaptive", 4, 3, "Adams / BDF, switching on stiffness", solver="LSODA", implicit=True),
    runge_kutta("euler", "explicit Euler", EULER),
    runge_kutta("midpoint", "explicit midpoint (RK2)", MIDPOINT),
    Method("symplectic_euler", "fixed-step", 1, 1, "semi-implicit Euler", scheme=SymplecticEuler,
           step_matrix=_symplectic_euler_matrix, particle_step=kernels.symplectic_euler, symplectic=True),
    Method("verlet", "fixed-step", 2, 1, "velocity Verlet", scheme=VelocityVerlet, step_matrix=_verlet_matrix,
           particle_step=kernels.verlet, symplectic=True),
    Method("backward_euler", "fixed-step", 1, 2, "linearised backward Euler", scheme=BackwardEuler,
           step_matrix=_backward_euler_matrix, particle_step=kernels.backward_euler, implicit=True),
)}

#: Fixed-step method name -> scheme class; adaptive method name -> scipy solver class.
FIXED_STEP_SCHEMES: dict[str, type[Scheme]] = {name: m.scheme for name, m in METHODS.items() if m.scheme is not None}
SCIPY_METHODS: tuple[str, ...] = tuple(name for name, m in METHODS.items() if m.solver is not None)

#: Stability limit ``|h λ|`` along the negative real axis of each explicit Runge–Kutta pair.
EXPLICIT_LIMITS = {name: m.stability_limit for name, m in METHODS.items() if m.stability_limit is not None}
