"""What a simulation will cost, before it starts: wall time and memory, term by term.

The pre-flight (:func:`check_cost`) refuses a run whose estimate exceeds its budget (``solver.max_cost``, or
``--max-cost``) or the memory this machine has, naming the term that makes it expensive, instead of running for
hours or being killed half-way. The estimate is an order of magnitude, not a promise:

* **time per right-hand side** is measured, not guessed: the scene's own equations are evaluated a few times here;
* **steps**: exact for fixed-step methods (steps per frame × frames); for adaptive ones, the larger of what stability
  forces on an explicit method (``ω T / |hλ|max`` for the stiffest spring) and what accuracy asks of the tightest
  orbit at the start (``ω T / rtol^(1/(p+1))``, for a method of order p), and at least one step per frame;
  ``solver.max_step`` adds ``T / max_step``;
* **implicit methods** add Jacobians (analytic and sparse where the scene has them, else one right-hand side per
  state variable) and LU factorisations (dense: n³/3 flops);
* **emitted particles**: births (rate × time + bursts, within the pool's capacity) × steps, at a documented cost per
  particle-step (``PARTICLE_STEP_SECONDS``, measured on the fountain scene).

What cannot be foreseen from the first state (two bodies plunging into each other, a pile that jams) is caught while
the run goes, by the same budget (:mod:`animbatch.sim.integrators.budget`).
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from animbatch.errors import OverBudget, SimulationError
from animbatch.sim.forces.gravitation import InverseSquarePairs
from animbatch.sim.integrators.budget import format_seconds
from animbatch.sim.integrators.interface import EquationsOfMotion, StepSettings
from animbatch.sim.integrators.methods import EXPLICIT_LIMITS, METHODS
from animbatch.sim.integrators.stability import stiffest_mode, time_scales
from animbatch.sim.integrators.step_plan import resolve_dt, substeps
from animbatch.sim.model import Dynamics, Model

#: Cost of advancing one emitted particle by one step [s], births and records included: the fountain (gravity, drag,
#: box colliders) measured 0.35-0.7 µs per particle-step on a 2-core machine; the bare stepping benchmark ~40 ns.
PARTICLE_STEP_SECONDS = 500e-9
#: The same where the compiled kernel steps the pool (animbatch.sim.kernels.particle_pool): the fountain at 1e5 live
#: drops measured 37 ns per particle-step, births included, on the same machine.
COMPILED_PARTICLE_STEP_SECONDS = 50e-9
#: Bytes kept per emitted particle and frame (position float32 ×3, serial int64, age float32) and per pool slot.
PARTICLE_FRAME_BYTES = 24
PARTICLE_SLOT_BYTES = 160
#: Floating-point operations per second of a dense LU factorisation (LAPACK on one core, conservatively).
DENSE_FLOPS = 5e9
#: Steps between Jacobians (and between factorisations) of implicit adaptive methods, roughly.
STEPS_PER_JACOBIAN = 10
STEPS_PER_LU = 3
#: Part of the available memory a run may plan to use.
MEMORY_SHARE = 0.8


@dataclass(frozen=True)
class CostTerm:
    """One part of a run's cost: ``seconds`` of wall time [s] or ``bytes`` of memory, and what it comes from."""
    name: str
    seconds: float = 0.0
    bytes: float = 0.0
    detail: str = ""


@dataclass(frozen=True)
class CostEstimate:
    """The cost of a run, by term."""
    terms: list[CostTerm] = field(default_factory=list)

    @property
    def seconds(self) -> float:
        return sum(term.seconds for term in self.terms)

    @property
    def bytes(self) -> float:
        return sum(term.bytes for term in self.terms)

    def seconds_of(self, name: str) -> float:
        """The seconds of the term called ``name`` (0 without one)."""
        return sum(term.seconds for term in self.terms if term.name == name)

    def dearest(self, kind: str) -> CostTerm:
        """The term that costs most ``seconds`` or ``bytes``."""
        return max(self.terms, key=lambda term: getattr(term, kind))


def estimate_cost(model: Model, solver: StepSettings, particle_pools: Sequence[tuple[Any, ...]] = (),
                  particle_steps: int = 0, rhs_seconds: float | None = None,
                  contact_seconds: float = 0.0) -> CostEstimate:
    """The estimated cost of integrating ``model`` with ``solver`` settings, and of the emitted particles
    ``particle_pools``: (emitter name, pool capacity, particles born over the run[, seconds per particle-step, default
    PARTICLE_STEP_SECONDS]), each advanced ``particle_steps`` times. ``rhs_seconds``: time of one right-hand side [s]
    (measured here when not given); ``contact_seconds``: time of one step's contacts [s]: the search, which the
    contacts' package measures (:func:`animbatch.sim.contact.time_stepping.measure_contact_search`), and for numpy's
    path the solve of the contacts it found (:func:`animbatch.sim.contact.time_stepping.numpy_contact_solve`)."""
    times = np.asarray(model.frame_times)
    frames = len(times)
    states = int(np.size(model.y0))
    method = solver.method
    terms = [CostTerm("trajectory", bytes=frames * states * 8 * 3.0,
                      detail=f"{frames} frames × {states} state variables")]
    steps, why = _steps(model, solver, times)
    if states and steps:
        rhs = rhs_seconds if rhs_seconds is not None else measure_rhs(model)
        per_step = METHODS[method].evaluations_per_step if method in METHODS else 4
        evaluations = steps * per_step
        terms.append(CostTerm("integration", seconds=evaluations * rhs,
                              detail=f"{method}: about {steps:.3g} steps ({why}) × {per_step} "
                                     f"right-hand sides of {1e6 * rhs:.3g} µs ({states} state variables)"))
        terms += _implicit_terms(model, method, steps, states, rhs)
        if contact_seconds:
            terms.append(CostTerm("contacts", seconds=steps * contact_seconds,
                                  detail=f"about {steps:.3g} contact steps of {1e3 * contact_seconds:.3g} ms (at "
                                         "the start; a pile that has formed costs more)"))
    for name, capacity, births, *cost in particle_pools:
        alive = min(births, capacity)
        particle_step = float(cost[0]) if cost else PARTICLE_STEP_SECONDS
        terms.append(CostTerm(f"emitter {name!r}", seconds=alive * particle_steps * particle_step,
                              bytes=capacity * (PARTICLE_SLOT_BYTES + PARTICLE_FRAME_BYTES * frames),
                              detail=f"up to {capacity:,} particles alive ({births:,.0f} born) × {particle_steps:,} "
                                     f"steps at {1e9 * particle_step:.3g} ns each, kept at {frames} frames"))
    return CostEstimate(terms)


def _steps(model: Model, solver: StepSettings, times: np.ndarray) -> tuple[float, str]:
    """Steps the method will take over ``times``, and the reason in words."""
    frames = len(times)
    if frames < 2:
        return 0.0, "a single frame"
    duration = float(times[-1] - times[0])
    interval = duration / (frames - 1)
    method = solver.method
    if method not in METHODS or METHODS[method].fixed_step:
        per_frame = substeps(interval, resolve_dt(solver.dt, method, interval))
        return float(per_frame * (frames - 1)), f"{per_frame} per frame × {frames - 1} frames"
    candidates = [(float(frames - 1), "one per frame at least")]
    if solver.max_step:
        candidates.append((duration / solver.max_step, f"max_step {solver.max_step:g} s"))
    for omega, what, followed in _fastest_motions(model):
        if method in EXPLICIT_LIMITS:
            candidates.append((omega * duration / EXPLICIT_LIMITS[method],
                               f"stability of the {what}, {'ω' if followed else 'rate'} = {omega:.3g} "
                               f"{'rad/s' if followed else '1/s'}"))
        if not followed:
            continue  # a stiff spring rarely vibrates visibly, drag only decays: they cost stability, not accuracy
        per_radian = solver.rtol ** (-1.0 / (METHODS[method].order + 1))
        candidates.append((omega * duration * per_radian,
                           f"accuracy on the {what}, ω = {omega:.3g} rad/s at rtol {solver.rtol:g}"))
    return max(candidates)


def _fastest_motions(model: Model) -> list[tuple[float, str, bool]]:
    """(rate [rad/s or 1/s], description, whether a method must follow it for accuracy too) of the stiffest spring,
    of the tightest gravitating or charged pair at the start, of the fastest spin, and of each force term's own
    time scale (a gyration in a magnetic field, the relaxation of drag)."""
    found = []
    mode = stiffest_mode(model)
    if mode is not None and mode.omega > 0:
        found.append((float(mode.omega), f"stiffest spring (around {mode.body!r})", False))

    positions = np.asarray(model.positions(model.y0[None])[0])
    found += [(scale.rate, scale.what, scale.turns) for scale in time_scales(model)]
    for term in model.force_terms:
        if not isinstance(term, InverseSquarePairs) or len(term.mass) < 2:
            continue
        index = np.arange(len(positions)) if term.index is None else term.index
        points = positions[index][:2000]  # the first 2000 suffice
        r2 = np.sum((points[:, None, :] - points[None, :, :]) ** 2, axis=-1) + term.softening ** 2
        np.fill_diagonal(r2, np.inf)
        first = np.arange(len(points))
        with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
            omega2 = term.pair_frequency(r2, first[:, None], first[None, :])
        omega2 = np.nan_to_num(omega2, nan=0.0, posinf=1e300)
        i, j = np.unravel_index(int(np.argmax(omega2)), omega2.shape)
        names = model.bodies.names
        found.append((float(np.sqrt(omega2[i, j])),
                      f"tightest {'gravitating' if term.kind == 'gravitation' else 'charged'} pair "
                      f"({names[index[i]]!r} and {names[index[j]]!r})", True))
    if model.rigid_count:
        # a body spinning at ω turns its orientation's quaternion at ω/2: each component a sinusoid the method must
        # follow (a spinning top at 400 rad/s takes some 1600 DOP853 steps over 2.5 s at rtol 1e-8)
        spin = np.linalg.norm(np.asarray(model.angular_velocities(model.y0[None])[0])[model.particle_count:], axis=1)
        if spin.size and spin.max() > 0:
            fastest = int(np.argmax(spin))
            found.append((float(spin[fastest]) / 2, f"spin of {model.bodies.names[model.particle_count + fastest]!r}"
                                                    f" ({spin[fastest]:.3g} rad/s: its quaternion turns at half that)",
                          True))
    return found


def _implicit_terms(model: Model, method: str, steps: float, states: int, rhs: float) -> list[CostTerm]:
    if method not in ("Radau", "BDF", "LSODA"):
        return []
    analytic = method in ("Radau", "BDF") and getattr(model, "has_jacobian", False)
    jacobians = steps / STEPS_PER_JACOBIAN
    factorisations = steps / STEPS_PER_LU
    terms = []
    if not analytic:
        terms.append(CostTerm("Jacobians", seconds=jacobians * states * rhs,
                              detail=f"about {jacobians:.3g} finite-difference Jacobians of {states} right-hand "
                                     "sides each"))
        dense = states ** 3 / 3 / DENSE_FLOPS
        terms.append(CostTerm("factorisations", seconds=factorisations * dense, bytes=16.0 * states ** 2,
                              detail=f"about {factorisations:.3g} dense LU factorisations of {states}×{states}"))
    return terms


def measure_rhs(model: Model, system: EquationsOfMotion | None = None, repeats: int = 3) -> float:
    """Wall time of one evaluation of the right-hand side [s] of ``system`` (default: the model's numpy Dynamics),
    the fastest of a few."""
    dynamics = system if system is not None else Dynamics(model)
    y = np.array(model.y0, dtype=np.float64)
    t = float(model.frame_times[0])
    best = np.inf
    with np.errstate(all="ignore"):
        for _ in range(repeats + 1):  # the first call warms caches (and loads compiled code) and is not counted
            start = time.perf_counter()
            dynamics.rhs(t, y)
            best = min(best, time.perf_counter() - start)
    return float(best)


def available_memory() -> float:
    """Bytes of memory available to a new allocation (MemAvailable on Linux, else physical memory)."""
    try:
        with open("/proc/meminfo") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except OSError:
        pass
    try:

        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return float("inf")


def check_cost(estimate: CostEstimate, max_cost: float | None, memory: float | None = None) -> None:
    """Refuse (SimulationError, exit code 3) a run estimated to take more than ``max_cost`` [s] (None or 0: no
    limit) or more than MEMORY_SHARE of ``memory`` [bytes] (default: what is available now)."""
    memory = available_memory() if memory is None else memory
    if estimate.bytes > MEMORY_SHARE * memory:
        term = estimate.dearest("bytes")
        raise SimulationError(
            f"refused before it starts: the run would need about {estimate.bytes / 2**30:.3g} GiB of memory, more "
            f"than this machine has available ({memory / 2**30:.3g} GiB); most of it for the {term.name} "
            f"({term.bytes / 2**30:.3g} GiB: {term.detail}). Shorten the scene, lower fps, or lower the particle "
            "rate or the emitter's capacity")
    if max_cost and estimate.seconds > max_cost:
        term = estimate.dearest("seconds")
        raise OverBudget(
            f"refused before it starts: the run would take about {format_seconds(estimate.seconds)}, more than its "
            f"budget of {format_seconds(max_cost)} (solver.max_cost); most of it in the {term.name}: {term.detail}. "
            f"{_fix(term)}Or raise the budget with --max-cost {_suggest(estimate.seconds)} or solver.max_cost "
            "(0 = no limit)", estimate=estimate.seconds)


def _fix(term: CostTerm) -> str:
    if "stability of the stiffest spring" in term.detail:
        return ("An implicit method (Radau or BDF with the analytic Jacobian, or backward_euler) is not limited by "
                "stiff springs. ")
    if "finite-difference" in term.detail or "dense LU" in term.detail:
        return "Radau or BDF with the analytic Jacobian (particles and cloth), or backward_euler, cost far less. "
    if "per frame" in term.detail:
        return "A larger solver.dt (or an implicit method for stiff springs) takes fewer steps. "
    if "accuracy" in term.detail:
        higher = "" if "DOP853" in term.detail else " or a higher-order method (DOP853)"
        return f"A looser solver.rtol{higher} takes fewer steps. "
    if term.name.startswith("emitter"):
        return "A lower rate, shorter lifetimes or a larger solver.dt cost less. "
    return ""


def _suggest(seconds: float) -> str:
    """A budget comfortably above ``seconds``, as the command line takes it (``90``, ``30min``, ``5h``)."""
    padded = 2 * seconds
    if padded < 120:
        return f"{int(np.ceil(padded))}"
    if padded < 7200:
        return f"{int(np.ceil(padded / 60))}min"
    return f"{int(np.ceil(padded / 3600))}h"
