"""The accuracy ledger of a run: what the integration did, what it cost, and how well it kept what physics keeps.

Every simulation (``simulate``, ``render``, ``bake``) gets one, computed from the states at the frame times only (so
it costs a small fraction of the run):

* **work**: the method, the step it used (fixed-step methods use the largest step ≤ ``solver.dt`` that divides the
  frame interval; adaptive ones report their smallest and largest accepted steps), steps and right-hand-side
  evaluations of the bodies and of the emitted particles;
* **conservation**: for energy, linear momentum and angular momentum, whether this scene conserves it and why (or
  why not), and where it does, its *drift*: the largest change from the first frame over the run, relative to the
  quantity's scale in this scene (:func:`conservation_laws`, :func:`drifts`);
* **contacts**: in scenes with collisions, the deepest overlap that no logged impact explains (a collision the
  integration missed), and the deepest one the scene starts with (:mod:`animbatch.sim.contact.audit`);
* **warnings**: a drift above ``solver.drift_warning`` (default :data:`DEFAULT_DRIFT_WARNING`) in a quantity the scene
  conserves, a missed collision, or bodies placed inside each other, each naming the quantity or bodies, the
  numbers and what to change.

The per-frame series behind the drifts (:class:`QuantitySeries`) are written as CSV next to a render's report and
plotted by ``animbatch plot``.
"""

from __future__ import annotations

import dataclasses
import io
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from animbatch.errors import AccuracyWarning
from animbatch.sim.contact.audit import Overlap, OverlapAudit
from animbatch.sim.deformable.intersections import crossing_pairs
from animbatch.sim.forces import SpringForces
from animbatch.sim.forces.dihedral import DihedralSprings
from animbatch.sim.forces.gravitation import InverseSquarePairs
from animbatch.sim.forces.pressure import Pressure
from animbatch.sim.integrators.advice import Encounter, closest_encounter
from animbatch.sim.integrators.guard import energy_scale
from animbatch.sim.integrators.methods import METHODS
from animbatch.sim.integrators.step_plan import ONE_STEP_PER_FRAME
from animbatch.sim.invariants import angular_momentum, centre_of_mass, kinetic_energy, linear_momentum, potential_energy
from animbatch.sim.model.dynamics import Dynamics
from animbatch.sim.model.model import Model

#: Relative drift of a conserved quantity above which a run warns (``solver.drift_warning``).
DEFAULT_DRIFT_WARNING = 0.01
QUANTITIES = ("energy", "momentum", "angular_momentum")
UNITS = {"energy": "J", "momentum": "kg·m/s", "angular_momentum": "kg·m²/s"}
#: A step used that differs from ``solver.dt`` by more than this fraction is pointed out (0.0333334 for one step
#: per frame at 30 fps is the same step).
DT_DIFFERS = 1e-3


#: How the damping of terms that also have a potential is named.
DAMPED = {"spring": "spring damping", "dihedral": "dihedral damping", "controller": "controller damping"}


@dataclass(frozen=True)
class Law:
    """Whether a scene conserves one quantity, and in words why (or why not)."""

    conserved: bool
    reason: str


def _elastic_contacts(model: Model) -> bool:
    """True when every pair of materials that can meet in the scene bounces with e = 1 and no friction."""
    world = model.contact_world
    if world is None:
        return True
    if world.group is not None and np.any((world.group >= 0) & world.collides):
        return False  # cloth and lattice vertices never bounce
    table = world.materials
    bodies = np.unique(world.body_material[world.collides])
    statics = world.statics
    fixed = np.unique(np.concatenate([statics.plane_material, statics.sphere_material, statics.box_material,
                                      statics.triangle_material]).astype(np.intp))
    solids = np.union1d(fixed, bodies) if world.bodies_collide else fixed
    pairs = np.ix_(bodies, solids)
    return bool(np.all(table.restitution[pairs] == 1.0) and np.all(table.static_friction[pairs] == 0.0)
                and np.all(table.kinetic_friction[pairs] == 0.0))


def _has_fixed_colliders(model: Model) -> bool:
    world = model.contact_world
    return world is not None and world.statics.count > 0


def conservation_laws(model: Model) -> dict[str, Law]:
    """Which of energy, linear momentum and angular momentum the scene conserves, with the reason.

    Energy: every force derives from a potential we track (gravity, gravitation, springs, dihedral springs,
    controllers to fixed targets), nothing moves the anchors, and collisions (if any) are elastic and frictionless.
    Momenta: every force is internal to the bodies (gravitation, springs and dihedral springs between bodies) and no
    fixed collider or anchor pushes them; contacts between bodies exchange equal and opposite impulses at one point,
    so they keep both momenta.
    """
    energy_culprits = []
    for term in model.force_terms:
        if term.adds_energy:
            energy_culprits.append(f"{term.label} does work that no potential accounts for")
        elif term.dissipative:
            energy_culprits.append(f"{DAMPED.get(term.label, term.label)} dissipates it")
    if model.anchors.moving:
        energy_culprits.append("moving anchors do work")
    if model.joints is not None and model.joints.driven:
        energy_culprits.append("joint motors do work")
    if model.contact_world is not None and model.contact_world.moving is not None:
        energy_culprits.append("moving colliders do work")
    if model.kinematic is not None:
        energy_culprits.append("kinematic bodies (keyframes or motion) do work")
    if model.joints is not None and model.joints.stopping:
        energy_culprits.append("joint limits and ropes stop bodies inelastically")
    if model.contact_world is not None and not _elastic_contacts(model):
        energy_culprits.append("collisions lose it: restitution below 1 or friction")
    if energy_culprits:
        energy = Law(False, "; ".join(dict.fromkeys(energy_culprits)))
    else:
        sources = sorted({term.label for term in model.force_terms})
        energy = Law(True, ("all forces derive from potentials: " + ", ".join(sources) if sources
                            else "no force acts") + ("; collisions are elastic and frictionless"
                                                     if model.contact_world is not None else ""))

    external = []
    for term in model.force_terms:
        if isinstance(term, SpringForces):
            if term.springs.second_is_anchor.any():
                external.append("springs to anchors or pins hold the bodies")
        elif not isinstance(term, InverseSquarePairs | DihedralSprings | Pressure):
            external.append(f"{term.label} is an external force")
    if model.joints is not None and model.joints.anchored:
        external.append("joints to the world or anchors hold the bodies")
    if _has_fixed_colliders(model):
        external.append("fixed colliders push the bodies")
    if model.anchors.moving:
        external.append("moving anchors pull the bodies")
    if model.kinematic is not None:
        external.append("kinematic bodies (keyframes or motion) move as their paths say, whatever acts on them")
    if external:
        momentum = Law(False, "; ".join(dict.fromkeys(external)))
    else:
        contacts = "; contacts only between bodies" if model.contact_world is not None else ""
        if any(isinstance(term, Pressure) for term in model.force_terms):
            contacts += "; pressure on a closed surface adds no net force or torque"
        momentum = Law(True, "all forces act between the bodies, equal and opposite" + contacts)
    angular = Law(momentum.conserved, momentum.reason if not momentum.conserved else
                  "all forces act between the bodies, equal and opposite on one line" + contacts)
    return {"energy": energy, "momentum": momentum, "angular_momentum": angular}


@dataclass(frozen=True)
class QuantitySeries:
    """The scene's mechanical quantities at the frame times: ``times`` (F,) [s]; kinetic, potential and total energy
    (F,) [J]; linear momentum (F, 3) [kg·m/s]; angular momentum about the scene's centre of mass (F, 3) [kg·m²/s];
    the speed of each scene body's centre of mass (F, B) [m/s] (a cloth or lattice: of its vertices' centre of
    mass), named by ``body_names`` (B,); and the proper times (F, K) [s] of the clocks some bodies carry."""

    times: np.ndarray
    kinetic: np.ndarray
    potential: np.ndarray
    momentum: np.ndarray
    angular_momentum: np.ndarray
    body_names: tuple[str, ...]
    speeds: np.ndarray
    clock_names: tuple[str, ...] = ()
    proper_times: np.ndarray | None = None  # (F, K) [s], the clocks' proper times

    @property
    def total(self) -> np.ndarray:
        return self.kinetic + self.potential

    @classmethod
    def of_states(cls, model: Model, states: np.ndarray) -> QuantitySeries:
        """From the states (F, n) at ``model.frame_times``."""
        count = len(states)
        times = np.asarray(model.frame_times[:count], float)
        if not model.body_count:
            zero, zero3 = np.zeros(count), np.zeros((count, 3))
            return cls(times, zero, zero, zero3, zero3, (), np.zeros((count, 0)))
        centre = centre_of_mass(model, states)
        spin = angular_momentum(model, states, origin=centre[:, None, :])
        names, first, owner = np.unique(np.asarray(model.owners), return_index=True, return_inverse=True)
        order = np.argsort(first)  # scene order: as each body is first seen
        mass = model.bodies.mass
        weighted = np.zeros((count, len(names), 3))
        np.add.at(weighted, (slice(None), owner), model.velocities(states) * mass[:, None])  # type: ignore[arg-type]  # numpy stubs: slice in index
        totals = np.bincount(owner, weights=mass, minlength=len(names))
        speeds = np.linalg.norm(weighted / totals[None, :, None], axis=2)[:, order]
        clocks = model.clocks.names if model.clocks is not None else ()
        return cls(times, kinetic_energy(model, states), potential_energy(model, states),
                   linear_momentum(model, states), spin, tuple(str(n) for n in names[order]), speeds, clocks,
                   model.proper_times(states))

    def csv(self) -> str:
        """The series as CSV text: one row per frame, SI units in the column names."""
        columns = ["time_s", "kinetic_energy_J", "potential_energy_J", "total_energy_J", "momentum_x_kg_m_s",
                   "momentum_y_kg_m_s", "momentum_z_kg_m_s", "angular_momentum_x_kg_m2_s",
                   "angular_momentum_y_kg_m2_s", "angular_momentum_z_kg_m2_s"]
        columns += [f"speed_{name}_m_s" for name in self.body_names]
        columns += [f"proper_time_{name}_s" for name in self.clock_names]
        clocks = self.proper_times if self.proper_times is not None else np.zeros((len(self.times), 0))
        table = np.column_stack([self.times, self.kinetic, self.potential, self.total, self.momentum,
                                 self.angular_momentum, self.speeds, clocks])
        out = io.StringIO()
        out.write(",".join(columns) + "\n")
        np.savetxt(out, table, delimiter=",", fmt="%.10g")
        return out.getvalue()


def _scales(model: Model, states: np.ndarray) -> dict[str, float]:
    """What each drift is relative to: energy, the largest of |E₀|, the kinetic energy and M g L (see
    :func:`~animbatch.sim.integrators.guard.energy_scale`); momentum, the largest Σ m|v| over the run; angular momentum,
    the largest Σ m |x - c| |v| plus the bodies' spins |L| over the run (c: the centre of mass)."""
    mass = model.bodies.mass
    velocities = model.velocities(states)
    speed = np.linalg.norm(velocities, axis=2)
    arm = np.linalg.norm(model.positions(states) - centre_of_mass(model, states)[:, None, :], axis=2)
    spin = 0.0
    if model.rigid is not None:
        spin = np.linalg.norm(model.layout.view(states, "rigid_angular_momentum"), axis=2).sum(axis=1)
    return {"energy": energy_scale(model),
            "momentum": float(np.max(speed @ mass, initial=0.0)),
            "angular_momentum": float(np.max((arm * speed) @ mass + spin, initial=0.0))}


def drifts(model: Model, states: np.ndarray, series: QuantitySeries, laws: dict[str, Law]
           ) -> dict[str, tuple[float, float] | None]:
    """For each conserved quantity, (relative drift, scale): the largest change from the first frame over the run,
    divided by the scale (:func:`_scales`); None where the scene does not conserve it."""
    scales = _scales(model, states)
    values = {"energy": series.total[:, None], "momentum": series.momentum,
              "angular_momentum": series.angular_momentum}
    result: dict[str, tuple[float, float] | None] = {}
    for name in QUANTITIES:
        if not laws[name].conserved or len(states) == 0:
            result[name] = None
            continue
        change = float(np.max(np.linalg.norm(values[name] - values[name][0], axis=1)))
        scale = scales[name]
        result[name] = (change / scale if scale > 0 else 0.0, scale)
    return result


def drift_advice(method: str, drift: float, threshold: float, *, rtol: float | None, dt: float | None) -> str:
    """What to change when a conserved quantity drifts by ``drift`` (relative) under ``method``, to bring it under
    ``threshold``: a step or tolerance worked out from the method's order, with a factor two to spare."""
    shrink = 0.5 * threshold / drift  # how much smaller the drift must become
    if method in METHODS and METHODS[method].fixed_step:
        order = METHODS[method].order  # its drift over a run shrinks as dt to this power
        step = f"solver.dt ≤ {dt * shrink ** (1 / order):.3g} s (its drift shrinks as dt^{order})" if dt else \
            "a smaller solver.dt"
        if not (METHODS[method].symplectic or METHODS[method].implicit):  # explicit, not symplectic: drifts
            return ("it is not symplectic, so its error accumulates step after step: use a symplectic method "
                    f"(solver.method: verlet) or an adaptive one (DOP853), or {step}")
        if method == "backward_euler":
            return ("backward Euler damps every vibration it cannot resolve, which conservative scenes show as lost "
                    f"energy: use verlet (symplectic), or {step}")
        return f"use {step}"
    # an adaptive run's drift falls with its tolerance, but seldom in proportion: aim a decade lower
    tighter = f" to {rtol * shrink / 10:.2g} or less" if rtol else ""
    advice = f"tighten solver.rtol{tighter} (and solver.atol with it; tighter still if this warning stays)"
    if method == "DOP853":  # already the highest order: a fixed-step symplectic method is the other way
        return f"{advice}, or use verlet with a small solver.dt, which keeps energy bounded over long runs"
    return f"{advice}, or use DOP853, whose high order pays off at tight tolerances"


@dataclass
class Ledger:
    """The ledger of one run (see the module notes); ``as_dict`` is what report.json and trajectory files hold.
    ``warnings`` follow from the rest (:func:`judge`), so a cached run can be judged again against another
    ``drift_warning`` without simulating again."""

    method: str
    kind: str  # "adaptive" or "fixed-step"
    rtol: float | None
    step: dict[str, Any]
    work: dict[str, Any]
    conservation: dict[str, dict[str, Any]]
    drift_warning: float
    contacts: dict[str, Any] | None = None
    encounter: dict[str, Any] | None = None  # two gravitating bodies closer than their radii, without softening
    joints: dict[str, Any] | None = None  # the joints' largest violations over the frames (see joint_drift)
    orientation: dict[str, Any] | None = None  # rotation matrices' distance from rotations (orientation_drift)
    surfaces: dict[str, Any] | None = None  # cloth or lattices through themselves or each other (surface_crossings)
    warnings: list[str] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


def surface_crossings(model: Model, states: np.ndarray, times: np.ndarray) -> dict[str, Any] | None:
    """Where cloth and lattices passed through themselves or each other over the frames ``states`` (F, n) at
    ``times`` (F,) [s] (they do not collide with their own triangles, nor with another's): the first frame time
    with a crossing, the frame with the most crossing triangle pairs and how many, and which bodies crossed (pairs
    of names, a name twice for a body through itself); None when no frame has one."""
    deformables = model.deformables
    assert deformables is not None
    bodies, triangles = deformables.bodies, deformables.triangles
    owner = np.repeat(np.arange(len(bodies)), [len(body.triangles) for body in bodies])
    dynamics = Dynamics(model)
    first, most, worst = None, 0, 0.0
    crossed: set[tuple[int, int]] = set()
    for y, t in zip(states, times):
        state = dynamics.kinematics(*dynamics.split(y), t=float(t))
        x = deformables.vertex_map.place(state.x, state.rotation, deformables.anchors.positions(float(t)))
        pairs = crossing_pairs(x, triangles)
        if len(pairs):
            first = float(t) if first is None else first
            if len(pairs) > most:
                most, worst = len(pairs), float(t)
            crossed.update(map(tuple, np.unique(np.sort(owner[pairs], axis=1), axis=0).tolist()))
    if first is None:
        return None
    return {"first_time": first, "worst_time": worst, "pairs": most,
            "bodies": [[bodies[a].name, bodies[b].name] for a, b in sorted(crossed)],
            "self_collision": [body.name for body in bodies if body.self_collision]}


def crossing_message(surfaces: dict[str, Any]) -> str:
    """The warning for :func:`surface_crossings`' finding."""
    through = [f"'{a}' through itself" if a == b else f"'{a}' and '{b}' through each other"
               for a, b in surfaces["bodies"]]
    colliding = set(surfaces.get("self_collision", ()))
    off = sorted({name for pair in surfaces["bodies"] for name in pair} - colliding)
    start = (f"{', '.join(through)} from t = {surfaces['first_time']:.4g} s ({surfaces['pairs']} triangle pairs "
             f"crossing at t = {surfaces['worst_time']:.4g} s)")
    if off:
        return (f"{start}: {', '.join(map(repr, off))} {'has' if len(off) == 1 else 'have'} self-collision off, so "
                "the frames from then on draw them passing through. Set self_collision: true on every cloth or "
                "lattice that meets another or folds (with solver.method symplectic_euler, verlet or "
                "backward_euler), or give the cloth room to fall without folding onto itself.")
    return (f"{start}, though they collide with themselves and each other: a step too long for how fast the layers "
            "close. Try a smaller solver.dt, or a larger thickness.")


def orientation_drift(model: Model, states: np.ndarray) -> dict[str, Any]:
    """How far integrated rotation matrices strayed from rotations over the frames ``states`` (F, n): the largest
    ‖RᵀR − I‖ (Frobenius) of any body, at which frame, the last frame's, and how often they were renormalised."""
    errors = model.orientation_errors(states).max(axis=-1)  # (F,)
    every = model.renormalise_every
    frame = int(np.argmax(errors))
    return {"largest": float(errors[frame]), "frame": frame, "final": float(errors[-1]),
            "renormalise": "never" if not every else "every step" if every == 1 else f"every {every} steps"}


def step_note(requested_dt: float | None, used: float | None, interval: float | None, dt_given: bool = True
              ) -> str | None:
    """Why a fixed step ``used`` [s] differs from the step bound ``requested_dt`` (``solver.dt``, or the default
    when not ``dt_given``); None when it does not, to :data:`DT_DIFFERS`."""
    if used is None or requested_dt is None or interval is None:
        return None
    if abs(used - requested_dt) <= DT_DIFFERS * requested_dt:
        return None
    bound = f"solver.dt = {requested_dt:.4g} s" if dt_given else f"the default step {requested_dt:.4g} s"
    return f"the largest step ≤ {bound} that divides the frame interval {interval:.4g} s"


def step_record(adaptive: bool, stats: dict[str, Any], requested_dt: float | None, interval: float | None,
                duration: float, dt_given: bool = True) -> dict[str, Any]:
    """The step a run used: fixed-step methods the step and how it relates to ``solver.dt`` and the frame interval
    [s]; adaptive ones their smallest, largest and mean accepted steps over the ``duration`` [s]."""
    if not adaptive:
        used = stats.get("dt")
        record: dict[str, Any] = {"requested_dt": requested_dt, "dt_given": dt_given, "dt": used,
                                  "steps_per_frame": stats.get("substeps_per_frame")}
        note = step_note(requested_dt, used, interval, dt_given)
        if note:
            record["note"] = f"{stats.get('substeps_per_frame')} steps of {used:.4g} s per frame: {note}"
        return record
    steps = stats.get("steps") or 0
    return {"smallest": stats.get("smallest_step"), "largest": stats.get("largest_step"),
            "mean": duration / steps if steps else None}


def judge(ledger: dict[str, Any]) -> list[str]:
    """The warnings a ledger (as a dict) calls for: one for the conserved quantities that drifted more than its
    ``drift_warning`` (with the fix the worst of them needs), one for a missed collision, one for bodies that start
    inside each other, one for joints that did not hold."""
    method, threshold = ledger["method"], ledger["drift_warning"]
    adaptive = ledger["kind"] == "adaptive"
    messages = []
    drifted = {name: entry for name, entry in ledger["conservation"].items()
               if entry.get("drift") is not None and entry["drift"] > threshold}
    if drifted:
        parts = [f"the {name.replace('_', ' ')}{' drifted' if not number else ''} by {100 * entry['drift']:.3g} % "
                 f"(of {entry['scale']:.4g} {entry['unit']})" for number, (name, entry) in enumerate(drifted.items())]
        worst = max(entry["drift"] for entry in drifted.values())
        advice = drift_advice(method, worst, threshold, rtol=ledger.get("rtol") if adaptive else None,
                              dt=ledger["step"].get("dt"))
        encounter = ledger.get("encounter")
        if encounter:  # the likelier culprit: a pass closer than the bodies' radii, where 1/r² has no bound

            advice += ". " + Encounter(**encounter).advice()
        messages.append(
            " and ".join(parts) + f" over the run, though this scene conserves {'it' if len(drifted) == 1 else 'them'}"
            f" (solver.drift_warning: {100 * threshold:.3g} %). {method} is not accurate enough here: {advice}.")
    for overlap in (ledger.get("contacts") or {}).values():
        if overlap:

            messages.append(Overlap(**overlap).message(method, adaptive=adaptive))
    if ledger.get("surfaces"):
        messages.append(crossing_message(ledger["surfaces"]))
    joints = ledger.get("joints")
    if joints and (joints.get("max_violation", 0.0) > JOINT_LENGTH_WARNING
                   or joints.get("max_angle_violation", 0.0) > JOINT_ANGLE_WARNING):
        messages.append(joint_message(joints, method, adaptive=adaptive))
    folding = (ledger.get("work") or {}).get("bodies", {}).get("self_collision")
    if folding and folding.get("unresolved"):
        messages.append(
            f"self-collision could not part every pair of the cloth's layers in {folding['unresolved']} step(s), even "
            f"with impact zones of up to {folding['largest_zone']} vertices moving as one: those steps may pass "
            "through. Try a smaller solver.dt, or a thickness closer to the cloth's edge length.")
    return messages


#: A joint further than this from holding [m, rad] over a run is reported: the fixed-step methods hold joints to
#: rounding, and the adaptive ones to their tolerance, except a limit or rope next to contacts (held by stabilisation).
JOINT_LENGTH_WARNING, JOINT_ANGLE_WARNING = 1e-3, 0.01


def joint_message(joints: dict[str, Any], method: str, *, adaptive: bool) -> str:
    """The warning for joints that did not hold (``joints``: :func:`joint_drift`'s entry)."""
    parts = [f"{joints[key]:.3g} {unit}" for key, unit in (("max_violation", "m"), ("max_angle_violation", "rad"))
             if joints.get(key, 0.0) > (JOINT_LENGTH_WARNING if unit == "m" else JOINT_ANGLE_WARNING)]
    where = f"the worst joint {joints.get('joint')!r} at t = {joints.get('time', 0.0):.4g} s"
    fix = (f"{method} holds the joints by stabilisation, and a limit or rope next to contacts by that alone, so a "
           "stop reached fast is overshot. Use solver.method: symplectic_euler or verlet, which meet every stop and "
           "project the joints at every step" if adaptive else
           f"{method} projects the joints at every step, yet they came apart: try a smaller solver.dt")
    return (f"the joints were up to {' and '.join(parts)} from holding ({where}: past a limit or a rope's length, "
            f"or pulled apart), and the motion after it is wrong. {fix}.")


def with_threshold(ledger: dict[str, Any], drift_warning: float) -> dict[str, Any]:
    """The same ledger judged against another ``drift_warning`` (a cached bake rendered with a new setting)."""
    judged = {**ledger, "drift_warning": drift_warning}
    judged["warnings"] = judge(judged)
    return judged


def warn_again(ledger: dict[str, Any]) -> None:
    """Issue a stored ledger's warnings again (a run from a cached bake or a trajectory file tells them too)."""
    for message in ledger.get("warnings", []):
        warnings.warn(message, AccuracyWarning, stacklevel=2)


def build_ledger(model: Model, states: np.ndarray, stats: dict[str, Any], particle_stats: dict[str, Any], *,
                 method: str, adaptive: bool, requested_dt: float | None, rtol: float | None,
                 dt_given: bool = True, drift_warning: float = DEFAULT_DRIFT_WARNING,
                 series: QuantitySeries | None = None) -> Ledger:
    """The ledger of a run of ``model`` that gave ``states`` (F, n) at the frame times, with the solver's statistics
    ``stats`` and the emitted particles' ``particle_stats`` (empty without emitters). Its warnings are also issued
    as :class:`~animbatch.errors.AccuracyWarning`."""
    times = model.frame_times
    interval = float(times[1] - times[0]) if len(times) > 1 else None
    work: dict[str, Any] = {}
    if model.layout.size:
        work["bodies"] = {"steps": stats.get("steps", 0), "rhs_evaluations": stats.get("rhs_evaluations", 0),
                          "wall_time": stats.get("wall_time", 0.0)}
        if stats.get("lu_decompositions"):  # implicit methods: the sparse factorisations, usually most of the cost
            work["bodies"]["factorisations"] = stats["lu_decompositions"]
        solves = stats.get("contact_solves")
        if solves and solves.get("solves") and model.contact_settings is not None:
            # how the contact impulse solves ended: those that ran out of sweeps left contacts off their targets
            work["bodies"]["contact_solves"] = {**solves, "iterations": model.contact_settings.iterations}
        if stats.get("self_contact"):  # cloth's self-collision: what its filter did
            work["bodies"]["self_collision"] = dict(stats["self_contact"])
    if particle_stats:
        work["particles"] = {"steps": particle_stats.get("steps", 0),
                             "rhs_evaluations": particle_stats.get("rhs_evaluations", 0),
                             "wall_time": particle_stats.get("wall_time", 0.0)}
    laws = conservation_laws(model)
    if model.body_count:
        series = series if series is not None else QuantitySeries.of_states(model, states)
        drift = drifts(model, states, series, laws)
    else:
        drift = {name: None for name in QUANTITIES}
    conservation = {name: {"conserved": laws[name].conserved, "reason": laws[name].reason,
                           "drift": None if (found := drift[name]) is None else found[0],
                           "scale": None if found is None else found[1], "unit": UNITS[name]}
                    for name in QUANTITIES}

    encounter = closest_encounter(model, model.positions(states), times) if model.body_count else None
    contacts = None
    if model.contact_world is not None and model.body_count:
        overlaps = OverlapAudit(model, Dynamics(model)).run(states, times,
                                                            [tuple(i) for i in stats.get("impacts", [])])
        contacts = {kind: overlap.as_dict() if overlap is not None else None for kind, overlap in overlaps.items()}
    stepped = stats if model.layout.size or not particle_stats else particle_stats  # emitters only: their steps
    ledger = Ledger(method, "adaptive" if adaptive else "fixed-step", rtol if adaptive else None,
                    step_record(adaptive, stepped, requested_dt, interval, float(times[-1] - times[0]), dt_given),
                    work,
                    conservation, drift_warning, contacts,
                    encounter=dataclasses.asdict(encounter) if encounter is not None else None)
    if model.joints is not None and len(states):
        ledger.joints = joint_drift(model, states, times)
    if model.layout.matrix_orientation and len(states):
        ledger.orientation = orientation_drift(model, states)
    if model.deformables is not None and model.deformables.bodies and len(states):
        ledger.surfaces = surface_crossings(model, states, times)
    ledger.warnings = judge(ledger.as_dict())
    for message in ledger.warnings:
        warnings.warn(message, AccuracyWarning, stacklevel=2)
    return ledger


def joint_drift(model: Model, states: np.ndarray, times: np.ndarray) -> dict[str, Any]:
    """How far the joints were from holding over the frames ``states`` (F, n) at ``times`` (F,) [s]: the largest
    violation of a length [m] (``max_violation``), of an angle [rad] (``max_angle_violation``, for hinges, sliders
    and welds), the joint and the time of the worst."""
    joints = model.joints
    assert joints is not None
    dynamics = Dynamics(model)
    violation = np.stack([joints.violation(joints.motion(dynamics.kinematics(*dynamics.split(y), t=float(t))))
                          for y, t in zip(states, times)])
    result: dict[str, Any] = {}
    for key, rows in (("max_violation", ~joints.row_is_angle), ("max_angle_violation", joints.row_is_angle)):
        if rows.any():
            part = violation[:, rows]
            frame, row = np.unravel_index(int(np.argmax(part)), part.shape)
            result[key] = float(part[frame, row])
            if key == "max_violation" or result[key] > result.get("max_violation", 0.0):
                result["joint"] = joints.names[joints.row_joint[np.flatnonzero(rows)[row]]]
                result["time"] = float(times[frame])
    result.setdefault("max_violation", 0.0)
    return result


def _number(value: float) -> str:
    return f"{value:.2g}" if value else "0"


def summary(ledger: dict[str, Any]) -> str:
    """The ledger in one line: method and step, work of every part, drifts, and how many warnings."""
    parts = []
    method, step = ledger.get("method", "?"), ledger.get("step", {})
    work = ledger.get("work", {})
    if ledger.get("kind") == "fixed-step" and step.get("dt"):
        # where the step came from: solver.dt (no note), the default, or either adjusted to divide 1/fps
        given = step.get("dt_given", True)
        bound = "solver.dt" if given else "the default step"
        how = f" dt {step['dt']:.4g} s"
        if step.get("note"):
            how += f" ({bound} {step['requested_dt']:.4g} s does not divide 1/fps)"
        elif not given:
            how += " (default: one step per frame)" if method in ONE_STEP_PER_FRAME else " (default)"
    elif step.get("smallest") is not None:
        how = f" steps {step['smallest']:.2g}–{step['largest']:.2g} s"
    else:
        how = ""
    if "bodies" in work:
        bodies = work["bodies"]
        factored = f", {bodies['factorisations']} factorisations" if bodies.get("factorisations") else ""
        parts.append(f"{method}{how}: {bodies['steps']} steps, {bodies['rhs_evaluations']} RHS{factored}")
    solves = work.get("bodies", {}).get("contact_solves")
    if solves and solves["unconverged"]:
        parts.append(f"contacts: {solves['unconverged']} of {solves['solves']} solves stopped short (stalled, or "
                     f"at all {solves['iterations']} iterations), leaving contacts off their targets by up to "
                     f"{_number(solves['residual'])} m/s")
    folding = work.get("bodies", {}).get("self_collision")
    if folding and (folding["repelled"] or folding["collisions"]):
        zones = (f", {folding['zones']} impact zones (largest {folding['largest_zone']} vertices)" if folding["zones"]
                 else "")
        parts.append(f"self-collision: {folding['repelled']} repulsions, {folding['collisions']} collisions{zones}")
    if "particles" in work:
        particles = work["particles"]
        parts.append(f"particles ({method}{'' if 'bodies' in work else how}): {particles['steps']} steps, "
                     f"{particles['rhs_evaluations']} RHS")
    conservation = ledger.get("conservation", {})
    kept = [f"{name.replace('_', ' ')} {_number(entry['drift'])}" for name, entry in conservation.items()
            if entry.get("drift") is not None]
    if kept:
        parts.append("drift: " + ", ".join(kept))
    lost = [name.replace("_", " ") for name, entry in conservation.items() if not entry.get("conserved")]
    if lost and "bodies" in work:
        parts.append("not conserved: " + ", ".join(lost))
    orientation = ledger.get("orientation")
    if orientation:
        parts.append(f"rotation matrices: ‖RᵀR − I‖ ≤ {_number(orientation['largest'])} ({orientation['renormalise']})")
    joints = ledger.get("joints")
    if joints:
        parts.append(f"joints: |C| ≤ {_number(joints['max_violation'])} m"
                     + (f", {_number(joints['max_angle_violation'])} rad" if "max_angle_violation" in joints else ""))
    count = len(ledger.get("warnings", []))
    if count:
        parts.append(f"{count} accuracy warning{'s' if count > 1 else ''} (above)")
    return " | ".join(parts)
