"""Exact motion of the bodies of a scene that has one: the reference of ``study.closed_form: true``, and the motion
itself for ``solver.method: analytic`` (the lecture notes' kinematic simulation).

Each body is matched to the one closed form its forces allow, from the compiled force terms (not from its name):

* **projectile**: uniform gravity only, ``x = x₀ + v₀ t + g t²/2``;
* **linear drag** (and gravity, optionally wind ``w``): with ``u = v - w``, ``τ = m / c`` and ``u_T = g τ``,
  ``u = u_T + (u₀ - u_T) e^{-t/τ}`` and ``x = x₀ + (w + u_T) t + (u₀ - u_T) τ (1 - e^{-t/τ})``;
* **oscillator**: one spring (stiffness k, damping d, rest length r) to a fixed anchor, starting on the spring's
  line with its velocity and gravity along it: the displacement from equilibrium ``s_eq = r + m g·n / k`` obeys
  ``m u'' + d u' + k u = 0``, solved by the matrix exponential;
* **Kepler**: two bodies attracting only each other by gravitation (same uniform gravity on both allowed): the centre
  of mass is a projectile and the separation an ellipse, stepped by Kepler's equation in difference form (the f and g
  functions, valid for circular orbits too).

A scene that asks for closed forms but has a body outside these cases gets an error naming the body and the reason.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import numpy as np
from scipy.linalg import expm

from animbatch.sim.forces import Drag, Gravitation, SpringForces, UniformGravity
from animbatch.sim.integrators.description import describe_method
from animbatch.sim.integrators.interface import (
    EquationsOfMotion,
    FrameCallback,
    IntegrationResult,
    Integrator,
    SolverStats,
)

if TYPE_CHECKING:  # the model imports nothing from here; the hint only
    from animbatch.sim.model.model import Model


@dataclass(frozen=True)
class ExactMotion:
    """Positions and velocities of every body at the frame times, (F, P, 3) each, and the form used per body."""

    positions: np.ndarray
    velocities: np.ndarray
    forms: dict[str, str]


def _acts_on(term: object, point: int) -> bool:
    index = getattr(term, "index", None)
    return index is None or point in np.asarray(index)


class NoClosedForm(ValueError):
    """A body of a scene that asks for closed forms has none (the message names it and says why)."""


def _refuse(body: str, why: str) -> NoClosedForm:
    return NoClosedForm(f"body {body!r} has no closed form: {why}")


def exact_motion(model: Model) -> ExactMotion:
    """The closed-form motion of every body of ``model`` at its frame times (raises NoClosedForm when a body has
    none)."""
    bodies = model.bodies
    names = bodies.names
    if bodies.rigid_count:
        raise _refuse(names[bodies.first_rigid], "closed forms here are for particles (rigid bodies also turn)")
    if model.contact_world is not None:
        raise _refuse(names[0], "the scene has collisions")
    times = model.frame_times
    count = bodies.count
    x0 = model.positions(model.y0[None])[0]
    v0 = model.velocities(model.y0[None])[0]
    positions = np.empty((len(times), count, 3))
    velocities = np.empty_like(positions)
    forms: dict[str, str] = {}
    done: set[int] = set()
    for point in range(count):
        if point in done:
            continue
        acting = [term for term in model.force_terms if _acts_on(term, point)]
        springs = [term for term in acting if isinstance(term, SpringForces)]
        spring_rows = np.flatnonzero((springs[0].springs.first == point)
                                     | (~springs[0].springs.second_is_anchor & (springs[0].springs.second == point))
                                     ) if springs else np.zeros(0, int)
        gravity = sum((term.g for term in acting if isinstance(term, UniformGravity)), np.zeros(3))
        others = [term for term in acting if not isinstance(term, UniformGravity | Drag | Gravitation | SpringForces)]
        if others:
            raise _refuse(names[point], f"it feels {others[0].label}")
        drags = [term for term in acting if isinstance(term, Drag)]
        attraction = [term for term in acting if isinstance(term, Gravitation)]
        name = names[point]
        if attraction:
            if drags or len(spring_rows):
                raise _refuse(name, "gravitation together with drag or springs")
            x, v, partner = _kepler(model, attraction[0], point, gravity, times, x0, v0)
            positions[:, [point, partner]], velocities[:, [point, partner]] = x, v
            forms[name] = forms[names[partner]] = "kepler"
            done.add(partner)
        elif len(spring_rows):
            positions[:, point], velocities[:, point] = _oscillator(model, springs[0], spring_rows, point, gravity,
                                                                    drags, times, x0[point], v0[point])
            forms[name] = "oscillator"
        elif drags:
            positions[:, point], velocities[:, point] = _linear_drag(name, drags, bodies.mass[point], gravity, times,
                                                                     x0[point], v0[point])
            forms[name] = "linear drag"
        else:
            positions[:, point] = x0[point] + v0[point] * times[:, None] + 0.5 * gravity * times[:, None] ** 2
            velocities[:, point] = v0[point] + gravity * times[:, None]
            forms[name] = "projectile"
    return ExactMotion(positions, velocities, forms)


def _linear_drag(name: str, drags: list[Drag], mass: float, gravity: np.ndarray, times: np.ndarray,
                 x0: np.ndarray, v0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    if len(drags) > 1 or drags[0].law != "linear" or drags[0].at_points is not None:
        raise _refuse(name, f"it feels {drags[0].law} drag (only one linear drag at the centre has a closed form)")
    drag = drags[0]
    wind = drag.wind if drag.wind is not None else np.zeros(3)
    tau = mass / float(drag.coefficient)
    terminal = gravity * tau
    start = v0 - wind
    decay = np.exp(-times / tau)[:, None]
    velocity = wind + terminal + (start - terminal) * decay
    position = x0 + (wind + terminal) * times[:, None] + (start - terminal) * tau * (1 - decay)
    return position, velocity


def _oscillator(model: Model, springs: SpringForces, rows: np.ndarray, point: int, gravity: np.ndarray,
                drags: list[Drag], times: np.ndarray, x0: np.ndarray, v0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    name = model.bodies.names[point]
    table = springs.springs
    if drags or len(rows) != 1 or not table.second_is_anchor[rows[0]] or table.first[rows[0]] != point:
        raise _refuse(name, "an oscillator needs exactly one spring, from the body to an anchor, and no drag")
    row = int(rows[0])
    anchor = int(table.second[row])
    if anchor in model.anchors.paths:
        raise _refuse(name, "its spring's anchor moves")
    anchor_at = model.anchor_position[anchor]
    if np.any(table.first_offset[row]) or np.any(table.second_offset[row]):
        raise _refuse(name, "its spring is attached off the centre")
    offset = x0 - anchor_at
    length = float(np.linalg.norm(offset))
    axis = offset / length
    for what, vector in (("velocity", v0), ("gravity", gravity)):
        if np.linalg.norm(vector - (vector @ axis) * axis) > 1e-12 * max(1.0, float(np.linalg.norm(vector))):
            raise _refuse(name, f"its {what} is not along its spring, so it swings (a pendulum has no closed form)")
    mass = float(model.bodies.mass[point])
    k, d, rest = float(table.stiffness[row]), float(table.damping[row]), float(table.rest_length[row])
    equilibrium = rest + mass * float(gravity @ axis) / k
    rate = np.array([[0.0, 1.0], [-k / mass, -d / mass]])
    start = np.array([length - equilibrium, float(v0 @ axis)])
    motion = np.array([expm(rate * t) @ start for t in times])
    along = equilibrium + motion[:, 0]
    if np.any(along <= 0):
        raise _refuse(name, "it passes through its anchor, where the spring's direction flips")
    return anchor_at + along[:, None] * axis, motion[:, 1:2] * axis


def _kepler(model: Model, term: Gravitation, point: int, gravity: np.ndarray, times: np.ndarray, x0: np.ndarray,
            v0: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    names = model.bodies.names
    members = np.arange(model.bodies.count) if term.index is None else np.asarray(term.index)
    if len(members) != 2 or term.softening > 0:
        raise _refuse(names[point], "gravitation has a closed form between exactly two bodies without softening")
    first, second = (int(m) for m in members)
    partner = second if point == first else first
    partner_gravity = sum((t.g for t in model.force_terms
                           if isinstance(t, UniformGravity) and _acts_on(t, partner)), np.zeros(3))
    if not np.allclose(partner_gravity, gravity):
        raise _refuse(names[point], "the two bodies of the pair feel different uniform gravity")
    m1, m2 = (float(model.bodies.mass[i]) for i in (first, second))
    total = m1 + m2
    mu = term.G * total
    centre = (m1 * x0[first] + m2 * x0[second]) / total
    drift = (m1 * v0[first] + m2 * v0[second]) / total
    separation, closing = _two_body(x0[second] - x0[first], v0[second] - v0[first], mu, times,
                                    names[first], names[second])
    t = times[:, None]
    com = centre + drift * t + 0.5 * gravity * t**2
    com_velocity = drift + gravity * t
    x = np.stack([com - m2 / total * separation, com + m1 / total * separation], axis=1)
    v = np.stack([com_velocity - m2 / total * closing, com_velocity + m1 / total * closing], axis=1)
    order = [0, 1] if point == first else [1, 0]
    return x[:, order], v[:, order], partner


def _two_body(r0: np.ndarray, v0: np.ndarray, mu: float, times: np.ndarray, a_name: str, b_name: str
              ) -> tuple[np.ndarray, np.ndarray]:
    """Separation and its rate (F, 3) of a bound Kepler orbit, by the f and g functions of the eccentric-anomaly
    change ΔE, which solves ``n t = ΔE - (1 - r₀/a) sin ΔE + σ₀/√a (1 - cos ΔE)`` (Newton's method)."""
    distance = float(np.linalg.norm(r0))
    inverse_a = 2 / distance - float(v0 @ v0) / mu
    if inverse_a <= 0:
        raise _refuse(a_name, f"its orbit with {b_name!r} is unbound (parabolic or hyperbolic); only ellipses are "
                              "implemented")
    a = 1 / inverse_a
    n = np.sqrt(mu / a**3)
    sigma = float(r0 @ v0) / np.sqrt(mu)
    anomaly = n * times
    for _ in range(60):
        residual = anomaly - (1 - distance / a) * np.sin(anomaly) + sigma / np.sqrt(a) * (1 - np.cos(anomaly)) \
            - n * times
        slope = 1 - (1 - distance / a) * np.cos(anomaly) + sigma / np.sqrt(a) * np.sin(anomaly)
        anomaly = anomaly - residual / slope
    r = a + (distance - a) * np.cos(anomaly) + sigma * np.sqrt(a) * np.sin(anomaly)
    f = 1 - a / distance * (1 - np.cos(anomaly))
    g = times - (anomaly - np.sin(anomaly)) / n
    f_rate = -np.sqrt(mu * a) * np.sin(anomaly) / (r * distance)
    g_rate = 1 - a / r * (1 - np.cos(anomaly))
    return f[:, None] * r0 + g[:, None] * v0, f_rate[:, None] * r0 + g_rate[:, None] * v0


class ClosedFormIntegrator(Integrator):
    """``solver.method: analytic``: the bodies move by their closed forms (the notes' kinematic simulation), with
    no integration at all; a model with a body outside them is refused (:class:`NoClosedForm`, naming it)."""

    method = "analytic"

    def integrate(self, system: EquationsOfMotion, y0: np.ndarray, times: np.ndarray, *,
                  on_frame: FrameCallback | None = None) -> IntegrationResult:
        started = time.perf_counter()
        model = cast("Model", getattr(system, "model"))  # a Dynamics: the closed forms read its model
        exact = exact_motion(model)
        states = model.states_from(exact.positions, exact.velocities)
        if on_frame is not None:
            on_frame(len(times) - 1, float(times[-1]))
        return IntegrationResult(states, SolverStats(self.method, wall_time=time.perf_counter() - started))

    def describe(self) -> str:
        return describe_method("analytic", adaptive=False)


def check_closed_form(model: Model) -> None:
    """Raise NoClosedForm, naming the body or the item, unless every body of ``model`` has a closed form and the
    model has nothing that needs integrating (clocks)."""
    if getattr(model, "clocks", None) is not None:
        raise NoClosedForm("the scene's clocks integrate proper time, which needs an integrating method")
    exact_motion(model)
