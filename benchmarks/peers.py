"""animbatch next to MuJoCo on the same small scenes, in the same process: ``bash scripts/dev.sh bench --only peers``.

MuJoCo is the yardstick for small rigid and jointed scenes. Each case is built twice from the same numbers: an
animbatch scene and an MJCF model. Both are timed for the whole run, after a warm-up (numba's kernels loaded, the
MJCF compiled). Each is also judged by what it should keep: the joints (animbatch integrates maximal coordinates, so
the gap a joint opens is its error; MuJoCo's generalized coordinates keep hinges by construction), the energy (the
largest change from the start over the run) and, for the hinged bar, the period against the closed form. MuJoCo's
semi-implicit Euler is its fastest integrator and the one the targets compare with; its RK4 is shown where the
accuracy is in question.

``mujoco`` is in the ``bench`` extra, never a runtime dependency; without it the cases are skipped with the command
that installs it.

Cases (issue 36's targets: the chain ≤ 5× MuJoCo's time, the bar ≤ 0.5 s, the double pendulum ≤ 1 s, the pile
≤ 20× MuJoCo's time per step, the ragdoll ≤ 10 s for 4 s):

* a chain of 20 bars (10 cm, 0.1 kg) on hinges, released from the horizontal, 5 s at dt 1 ms, by velocity Verlet
  and by semi-implicit Euler (MuJoCo's anchor's own method);
* one bar (1 m) on a hinge, released 60° from the vertical, 12 000 steps of 1 ms: its period against
  ``T = 4 √(I / (m g d)) K(sin²(θ₀/2))``;
* a double pendulum of point masses (1 kg and 0.5 kg on rods of 1 m and 0.8 m), 10 s: DOP853 at rtol 1e-8 here, RK4
  at 1 ms there;
* a dozen 20 cm boxes dropped in a loose stack on the ground, 3 s at 1 ms: the deepest a corner goes into the ground
  and the kinetic energy left at the end (MuJoCo: its deepest contact, which includes its soft contacts' give);
* ``scenes/mixed_pile.yaml`` (twelve bodies of five shapes into a bin) and ``scenes/dominoes.yaml`` as they are,
  3 s at 1 ms, step for step against MuJoCo's pile of boxes (issue 36's target for them: ≤ 20× its time per step);
* ``scenes/ragdoll_stairs.yaml`` as it is (4 s, timed once) and the same bodies, joints and stairs in MJCF.

And the other way round, MJCF models imported by ``animbatch import`` (issue 41): a 20-bar chain and
``scenes/models/figure.xml`` (ball joints, hinges, defaults classes, a servo), each simulated by both for 1 s from
the same file, with the largest difference between their joints' angles (:func:`imported_angles`).
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.special import ellipk

G = 9.81

Row = dict[str, object]


@dataclass
class Outcome:
    """One side of a case: wall time [s] and what it kept (text)."""

    seconds: float
    accuracy: str


def _timed(work: Callable[[], Any], repeats: int = 3) -> tuple[float, Any]:
    """The fastest wall time of ``repeats`` runs of ``work`` (after one warm-up run), and its last result."""
    result = work()
    best = np.inf
    for _ in range(repeats):
        started = time.perf_counter()
        result = work()
        best = min(best, time.perf_counter() - started)
    return best, result


# ------------------------------------------------------------------------------------------ animbatch's side


def _integrate(text: str, path: Any = None) -> tuple[Any, Any, Any, Any]:
    """Model, system, integrator and initial state of a scene text (``path``: the scene file it came from, whose
    folder holds its meshes), with the system the CLI would choose (compiled where it pays, which these scenes
    do)."""
    from animbatch.compile.integrator import make_integrator
    from animbatch.compile.model import compile_scene
    from animbatch.sim.model.compiled import dynamics_for
    from animbatch.stages import parse_scene

    loaded = parse_scene(text, filename="peer.yaml" if path is None else str(path), path=path)
    model = compile_scene(loaded.spec, "." if path is None else path.parent)
    return model, dynamics_for(model, np.inf), make_integrator(loaded.spec.solver, model), loaded


def _run(text: str, repeats: int = 3, path: Any = None) -> tuple[float, Any, Any, Any]:
    model, system, integrator, loaded = _integrate(text, path)
    seconds, result = _timed(lambda: integrator.integrate(system, model.y0, model.frame_times), repeats)
    return seconds, result, model, loaded


def _energy_drift(model: Any, states: np.ndarray) -> float:
    """The largest change of the total energy from the first frame [J]."""
    from animbatch.sim.model.dynamics import Dynamics

    dynamics = Dynamics(model)
    totals = [dynamics.energy(float(t), *dynamics.split(y))[0] for t, y in zip(model.frame_times, states)]
    return float(np.max(np.abs(np.array(totals) - totals[0])))


def _joint_gap(model: Any, states: np.ndarray) -> float:
    from animbatch.sim.ledger import joint_drift

    return float(joint_drift(model, states, model.frame_times)["max_violation"])


# ------------------------------------------------------------------------------------------ the chain


def chain_scene(count: int = 20, length: float = 0.1, mass: float = 0.1, method: str = "verlet",
                dt: float = 1e-3, duration: float = 5.0) -> str:
    """``count`` bars (``length`` × 2 cm × 2 cm, ``mass``) on hinges about z, laid along +x from the origin."""
    lines = [f"duration: {duration}", "fps: 50", f"solver: {{method: {method}, dt: {dt}}}", "bodies:"]
    for i in range(count):
        lines.append(f"  - {{name: bar{i}, type: rigid, shape: {{type: box, size: [{length}, 0.02, 0.02]}}, "
                     f"mass: {mass}, position: [{length * (i + 0.5):.6f}, 0, 0]}}")
    lines.append("joints:")
    lines.append("  - {type: hinge, between: [bar0], anchor: [0, 0, 0], axis: [0, 0, 1]}")
    for i in range(1, count):
        lines.append(f"  - {{type: hinge, between: [bar{i}, bar{i - 1}], anchor: [{length * i:.6f}, 0, 0], "
                     "axis: [0, 0, 1]}")
    lines.append("fields: [{type: gravity}]")
    return "\n".join(lines) + "\n"


def chain_mjcf(count: int = 20, length: float = 0.1, mass: float = 0.1, integrator: str = "Euler",
               dt: float = 1e-3) -> str:
    """The same chain in MJCF: bars along +x, hinges about y, gravity along −z (the same plane of motion)."""
    bodies, closing = "", ""
    for i in range(count):
        where = "0 0 0" if i == 0 else f"{length} 0 0"
        bodies += (f'<body pos="{where}"><joint type="hinge" axis="0 1 0"/><geom type="box" '
                   f'size="{length / 2} 0.01 0.01" pos="{length / 2} 0 0" mass="{mass}" contype="0" '
                   'conaffinity="0"/>')
        closing += "</body>"
    return (f'<mujoco><option timestep="{dt}" integrator="{integrator}"><flag energy="enable"/></option>'
            f"<worldbody>{bodies}{closing}</worldbody></mujoco>")


def _mujoco_run(xml: str, steps: int, record: Callable[[Any, Any], Any] | None = None
                ) -> tuple[float, float, list[Any]]:
    """Wall time of ``steps`` steps of an MJCF model (best of three), the largest energy change [J] over the run,
    and what ``record(model, data)`` returned after each step."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)

    def reset() -> None:  # to the first keyframe where there is one (a starting velocity)
        if model.nkey:
            mujoco.mj_resetDataKeyframe(model, data, 0)
        else:
            mujoco.mj_resetData(model, data)

    def work() -> tuple[float, list[Any]]:
        reset()
        mujoco.mj_forward(model, data)
        start = float(data.energy.sum())
        largest, records = 0.0, []
        for _ in range(steps):
            mujoco.mj_step(model, data)
            largest = max(largest, abs(float(data.energy.sum()) - start))
            if record is not None:
                records.append(record(model, data))
        return largest, records

    def bare() -> None:  # timed without the bookkeeping
        reset()
        for _ in range(steps):
            mujoco.mj_step(model, data)

    seconds, _ = _timed(bare)
    largest, records = work()
    return seconds, largest, records


def _chain_case(quick: bool, method: str) -> tuple[str, Outcome, Outcome, list[tuple[str, Outcome]]]:
    duration = 1.0 if quick else 5.0
    steps = int(round(duration / 1e-3))
    seconds, result, model, _ = _run(chain_scene(duration=duration, method=method))
    ours = Outcome(seconds, f"joints {_joint_gap(model, result.states):.1g} m, energy ±"
                            f"{_energy_drift(model, result.states):.2g} J")
    theirs = []
    for integrator in ("Euler", "RK4"):
        mj_seconds, drift, _ = _mujoco_run(chain_mjcf(integrator=integrator), steps)
        theirs.append((integrator, Outcome(mj_seconds, f"joints exact, energy ±{drift:.2g} J")))
    return f"20-bar hinge chain, {duration:g} s at 1 ms ({method})", ours, theirs[0][1], theirs


def case_chain(quick: bool) -> tuple[str, Outcome, Outcome, list[tuple[str, Outcome]]]:
    return _chain_case(quick, "verlet")


def case_chain_euler(quick: bool) -> tuple[str, Outcome, Outcome, list[tuple[str, Outcome]]]:
    """The chain by the method MuJoCo's anchor uses: semi-implicit (symplectic) Euler on both sides."""
    return _chain_case(quick, "symplectic_euler")


# ------------------------------------------------------------------------------------------ the hinged bar

BAR_LENGTH, BAR_WIDTH, BAR_DENSITY = 1.0, 0.02, 1000.0
AMPLITUDE = 60.0


def bar_period() -> float:
    """T = 4 √(I / (m g d)) K(sin²(θ₀/2)) for the bar about its end."""
    inertia = (BAR_LENGTH**2 + BAR_WIDTH**2) / 12 + (BAR_LENGTH / 2) ** 2
    return float(4 * np.sqrt(inertia / (G * BAR_LENGTH / 2)) * ellipk(np.sin(np.radians(AMPLITUDE) / 2) ** 2))


def bar_scene(steps: int, dt: float = 1e-3) -> str:
    theta = np.radians(AMPLITUDE)
    centre = 0.5 * BAR_LENGTH * np.array([np.sin(theta), -np.cos(theta), 0.0])
    return f"""
duration: {steps * dt}
fps: 50
solver: {{method: verlet, dt: {dt}}}
bodies:
  - {{name: bar, type: rigid, shape: {{type: box, size: [{BAR_WIDTH}, {BAR_LENGTH}, {BAR_WIDTH}]}},
      density: {BAR_DENSITY}, position: [{float(centre[0])!r}, {float(centre[1])!r}, 0], orientation: {{axis: [0, 0, 1],
      angle: {AMPLITUDE}}}}}
joints: [{{type: hinge, between: [bar], anchor: [0, 0, 0], axis: [0, 0, 1]}}]
fields: [{{type: gravity}}]
stopwatches:
  - name: period
    start: {{body: bar, point: [0, 0, 0], normal: [1, 0, 0], direction: along}}
    stop: {{body: bar, point: [0, 0, 0], normal: [1, 0, 0], direction: along}}
"""


def bar_mjcf(dt: float = 1e-3, integrator: str = "RK4") -> str:
    mass = BAR_DENSITY * BAR_LENGTH * BAR_WIDTH**2
    return (f'<mujoco><option timestep="{dt}" integrator="{integrator}"><flag energy="enable"/></option><worldbody>'
            f'<body><joint name="hinge" type="hinge" axis="0 1 0" ref="0"/><geom type="box" size="{BAR_WIDTH / 2} '
            f'{BAR_WIDTH / 2} {BAR_LENGTH / 2}" pos="0 0 {-BAR_LENGTH / 2}" mass="{mass}" contype="0" '
            'conaffinity="0"/></body></worldbody></mujoco>')


def _crossings(angles: np.ndarray, dt: float) -> np.ndarray:
    """The times [s] at which an angle sampled every ``dt`` passes zero going up, by linear interpolation (the
    angle is straight there: its second derivative, −ω² sin θ, vanishes at θ = 0)."""
    up = np.flatnonzero((angles[:-1] < 0) & (angles[1:] >= 0))
    return (up + 1 - angles[up + 1] / (angles[up + 1] - angles[up])) * dt


def case_bar(quick: bool) -> tuple[str, Outcome, Outcome, list[tuple[str, Outcome]]]:
    from animbatch import api

    steps = 5_000 if quick else 12_000
    seconds, result, model, loaded = _run(bar_scene(steps))
    trajectory = api.simulate(loaded, model=model)
    (reading,) = api.stopwatch_readings(loaded.spec.stopwatches, trajectory)
    exact = bar_period()
    ours = Outcome(seconds, f"period error {abs(reading.elapsed / exact - 1):.1g}, joints "
                            f"{_joint_gap(model, result.states):.1g} m, energy ±"
                            f"{_energy_drift(model, result.states):.2g} J")
    outcomes = []
    for integrator in ("RK4", "Euler"):
        mj_seconds, drift, angles = _mujoco_bar(bar_mjcf(integrator=integrator), steps)
        times = _crossings(np.array(angles), 1e-3)
        period = float(np.mean(np.diff(times))) if len(times) > 1 else float("nan")
        outcomes.append((integrator, Outcome(mj_seconds, f"period error {abs(period / exact - 1):.1g}, joints exact, "
                                                         f"energy ±{drift:.2g} J")))
    return f"one hinged bar, {steps} steps of 1 ms (verlet; MuJoCo RK4)", ours, outcomes[0][1], outcomes


def _mujoco_bar(xml: str, steps: int) -> tuple[float, float, list[float]]:
    """The bar in MuJoCo released 60° off the vertical: wall time, energy change [J], the angle after each step."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)

    def start() -> None:
        mujoco.mj_resetData(model, data)
        data.qpos[0] = np.radians(AMPLITUDE)
        mujoco.mj_forward(model, data)

    def bare() -> None:
        start()
        for _ in range(steps):
            mujoco.mj_step(model, data)

    seconds, _ = _timed(bare)
    start()
    first = float(data.energy.sum())
    largest, angles = 0.0, []
    for _ in range(steps):
        mujoco.mj_step(model, data)
        largest = max(largest, abs(float(data.energy.sum()) - first))
        angles.append(float(data.qpos[0]))
    return seconds, largest, angles


# ------------------------------------------------------------------------------------------ the double pendulum

DOUBLE_PENDULUM = """
duration: {duration}
fps: 30
solver: {{method: DOP853, rtol: 1.0e-8, atol: 1.0e-10}}
anchors: [{{name: pivot, position: [0, 2, 0]}}]
bodies:
  - {{name: upper, mass: 1.0, radius: 0.07, position: [1.0, 2.0, 0]}}
  - {{name: lower, mass: 0.5, radius: 0.06, position: [1.0, 1.2, 0]}}
joints:
  - {{type: distance, between: [pivot, upper]}}
  - {{type: distance, between: [upper, lower]}}
fields: [{{type: gravity}}]
"""


def double_pendulum_mjcf(dt: float = 1e-3, integrator: str = "RK4") -> str:
    """Point masses (a sphere of 1 mm carries the mass) on massless rods, hinged about y; the upper rod starts
    horizontal (+x) and the lower one hangs from it, as in the scene."""
    point = 'type="sphere" size="0.001" contype="0" conaffinity="0"'
    return (f'<mujoco><option timestep="{dt}" integrator="{integrator}"><flag energy="enable"/></option><worldbody>'
            '<body><joint type="hinge" axis="0 1 0"/>'
            f'<geom {point} pos="1 0 0" mass="1.0"/>'
            '<body pos="1 0 0"><joint type="hinge" axis="0 1 0"/>'
            f'<geom {point} pos="0 0 -0.8" mass="0.5"/></body></body></worldbody></mujoco>')


def case_double_pendulum(quick: bool) -> tuple[str, Outcome, Outcome, list[tuple[str, Outcome]]]:
    duration = 3.0 if quick else 10.0
    seconds, result, model, _ = _run(DOUBLE_PENDULUM.format(duration=duration))
    ours = Outcome(seconds, f"rods {_joint_gap(model, result.states):.1g} m, energy ±"
                            f"{_energy_drift(model, result.states):.2g} J")
    steps = int(round(duration / 1e-3))
    mj_seconds, drift, _ = _mujoco_run(double_pendulum_mjcf(), steps)
    theirs = Outcome(mj_seconds, f"rods exact, energy ±{drift:.2g} J")
    return f"double pendulum, {duration:g} s (DOP853 rtol 1e-8; MuJoCo RK4 at 1 ms)", ours, theirs, [("RK4", theirs)]


# ------------------------------------------------------------------------------------------ a pile of boxes

PILE_COUNT, PILE_SIDE, PILE_DENSITY = 12, 0.2, 500.0


def _pile_place(i: int) -> tuple[float, float, float, float]:
    """Box i's centre (x, height, depth) [m] and turn about the vertical [deg]: a loose stack, each 5 cm above the
    last, shifted and turned a little so that they land corner first."""
    return 0.03 * (i % 3 - 1), 0.15 + 0.25 * i, 0.02 * (i % 2), 7.0 * i


def pile_scene(duration: float = 3.0, dt: float = 1e-3) -> str:
    """A dozen 20 cm boxes dropped in a loose stack on the ground, symplectic Euler."""
    lines = [f"duration: {duration}", "fps: 30", f"solver: {{method: symplectic_euler, dt: {dt}}}", "bodies:"]
    for i in range(PILE_COUNT):
        x, height, depth, turn = _pile_place(i)
        lines.append(f"  - {{name: box{i}, type: rigid, shape: {{type: box, size: [{PILE_SIDE}, {PILE_SIDE}, "
                     f"{PILE_SIDE}]}}, density: {PILE_DENSITY}, position: [{x}, {height}, {depth}], "
                     f"orientation: {{axis: [0, 1, 0], angle: {turn}}}}}")
    lines += ["colliders: [{type: plane}]", "fields: [{type: gravity}]"]
    return "\n".join(lines) + "\n"


def pile_mjcf(dt: float = 1e-3) -> str:
    """The same pile in MJCF (z up: our (x, y, z) is MuJoCo's (x, −z, y)), free boxes on a plane, semi-implicit
    Euler."""
    half = PILE_SIDE / 2
    boxes = "".join(f'<body pos="{x} {-depth} {height}" euler="0 0 {turn}"><freejoint/><geom type="box" '
                    f'size="{half} {half} {half}" density="{PILE_DENSITY}"/></body>'
                    for x, height, depth, turn in map(_pile_place, range(PILE_COUNT)))
    return (f'<mujoco><option timestep="{dt}" integrator="Euler"><flag energy="enable"/></option><worldbody>'
            f'<geom type="plane" size="5 5 0.1"/>{boxes}</worldbody></mujoco>')


def _rest_and_depth(model: Any, states: np.ndarray, half: float) -> tuple[float, float]:
    """The kinetic energy [J] in the last frame, and the deepest any box corner went below the ground [m] (frames)."""
    from animbatch.sim.model.dynamics import Dynamics

    dynamics = Dynamics(model)
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float) * half
    deepest = 0.0
    for t, y in zip(model.frame_times, states):
        state = dynamics.kinematics(*dynamics.split(np.array(y, float)), t=float(t))
        corners = state.x[:, None, :] + np.einsum("bij,kj->bki", state.rotation, signs)
        deepest = max(deepest, -float(corners[..., 1].min()))
    state = dynamics.kinematics(*dynamics.split(np.array(states[-1], float)), t=float(model.frame_times[-1]))
    kinetic = 0.5 * float(np.sum(model.bodies.mass[:, None] * state.v ** 2))
    return kinetic, deepest


def case_pile(quick: bool) -> tuple[str, Outcome, Outcome, list[tuple[str, Outcome]]]:
    duration = 1.5 if quick else 3.0
    seconds, result, model, _ = _run(pile_scene(duration=duration), repeats=1)
    kinetic, deepest = _rest_and_depth(model, result.states, PILE_SIDE / 2)
    solves = result.stats.contact_solves
    ours = Outcome(seconds, f"deepest corner {deepest * 1e3:.2g} mm into the ground, kinetic energy at the end "
                            f"{kinetic:.2g} J; {solves.unconverged} of {solves.solves} contact solves stopped short "
                            f"(stalled, or at {model.contact_settings.iterations} iterations; off by ≤ "
                            f"{solves.residual:.2g} m/s)")
    steps = int(round(duration / 1e-3))
    mj_seconds, _, depths = _mujoco_run(pile_mjcf(), steps, record=lambda m, d: (
        -min([float(d.contact[k].dist) for k in range(d.ncon)] + [0.0]), float(d.energy[1])))
    theirs = Outcome(mj_seconds, f"deepest contact {max(p for p, _ in depths) * 1e3:.2g} mm, kinetic energy at the end "
                                 f"{depths[-1][1]:.2g} J")
    return (f"{PILE_COUNT} boxes dropped on the ground, {duration:g} s at 1 ms (symplectic Euler)", ours, theirs,
            [("Euler", theirs)])


def _bundled_pile(name: str, quick: bool) -> tuple[str, Outcome, Outcome, list[tuple[str, Outcome]]]:
    """scenes/NAME.yaml as it is (symplectic Euler at 1 ms), step for step against MuJoCo's pile above: the target
    is per step, ≤ 20× MuJoCo's."""
    from pathlib import Path

    path = Path(__file__).parent.parent / "scenes" / f"{name}.yaml"
    duration = 1.0 if quick else 3.0
    text = re.sub(r"^duration: .*$", f"duration: {duration}", path.read_text(), flags=re.M)
    seconds, result, model, _ = _run(text, repeats=1, path=path)
    steps = int(round(duration / 1e-3))
    solves = result.stats.contact_solves
    ours = Outcome(seconds, f"{seconds / steps * 1e3:.2f} ms a step; {model.body_count} bodies; "
                            f"{solves.unconverged} of {solves.solves} contact solves stopped short")
    mj_seconds, _, _ = _mujoco_run(pile_mjcf(), steps)
    theirs = Outcome(mj_seconds, f"its {PILE_COUNT}-box pile, {mj_seconds / steps * 1e6:.0f} µs a step")
    return (f"scenes/{name}.yaml, {duration:g} s at 1 ms, step for step against MuJoCo's {PILE_COUNT}-box pile", ours,
            theirs, [("Euler", theirs)])


def case_mixed_pile(quick: bool) -> tuple[str, Outcome, Outcome, list[tuple[str, Outcome]]]:
    return _bundled_pile("mixed_pile", quick)


def case_dominoes(quick: bool) -> tuple[str, Outcome, Outcome, list[tuple[str, Outcome]]]:
    return _bundled_pile("dominoes", quick)


# ------------------------------------------------------------------------------------------ a ragdoll


def case_ragdoll(quick: bool) -> tuple[str, Outcome, Outcome, list[tuple[str, Outcome]]]:
    """scenes/ragdoll_stairs.yaml as it is, and the same eleven bodies, ten joints and five steps in MJCF."""
    from pathlib import Path

    duration = 1.0 if quick else 4.0
    text = (Path(__file__).parent.parent / "scenes" / "ragdoll_stairs.yaml").read_text()
    text = re.sub(r"^duration: .*$", f"duration: {duration}", text, flags=re.M)
    seconds, result, model, _ = _run(text, repeats=1)
    solves = result.stats.contact_solves
    ours = Outcome(seconds, f"joints {_joint_gap(model, result.states):.1g} m; {solves.unconverged} of {solves.solves} "
                            f"contact solves stopped short (stalled, or at {model.contact_settings.iterations} "
                            f"iterations; off by ≤ {solves.residual:.2g} m/s)")
    steps = int(round(duration / 1e-3))
    mj_seconds, _, _ = _mujoco_run(ragdoll_mjcf(), steps)
    theirs = Outcome(mj_seconds, "joints exact (generalized coordinates)")
    return f"ragdoll down the stairs, {duration:g} s at 1 ms (symplectic Euler)", ours, theirs, [("Euler", theirs)]


def ragdoll_mjcf(dt: float = 1e-3) -> str:
    """scenes/ragdoll_stairs.yaml in MJCF, z up (our (x, y, z) is MuJoCo's (x, −z, y)): the torso free, the rest
    hung from it by ball joints and limited hinges, capsules upright, the stairs as boxes; the torso starts with the
    scene's velocity and spin."""
    def at(x: float, y: float, z: float) -> str:
        return f"{x:.4f} {-z:.4f} {y:.4f}"

    def capsule(radius: float, length: float) -> str:
        return f'<geom type="capsule" size="{radius} {length / 2}" density="1000" friction="0.8"/>'

    def limb(name: str, centre: tuple[float, float, float], anchor: tuple[float, float, float], joint: str,
             shape: str, child: str = "") -> str:
        local = tuple(a - c for a, c in zip(anchor, centre))
        return f'<body name="{name}" pos="{at(*centre)}">{joint.format(at(*local))}{shape}{child}</body>'

    ball = '<joint type="ball" pos="{}"/>'
    elbow = '<joint type="hinge" axis="0 -1 0" limited="true" range="-0.05 2.4" pos="{}"/>'
    knee = '<joint type="hinge" axis="0 -1 0" limited="true" range="-2.4 0.05" pos="{}"/>'
    torso = (-0.3, 1.83, 0.0)

    def rel(point: tuple[float, float, float], parent: tuple[float, float, float]) -> tuple[float, float, float]:
        return (point[0] - parent[0], point[1] - parent[1], point[2] - parent[2])

    def side(z: float) -> str:
        arm, forearm = (-0.3, 1.85, z), (-0.3, 1.57, z)
        lower = limb("forearm", rel(forearm, arm), rel((-0.3, 1.705, z), arm), elbow, capsule(0.03, 0.26))
        return limb("arm", rel(arm, torso), rel((-0.3, 1.99, z), torso), ball, capsule(0.035, 0.28), lower)

    pelvis = (-0.3, 1.585, 0.0)

    def leg(z: float) -> str:
        thigh, shin = (-0.3, 1.39, z), (-0.3, 1.125, z)
        lower = limb("shin", rel(shin, thigh), rel((-0.3, 1.255, z), thigh), knee, capsule(0.04, 0.25))
        return limb("thigh", rel(thigh, pelvis), rel((-0.3, 1.5225, z), pelvis), ball, capsule(0.045, 0.27), lower)

    body = (f'<body name="torso" pos="{at(*torso)}"><freejoint/>'
            f'<geom type="box" size="0.08 0.15 0.17" density="1000" friction="0.8"/>'
            + limb("head", rel((-0.3, 2.1, 0), torso), rel((-0.3, 2.01, 0), torso), ball,
                   '<geom type="sphere" size="0.08" density="1000" friction="0.8"/>')
            + side(0.2) + side(-0.2)
            + limb("pelvis", rel(pelvis, torso), rel((-0.3, 1.6475, 0), torso), ball,
                   '<geom type="box" size="0.07 0.12 0.05" density="1000" friction="0.8"/>', leg(0.07) + leg(-0.07))
            + "</body>")
    body = re.sub(r'name="(forearm|arm|thigh|shin)"', "", body)  # names need not be unique: leave them out
    stairs = "".join(f'<geom type="box" pos="{at(x, h / 2, 0)}" size="{w / 2} 0.7 {h / 2}" friction="0.8"/>'
                     for x, w, h in ((-0.4, 0.8, 1.0), (0.175, 0.35, 0.8), (0.525, 0.35, 0.6),
                                     (0.875, 0.35, 0.4), (1.225, 0.35, 0.2)))
    return (f'<mujoco><option timestep="{dt}" integrator="Euler"/><worldbody><geom type="plane" size="5 5 0.1"/>'
            f"{stairs}{body}</worldbody><keyframe><key qvel=\"1.4 0 0 0 1.2 0{' 0' * 22}\"/></keyframe></mujoco>")


CASES = (case_chain, case_chain_euler, case_bar, case_double_pendulum, case_pile, case_mixed_pile, case_dominoes,
         case_ragdoll)


def _rotation(quaternion: np.ndarray) -> Any:
    from scipy.spatial.transform import Rotation

    w, x, y, z = quaternion
    return Rotation.from_quat([x, y, z, w])


def relative_angles(orientations: np.ndarray, parents: list[int | None]) -> np.ndarray:
    """Each body's turn [rad] relative to its parent since the start, (F, B): the angle of R_rel(0)ᵀ R_rel(t) with
    R_rel = R_parentᵀ R_body (the world for a parent of None), from quaternions [w, x, y, z] (F, B, 4). It does not
    depend on the world's axes, so MuJoCo's z-up bodies and an imported scene's y-up ones compare directly."""
    frames, count = orientations.shape[:2]
    angles = np.zeros((frames, count))
    for b, parent in enumerate(parents):
        def relative(k: int, b: int = b, parent: int | None = parent) -> Any:
            own = _rotation(orientations[k, b])
            return own if parent is None else _rotation(orientations[k, parent]).inv() * own

        start = relative(0)
        angles[:, b] = [(start.inv() * relative(k)).magnitude() for k in range(frames)]
    return angles


def imported_angles(path: Any, seconds: float = 1.0, fps: int = 50) -> tuple[np.ndarray, np.ndarray]:
    """The MJCF file at ``path`` imported by ``animbatch import`` and simulated by animbatch (DOP853 at rtol
    1e-10), and simulated by MuJoCo from the file itself (RK4 at 0.1 ms, its contacts off: the imported scene has
    colliders only where the file has world geoms), for ``seconds``: each body's angle relative to its parent at
    the frame times (ours, MuJoCo's), (F, B) each."""
    import mujoco

    from animbatch import api
    from animbatch.scene.mjcf import import_mjcf

    scene = api.parse_scene(import_mjcf(path).text, filename="imported.yaml", overrides=[
        f"duration={seconds}", f"fps={fps}", "solver.method=DOP853", "solver.rtol=1e-10", "solver.atol=1e-12"])
    trajectory = api.simulate(scene)
    model = mujoco.MjModel.from_xml_path(str(path))
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    model.opt.timestep = 1e-4
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    data = mujoco.MjData(model)
    theirs = []
    for t in trajectory.times:
        while data.time < t - 1e-9:
            mujoco.mj_step(model, data)
        mujoco.mj_kinematics(model, data)
        theirs.append(data.xquat.copy())
    # the import keeps MuJoCo's body order (depth first; MuJoCo's body 0 is the world), names or none
    assert model.nbody - 1 == len(trajectory.body_names), "every body of the file was imported"
    ids = list(range(1, model.nbody))
    parents: list[int | None] = [None if model.body_parentid[body] == 0 else int(model.body_parentid[body]) - 1
                                 for body in ids]
    return relative_angles(trajectory.orientations, parents), relative_angles(np.array(theirs)[:, ids], parents)


def bench_imports(quick: bool) -> list[Row]:
    """MJCF models imported and simulated by both: the largest joint-angle difference over 1 s [rad]."""
    import tempfile
    from pathlib import Path

    repo = Path(__file__).resolve().parent.parent
    rows: list[Row] = []
    with tempfile.TemporaryDirectory() as folder:
        chain = Path(folder) / "chain.xml"
        chain.write_text(chain_mjcf(count=5 if quick else 20).replace('contype="0" conaffinity="0"', ""))
        for label, path in (("20-bar chain", chain), ("scenes/models/figure.xml", repo / "scenes" / "models" /
                                                       "figure.xml")):
            ours, theirs = imported_angles(path)
            gap = float(np.abs(ours - theirs).max())
            print(f"  imported {label}: largest joint-angle difference from MuJoCo over 1 s {gap:.2e} rad "
                  f"(the joints turned up to {theirs.max():.2f} rad)")
            rows.append({"benchmark": "peers", "case": f"MJCF import, {label}: largest angle difference over 1 s",
                         "value": gap, "unit": "rad"})
    return rows


def bench_peers(quick: bool) -> list[Row]:
    """Every case, printed as a table of both sides, and returned as rows for the benchmark table."""
    try:
        import mujoco  # noqa: F401
    except ImportError:
        print("peers: skipped, MuJoCo is not installed (pip install 'animbatch[bench]', or "
              "bash scripts/dev.sh bench installs it)")
        return []
    rows: list[Row] = []
    table = []
    for case in CASES:
        label, ours, anchor, theirs = case(quick)
        table.append((label, ours, anchor, theirs))
        rows.append({"benchmark": "peers", "case": f"{label}: animbatch", "value": ours.seconds, "unit": "s"})
        for integrator, outcome in theirs:
            rows.append({"benchmark": "peers", "case": f"{label}: MuJoCo {integrator}", "value": outcome.seconds,
                         "unit": "s"})
        rows.append({"benchmark": "peers", "case": f"{label}: ratio", "value": ours.seconds / anchor.seconds,
                     "unit": "× MuJoCo"})
    print("\nanimbatch next to MuJoCo (same process, same numbers)")
    for label, ours, anchor, theirs in table:
        print(f"\n  {label}")
        print(f"    animbatch        {ours.seconds:8.3f} s   {ours.accuracy}")
        for integrator, outcome in theirs:
            print(f"    MuJoCo {integrator:<9} {outcome.seconds:8.3f} s   {outcome.accuracy}")
        print(f"    ratio            {ours.seconds / anchor.seconds:8.1f} ×")
    print("\nMJCF models imported by animbatch, simulated by both from the same file")
    rows += bench_imports(quick)
    return rows
