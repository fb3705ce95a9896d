"""The compiled particle-pool kernel against the numpy code it replaces (same particles, same places to round-off,
same counts), and against closed forms on its own; and when it is chosen."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import api
from animbatch.sim import kernels
from support.scenes import scene

numba = pytest.importorskip("numba", reason="numba is not installed: only the numpy code runs")

G = 9.81

#: Two emitters: a jet (births at every step: the step-by-step path) and a burst at t = 0 (no births after it: whole
#: frames fused into one call), with drag of every law, wind, a floor, a tilted wall, a sphere and a turned box, and
#: lives that end mid-run.
SCENE = """
duration: 0.8
fps: 25
seed: 3
solver: {{method: {method}, dt: 0.004}}
materials: {{rubber: {{restitution: 0.6, static_friction: 0.5, kinetic_friction: 0.3}}}}
emitters:
  - name: jet
    source: {{type: disc, position: [0, 0.3, 0], radius: 0.05, normal: [1, 1, 0]}}
    rate: 900
    lifetime: {{mean: 0.6, spread: 0.2}}
    speed: {{mean: 4, spread: 1}}
    direction: {{axis: [1, 1, 0], cone: 20}}
    radius: {{mean: 0.01, spread: 0.004}}
    collision: {mode}
    material: rubber
  - name: burst
    bursts: [{{time: 0, count: 400}}]
    source: {{type: sphere, position: [0, 1, 0], radius: 0.2}}
    lifetime: {{mean: 0.9, spread: 0.3}}
    speed: {{mean: 2, spread: 1}}
    radius: 0.01
    collision: {mode}
    material: rubber
fields:
  - {{type: gravity}}
  - {{type: drag, model: quadratic, coefficient: 2.0e-5, bodies: [jet]}}
  - {{type: wind, velocity: [-1, 0, 0.5], model: linear, coefficient: 1.0e-3, bodies: [burst]}}
  - {{type: drag, model: stokes, viscosity: 1.8e-4}}
colliders:
  - {{type: plane, material: rubber}}
  - {{type: plane, point: [1.2, 0, 0], normal: [-1, 0.3, 0], material: rubber}}
  - {{type: sphere, position: [0.5, 0.6, 0.1], radius: 0.25, material: rubber}}
  - {{type: box, position: [-0.4, 0.25, 0], size: [0.5, 0.5, 0.8], orientation: {{axis: [0.3, 1, 0.2], angle: 35}},
     material: rubber}}
"""


def simulate(text: str, monkeypatch, choice: str):
    monkeypatch.setenv(kernels.KERNELS_VARIABLE, choice)
    return api.simulate(scene(text))


def by_serial(frames, frame: int) -> tuple[np.ndarray, np.ndarray]:
    """The serials alive at ``frame``, sorted, and their positions in that order."""
    serials = frames.serials[frame]
    alive = np.flatnonzero(serials >= 0)
    order = alive[np.argsort(serials[alive])]
    return serials[order], frames.positions[frame][order].astype(float)


#: Gravity and one drag per emitter (the kernel reads such fields once per call, as scalars: field_summary), wind
#: on one of them.
ONE_DRAG_EACH = """fields:
  - {{type: gravity}}
  - {{type: drag, model: quadratic, coefficient: 2.0e-5, bodies: [jet]}}
  - {{type: wind, velocity: [-1, 0, 0.5], model: linear, coefficient: 1.0e-3, bodies: [burst]}}
colliders:"""


@pytest.mark.slow
@pytest.mark.parametrize(("method", "mode", "fields"), [
    ("verlet", "bounce", "table"), ("verlet", "stick", "table"), ("symplectic_euler", "die", "table"),
    ("euler", "bounce", "table"), ("verlet", "bounce", "one drag each"), ("verlet", "bounce", "planes only")])
def test_the_compiled_pool_moves_the_same_particles_to_the_same_places_as_numpy(monkeypatch, method, mode, fields):
    """Every frame holds the same particles, each within round-off of where the numpy code puts it (positions are
    stored as float32), and births, deaths and collisions are counted alike: every method and every collision mode
    of the kernel, once each at least, with fields the kernel reads from its table (two drags on each emitter) and
    as scalars (one drag each), and colliders that are planes only (the kernel's compilation without spheres and
    boxes)."""
    text = SCENE if fields == "table" else SCENE[:SCENE.index("fields:")] + ONE_DRAG_EACH + SCENE.split("colliders:")[1]
    if fields == "planes only":
        text = text[:text.index("  - {{type: sphere")]
    text = text.format(method=method, mode=mode)
    reference = simulate(text, monkeypatch, "numpy")
    compiled = simulate(text, monkeypatch, "numba")
    assert reference.particle_stats["kernels"] == "numpy" and compiled.particle_stats["kernels"] == "numba"
    for key in ("born", "died", "dropped", "collisions", "steps"):
        assert compiled.particle_stats[key] == reference.particle_stats[key], key
    assert reference.particle_stats["collisions"] > 100  # the planes are met, often
    for ours, theirs in zip(compiled.particles, reference.particles):
        for frame in range(len(ours.positions)):
            serials, positions = by_serial(ours, frame)
            expected_serials, expected = by_serial(theirs, frame)
            np.testing.assert_array_equal(serials, expected_serials)
            np.testing.assert_allclose(positions, expected, rtol=0, atol=2e-6)


def test_compiled_particles_fall_as_the_closed_form_of_quadratic_drag(monkeypatch):
    """Dropped from rest under quadratic drag, a particle falls (v_t² / g) ln cosh(g t / v_t), v_t = √(m g / C): the
    terminal speed it tends to (fused frames: no births after the first instant)."""
    mass, coefficient = 2e-6, 1.2e-7
    trajectory = simulate(f"""
        duration: 3.0
        fps: 10
        solver: {{method: verlet, dt: 0.002}}
        emitters:
          - {{name: drops, bursts: [{{time: 0, count: 50}}], source: {{type: box, position: [0, 100, 0],
              size: [1, 1, 1]}}, speed: 0, lifetime: 10, mass: {mass}, radius: 0.001}}
        fields: [{{type: gravity}}, {{type: drag, model: quadratic, coefficient: {coefficient}}}]
        """, monkeypatch, "numba")
    assert trajectory.particle_stats["kernels"] == "numba"
    fallen = trajectory.particles[0].positions[0, :50, 1].astype(float) - trajectory.particles[0].positions[
        :, :50, 1].astype(float)
    terminal = np.sqrt(mass * G / coefficient)
    expected = terminal**2 / G * np.log(np.cosh(G * trajectory.times / terminal))
    np.testing.assert_allclose(fallen, np.tile(expected[:, None], (1, 50)), rtol=0, atol=2e-5 * expected[-1])
    assert expected[-1] / trajectory.times[-1] > 0.6 * terminal  # far enough to feel the drag


@pytest.mark.slow
def test_the_kernel_is_chosen_only_where_it_applies_and_pays(monkeypatch):
    """auto: numpy for small work, the kernel for large; numba: the kernel whatever the size; numpy: never. A field
    or collider the kernel does not cover keeps the numpy code. A wrong setting is named."""
    small = """
        duration: 0.2
        fps: 10
        solver: {method: verlet, dt: 0.01}
        emitters: [{name: e, rate: 50, lifetime: 1}]
        fields: [{type: gravity}]
        """
    assert simulate(small, monkeypatch, "auto").particle_stats["kernels"] == "numpy"
    assert simulate(small, monkeypatch, "numba").particle_stats["kernels"] == "numba"
    monkeypatch.setattr(kernels, "MIN_WORK", 1.0)
    assert simulate(small, monkeypatch, "auto").particle_stats["kernels"] == "numba"
    assert simulate(small, monkeypatch, "numpy").particle_stats["kernels"] == "numpy"
    meshed = small.rstrip() + "\n        bodies: [{name: b, type: rigid, shape: {type: box, size: [1, 1, 1]}, " \
                              "position: [0, -1, 0], mass: 1}]\n"
    assert simulate(meshed, monkeypatch, "numba").particle_stats["kernels"] == "numpy"  # bodies: traced by numpy
    adaptive = small.replace("{method: verlet, dt: 0.01}", "{method: RK45}")
    assert simulate(adaptive, monkeypatch, "numba").particle_stats["kernels"] == "numpy"
    monkeypatch.setenv(kernels.KERNELS_VARIABLE, "fast")
    with pytest.raises(ValueError, match="ANIMBATCH_KERNELS='fast': choose auto, numba or numpy"):
        kernels.compiled_kernels()


def test_many_steps_of_a_small_pool_repay_the_kernel_as_its_numpy_steps_would_cost(monkeypatch):
    """A burst of 2500 sparks for a second: 10⁵ particle-steps at 10 ms steps, 2.5·10⁶ at 1 ms, both far below
    MIN_WORK, but the numpy code pays about half a millisecond a step whatever the pool's size: 1000 steps cost it
    ~0.8 s (the kernel runs), 100 steps ~0.08 s (numpy runs, loading numba would cost more)."""
    from animbatch.sim.particles.compiled import kernel_work

    burst = """
        duration: 1.0
        fps: 10
        solver: {method: verlet, dt: 0.001}
        emitters: [{name: e, bursts: [{time: 0, count: 2500}], lifetime: 10, speed: 3}]
        fields: [{type: gravity}, {type: drag, model: quadratic, coefficient: 1.0e-5}]
        """
    from animbatch.sim.particles.compiled import numpy_pool_seconds

    assert 2500 * 1000 < kernels.MIN_WORK and kernel_work(2500, 1000, numpy_pool_seconds(2500, 1000)) == \
        kernels.MIN_WORK
    assert kernel_work(2500, 100, numpy_pool_seconds(2500, 100)) == 2500 * 100
    assert simulate(burst, monkeypatch, "auto").particle_stats["kernels"] == "numba"
    coarse = burst.replace("dt: 0.001", "dt: 0.01")
    assert simulate(coarse, monkeypatch, "auto").particle_stats["kernels"] == "numpy"
    # three such emitters at 5 ms steps: 200 steps, 0.15 s each in numpy, 0.46 s together: still numpy; four
    # (0.62 s together) repay numba for all of them, though each alone would not
    several = burst.replace("dt: 0.001", "dt: 0.005").replace(
        "emitters: [{name: e, bursts: [{time: 0, count: 2500}], lifetime: 10, speed: 3}]",
        "emitters: [" + ", ".join(f"{{name: e{k}, bursts: [{{time: 0, count: 2500}}], lifetime: 10, speed: 3}}"
                                  for k in range(4)) + "]")
    assert simulate(several, monkeypatch, "auto").particle_stats["kernels"] == "numba"


@pytest.mark.slow
def test_a_kernel_that_fails_to_build_leaves_the_run_to_numpy_and_says_so(monkeypatch):
    """numba loads but cannot compile (an LLVM or type error): the run goes on with the numpy code, whose results it
    gives, and warns once, naming the emitter and the setting that silences it."""
    from numba.core.errors import TypingError

    from animbatch.sim.kernels import particle_pool

    def broken(*args, **kwargs):
        raise TypingError("no implementation for this machine")

    monkeypatch.setattr(particle_pool, "advance_pool", broken)
    text = SCENE.format(method="verlet", mode="bounce")
    with pytest.warns(RuntimeWarning, match=r"emitter '(jet|burst)' runs the numpy code instead .*ANIMBATCH_KERNELS=numpy"):
        fallen = simulate(text, monkeypatch, "numba")
    reference = simulate(text, monkeypatch, "numpy")
    assert fallen.particle_stats["kernels"] == "numpy"
    np.testing.assert_array_equal(fallen.particles[0].positions, reference.particles[0].positions)


@pytest.mark.slow
def test_the_cost_pre_flight_prices_compiled_pools_at_the_kernel_s_cost(monkeypatch):
    """A pool the kernel will step is estimated at its cost per particle-step, one the numpy code steps at the numpy
    code's (so that a run the kernel makes affordable is not refused before it starts)."""
    from animbatch.compile.model import compile_scene
    from animbatch.compile.particles import compile_particles, particle_costs
    from animbatch.sim.integrators.cost import COMPILED_PARTICLE_STEP_SECONDS, PARTICLE_STEP_SECONDS

    loaded = scene(SCENE.format(method="verlet", mode="bounce"))
    systems = compile_particles(loaded.spec, compile_scene(loaded.spec))
    for choice, expected in (("numba", COMPILED_PARTICLE_STEP_SECONDS), ("numpy", PARTICLE_STEP_SECONDS)):
        monkeypatch.setenv(kernels.KERNELS_VARIABLE, choice)
        costs = particle_costs(loaded.spec, systems, 300)
        assert [name for name, *_ in costs] == ["jet", "burst"]
        assert all(cost == expected for *_, cost in costs), choice
    monkeypatch.setenv(kernels.KERNELS_VARIABLE, "numba")
    rk45 = scene(SCENE.format(method="verlet", mode="bounce"), "solver.method=RK45")
    assert all(cost == PARTICLE_STEP_SECONDS for *_, cost in particle_costs(rk45.spec, systems, 300))


@pytest.mark.slow
def test_a_slow_kernel_build_is_announced_once_and_a_quick_one_never(monkeypatch):
    """A build still running after SLOW_BUILD (numba compiling, the first time on a machine) tells the announce hook
    once, with what is compiling; a build that loads from the cache at once says nothing, nor does any later one."""
    import time

    heard: list[str] = []
    monkeypatch.setattr(kernels, "announce", heard.append)
    monkeypatch.setattr(kernels, "SLOW_BUILD", 0.05)
    monkeypatch.setattr(kernels, "_asked", set())
    assert kernels.watched(lambda: None, "quick") is None
    assert kernels.watched(lambda: time.sleep(0.4), "slow") is None
    assert kernels.watched(lambda: time.sleep(0.4), "slow") is None  # asked before: not announced again
    assert kernels.watched(lambda: "TypingError: no", "broken") == "TypingError: no"  # the failure passes through
    assert heard == ["compiling the slow kernels (once on this machine: they are cached on disk)…"]
    monkeypatch.setattr(kernels, "announce", None)  # library use: nothing to tell, nothing waits
    assert kernels.watched(lambda: None, "other") is None
