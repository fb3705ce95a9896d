"""Bad input never gets a traceback, a hang or unbounded memory: regression tests for each defect the fuzzer and
hand-made hostile files found, the YAML limits, the number range, file paths, and the cost pre-flight and budget."""

from __future__ import annotations

import math
import os
import time

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner

from animbatch import api, stages
from animbatch.cli import cli
from animbatch.compile.model import compile_scene
from animbatch.compile.particles import pool_sizes
from animbatch.errors import SceneError, SimulationError
from animbatch.scene.yaml_source import MAX_DEPTH, MAX_DOCUMENT_BYTES, MAX_NODES
from animbatch.sim.integrators.budget import wall_budget
from animbatch.sim.integrators.cost import PARTICLE_STEP_SECONDS, CostEstimate, check_cost, estimate_cost
from animbatch.sim.particles.simulate import steps_per_frame
from animbatch.stages import load_scene, parse_scene
from support.paths import REPO
from support.scenes import scene

GOOD = "bodies: [{name: ball, mass: 1.0, position: [0, 1, 0]}]\nfields: [{type: gravity}]\n"


def refusal(text: str, *overrides: str) -> SceneError:
    """The SceneError that ``text`` gets, checked to point at a line and column; and how long it took."""
    with pytest.raises(SceneError) as caught:
        parse_scene(text, filename="hostile.yaml", overrides=list(overrides))
    for issue in caught.value.issues:
        assert issue.source.startswith(("hostile.yaml:", "--set")) or "the file is" in issue.message, issue
    return caught.value


def timed_refusal(text: str, limit: float = 1.0) -> str:
    start = time.perf_counter()
    message = str(refusal(text))
    elapsed = time.perf_counter() - start
    assert elapsed < limit, f"took {elapsed:.2f} s to refuse"
    return message


# ---------------------------------------------------------------------------------------------------------------
# YAML limits


def test_a_document_nested_thousands_deep_is_refused_without_recursion_error():
    for text in ("bodies: " + "[" * 5000 + "]" * 5000,
                 "bodies: " + "{a: " * 5000 + "1" + "}" * 5000,
                 "".join(" " * i + f"k{i}:\n" for i in range(3000))):
        message = timed_refusal(text)
        assert f"more than {MAX_DEPTH} levels" in message or "maximum nesting depth" in message


def test_an_alias_bomb_is_refused_in_milliseconds_naming_the_limit():
    """The 'billion laughs': nine levels of nine aliases each expand to 9⁹ ≈ 4·10⁸ nodes."""
    lines = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    lines += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]" for i in range(1, 10)]
    message = timed_refusal("\n".join(lines) + "\n", limit=0.2)
    assert f"more than {MAX_NODES:,} nodes (MAX_NODES)" in message and "hostile.yaml:" in message


def test_aliases_that_nest_deeper_than_the_limit_are_refused():
    """Depth through aliases counts too: each alias wraps the previous one in one more list, and merge keys chain."""
    chain = "a0: &a0 [1]\n" + "".join(f"a{i}: &a{i} [*a{i - 1}]\n" for i in range(1, 200))
    assert f"more than {MAX_DEPTH} levels" in timed_refusal(chain)
    merges = "a0: &a0 {x: 1}\n" + "".join(f"a{i}: &a{i} {{<<: *a{i - 1}, y{i}: 1}}\n" for i in range(1, 200))
    assert f"more than {MAX_DEPTH} levels" in timed_refusal(merges)


def test_a_self_referencing_alias_is_refused():
    assert "repeat forever" in timed_refusal("bodies: &b [*b]\n")


def test_an_oversized_file_is_refused_before_parsing():
    text = GOOD + "#" * (MAX_DOCUMENT_BYTES + 1)
    message = timed_refusal(text, limit=0.5)
    assert "MAX_DOCUMENT_BYTES" in message and "MiB" in message


def test_ordinary_aliases_and_merge_keys_still_work():
    from animbatch.scene.yaml_source import load_yaml

    data, _ = load_yaml("d: &x {m: 2, r: 0.1}\nb: [{<<: *x, n: a}, {<<: *x, n: b, m: 3}, *x]\n", "x.yaml")
    assert data["b"] == [{"m": 2, "r": 0.1, "n": "a"}, {"m": 3, "r": 0.1, "n": "b"}, {"m": 2, "r": 0.1}]


# ---------------------------------------------------------------------------------------------------------------
# Numbers and names


@pytest.mark.parametrize("value, word", [("1e300", "too large"), ("-1e300", "too large"), ("1e-300", "too small"),
                                         ("9" * 5000, "5000 digits")])
def test_absurd_numbers_are_refused_with_the_physical_range(value, word):
    message = str(refusal(GOOD.replace("position: [0, 1, 0]", f"position: [0, {value}, 0]")))
    assert word in message and "between 1e-35 and 1e+35" in message and "bodies[0].position[1]" in message
    message = str(refusal(GOOD, f"bodies[ball].mass={value}"))
    assert word in message


def test_a_list_or_mapping_where_a_body_name_belongs_is_a_located_error_not_a_traceback():
    """Found by the fuzzer: 'unhashable type' in the cross-reference checks."""
    for wrong in ("[ball]", "{a: ball}"):
        message = str(refusal(GOOD.replace("[{type: gravity}]", f"[{{type: drag, model: linear, coefficient: 0.1, "
                                                                f"bodies: [{wrong}]}}]")))
        assert "fields[0].bodies[0]" in message


def test_a_negative_emitter_rate_is_refused():
    """Found by the fuzzer: a negative rate passed validation and crashed the particle simulation."""
    message = str(refusal("emitters: [{name: e, rate: -5}]\n"))
    assert "emitters[0].rate: must be >= 0 1/s (got -5)" in message
    assert "must be a list" not in message  # the member of 'number | keyframes' it was not meant for is not blamed


@pytest.mark.parametrize("name", ["../../escape", "/etc/passwd", "a/b", "..", "con\\x", "ü"])
def test_scene_names_cannot_leave_the_output_folder(name):
    assert "hostile.yaml:1:7: name: names start with a letter or '_'" in str(refusal(f"name: {name!r}\n" + GOOD))


def test_huge_but_valid_coordinates_do_not_overflow_contact_detection():
    """Found by the fuzzer: a KD-tree query overflowed on huge coordinates. At the edge of the range, contacts work."""
    loaded = scene("""
        duration: 0.1
        bodies:
          - {name: a, mass: 1, radius: 1.0e+30, position: [1.0e+34, 0, 0], velocity: [1.0e+30, 0, 0]}
          - {name: b, mass: 1, radius: 1.0e+30, position: [-1.0e+34, 0, 0]}
        contacts: {}
        solver: {method: symplectic_euler, dt: 0.01}
        """)
    trajectory = api.simulate(loaded)
    assert np.isfinite(trajectory.positions).all()


# ---------------------------------------------------------------------------------------------------------------
# Files


def test_mesh_files_are_read_only_from_the_scene_folder(tmp_path):
    folder = tmp_path / "scene"
    (folder / "meshes").mkdir(parents=True)
    trimesh.creation.box((1.0, 1.0, 1.0)).export(folder / "meshes" / "box.stl")
    trimesh.creation.box((1.0, 1.0, 1.0)).export(tmp_path / "outside.stl")
    os.symlink(tmp_path / "outside.stl", folder / "link.stl")
    body = "bodies: [{{name: b, type: rigid, density: 1, shape: {{type: mesh, file: {!r}}}}}]\n"
    (folder / "ok.yaml").write_text(body.format("meshes/box.stl"))
    assert load_scene(folder / "ok.yaml").spec.bodies[0].shape.file == "meshes/box.stl"
    for file, word in [("/etc/shadow", "absolute"), ("../outside.stl", "outside the scene's folder"),
                       ("meshes/../../outside.stl", "outside the scene's folder"),
                       ("link.stl", "outside the scene's folder")]:
        (folder / "bad.yaml").write_text(body.format(file))
        with pytest.raises(SceneError) as caught:
            load_scene(folder / "bad.yaml")
        assert word in str(caught.value) and "bodies[0].shape.file" in str(caught.value), file


# ---------------------------------------------------------------------------------------------------------------
# Cost pre-flight and budget


STIFF = """
    duration: 1
    solver: {method: RK45, max_cost: 60}
    bodies: [{name: bob, mass: 0.001, position: [0, -1, 0], velocity: [0, -0.1, 0]}]
    anchors: [{name: top, position: [0, 0, 0]}]
    springs: [{name: wire, between: [top, bob], stiffness: 1.0e+12, rest_length: 1}]
    fields: [{type: gravity}]
    """


def test_an_explicit_method_on_a_very_stiff_spring_is_refused_before_it_starts_naming_the_spring_and_override():
    loaded = scene(STIFF)
    start = time.perf_counter()
    with pytest.raises(SimulationError) as caught:
        api.simulate(loaded)
    assert time.perf_counter() - start < 2.0
    message = str(caught.value)
    assert "refused before it starts" in message and "stability of the stiffest spring" in message
    assert "'bob'" in message and "--max-cost" in message and "solver.max_cost" in message
    assert "Radau or BDF" in message  # the fix that avoids the cost, not only the override


def test_the_explicit_step_estimate_is_the_stability_limit():
    """RK45 is stable for |hλ| ≤ 3.3; with ω = sqrt(k/m) = 3.16e7 rad/s over 1 s that is ~1e7 steps."""
    loaded = scene(STIFF)
    model = compile_scene(loaded.spec)
    estimate = estimate_cost(model, loaded.spec.solver, rhs_seconds=1e-5)
    integration = next(term for term in estimate.terms if term.name == "integration")
    steps = integration.seconds / 1e-5 / 6  # 6 right-hand sides per RK45 step
    span = model.frame_times[-1] - model.frame_times[0]
    assert steps == pytest.approx(np.sqrt(1e12 / 1e-3) * span / 3.3, rel=1e-6)


def test_the_fixed_step_estimate_counts_the_steps_exactly():
    loaded = scene(GOOD, "solver.method=verlet", "solver.dt=1e-4", "duration=2")
    model = compile_scene(loaded.spec)
    estimate = estimate_cost(model, loaded.spec.solver, rhs_seconds=1.0)
    frames = len(model.frame_times)
    assert estimate.seconds == pytest.approx((frames - 1) * math.ceil(1 / 30 / 1e-4) * 1.0)  # dt divides 1/fps


def test_the_adaptive_estimate_is_within_an_order_of_magnitude_of_the_steps_taken():
    loaded = scene("""
        duration: 6
        solver: {method: DOP853, rtol: 1.0e-10, atol: 1.0e-12}
        bodies:
          - {name: star, mass: 3.0, position: [-0.25, 0, 0], velocity: [0, -0.4, 0]}
          - {name: planet, mass: 1.0, position: [0.75, 0, 0], velocity: [0, 1.2, 0]}
        fields: [{type: gravitation, G: 1.0}]
        """)
    model = compile_scene(loaded.spec)
    estimate = estimate_cost(model, loaded.spec.solver, rhs_seconds=1.0)
    predicted = estimate.seconds / 12  # DOP853: 12 right-hand sides per step
    taken = api.simulate(loaded).solver_stats["steps"]
    assert taken / 10 < predicted < taken * 10


def test_a_fast_spin_counts_in_the_adaptive_estimate_as_its_quaternion_turning_at_half_the_rate():
    """A top spinning at 400 rad/s (a ball joint at its tip): its quaternion's components are sinusoids at 200 rad/s,
    which DOP853 must follow. Without that term the estimate saw one step per frame, 16 times too few (and left the
    run to numpy's slower equations); with it, the estimate is within a few times of the steps taken, never below."""
    loaded = api.load_scene(REPO / "scenes" / "spinning_top.yaml", ["duration=1"])
    model = compile_scene(loaded.spec)
    estimate = estimate_cost(model, loaded.spec.solver, rhs_seconds=1.0)
    integration = next(term for term in estimate.terms if term.name == "integration")
    assert "spin of 'top'" in integration.detail and "200 rad/s" in integration.detail
    predicted = integration.seconds / 12  # DOP853: 12 right-hand sides per step
    taken = api.simulate(loaded).solver_stats["steps"]
    assert taken < predicted < taken * 5


@pytest.mark.parametrize("method, per_frame", [("verlet", math.ceil(1 / 30 / 1e-3)), ("RK45", 1)])
def test_emitted_particles_are_estimated_at_the_steps_they_take(method, per_frame):
    """Fixed-step methods advance particles in steps of at most dt that divide the frame interval; adaptive ones
    integrate each frame interval as one segment. Everything born lives all run: alive = births = 30 × 2 s."""
    loaded = scene(f"""
        duration: 2
        solver: {{method: {method}, dt: 1.0e-3}}
        emitters: [{{name: jet, rate: 30, lifetime: 5}}]
        """)
    model = compile_scene(loaded.spec)
    steps = steps_per_frame(1 / 30, method, 1e-3) * (len(model.frame_times) - 1)
    assert steps == per_frame * 59
    estimate = estimate_cost(model, loaded.spec.solver, pool_sizes(loaded.spec), steps, rhs_seconds=0.0)
    emitter = next(term for term in estimate.terms if term.name == "emitter 'jet'")
    births = pool_sizes(loaded.spec)[0][2]
    assert births == pytest.approx(60, abs=1)
    assert emitter.seconds == pytest.approx(births * steps * PARTICLE_STEP_SECONDS)


def test_a_raised_budget_lets_the_run_through_the_pre_flight():
    loaded = scene(GOOD, "solver.method=euler", "solver.dt=1e-7", "duration=0.5")
    model = compile_scene(loaded.spec)
    estimate = estimate_cost(model, loaded.spec.solver, rhs_seconds=1e-5)
    with pytest.raises(SimulationError, match="per frame"):
        check_cost(estimate, max_cost=1.0)
    check_cost(estimate, max_cost=estimate.seconds * 1.5)
    check_cost(estimate, max_cost=0)  # 0 = no limit


def test_emitters_beyond_memory_are_refused_naming_the_emitter():
    loaded = scene("""
        duration: 10
        emitters: [{name: storm, rate: 4.0e+6, lifetime: 10}]
        """)
    model = compile_scene(loaded.spec)
    sizes = pool_sizes(loaded.spec)
    assert sizes[0][1] >= 4e7 * 0.99  # everything born stays alive for the whole run
    estimate = estimate_cost(model, loaded.spec.solver, sizes, rhs_seconds=1e-6)
    with pytest.raises(SimulationError) as caught:
        check_cost(estimate, max_cost=0, memory=16 * 2**30)
    assert "memory" in str(caught.value) and "emitter 'storm'" in str(caught.value)


@pytest.mark.parametrize("overrides", [
    ("solver.method=verlet", "solver.dt=1e-7"),  # fixed-step loop
    ("solver.method=RK45", "solver.rtol=1e-12", "solver.atol=1e-14", "solver.max_step=1e-6"),  # adaptive loop
])
def test_a_run_that_exceeds_its_budget_stops_early_saying_how_far_it_got(monkeypatch, overrides):
    """What the pre-flight cannot foresee is caught while running: here the estimate is disabled."""
    monkeypatch.setattr(stages, "estimate_cost", lambda *args, **kwargs: CostEstimate())
    loaded = scene(GOOD, *overrides, "duration=5", "solver.max_cost=0.5")
    start = time.perf_counter()
    with pytest.raises(SimulationError) as caught:
        api.simulate(loaded)
    assert time.perf_counter() - start < 3.0
    message = str(caught.value)
    assert "used up its wall-time budget of 0.5 s" in message and "% of the way" in message
    assert "--max-cost" in message


@pytest.mark.slow
def test_emitted_particles_stop_at_the_budget_too(monkeypatch):
    monkeypatch.setattr(stages, "estimate_cost", lambda *args, **kwargs: CostEstimate())
    loaded = scene("""
        duration: 20
        solver: {method: symplectic_euler, dt: 1.0e-5, max_cost: 0.5}
        emitters: [{name: jet, rate: 20000, lifetime: 20}]
        fields: [{type: gravity}]
        """)
    with pytest.raises(SimulationError, match="emitted particles' simulation used up its wall-time budget"):
        api.simulate(loaded)


def test_the_budget_is_per_context_and_off_by_default():
    from animbatch.sim.integrators.budget import budget_spent

    assert budget_spent(1.0) is None
    with wall_budget(1e-9, 0.0, 1.0):
        time.sleep(0.001)
        assert "used up" in budget_spent(0.5)
    assert budget_spent(1.0) is None
    with wall_budget(0, 0.0, 1.0):  # 0 = no limit
        time.sleep(0.001)
        assert budget_spent(0.5) is None


def test_max_cost_on_the_command_line_takes_units(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(STIFF.replace("\n    ", "\n"))
    runner = CliRunner()
    result = runner.invoke(cli, ["simulate", str(path), "--max-cost", "0.5min", "-o", str(tmp_path / "t.npz")])
    assert result.exit_code == 3 and "budget of 30 s" in result.output, result.output
    result = runner.invoke(cli, ["simulate", str(path), "--max-cost", "soon"])
    assert result.exit_code == 1 and "solver.max_cost" in result.output


@pytest.mark.slow
@pytest.mark.parametrize("method", ["symplectic_euler", "RK45"])  # fixed-step resolver and impact events
def test_a_feather_light_ball_in_a_break_stops_with_a_named_divergence_not_a_kd_tree_overflow(method):
    """Found by the long fuzz run: ball4 at 1e-9 kg among 0.17 kg balls is kicked past 1e100 m/s and the contact
    search overflowed (ValueError from cKDTree). The run now stops, naming the body: under RK45 where it leaves
    every physical scale (the check sits in the contact search the methods share), or before it starts when the
    estimate of RK45's steps for its drag exceeds the budget; under a fixed step before it starts, since the
    table's drag on 1e-9 kg relaxes its velocity in 2e-8 s, far below the step."""
    loaded = load_scene(REPO / "scenes" / "billiard_break.yaml",
                        overrides=["duration=0.2", "bodies[ball4].mass=1e-9", f"solver.method={method}"])
    with pytest.raises(SimulationError) as caught:
        api.simulate(loaded)
    message = str(caught.value)
    if method == "symplectic_euler":
        assert "cannot hold the linear drag on 'ball4'" in message and "Nothing was simulated." in message
    else:  # RK45's steps for that drag cost some 30 min: on a loaded machine over the budget, refused at once
        assert ("'ball4' (mass 1e-09 kg) left every physical scale" in message
                or ("refused before it starts" in message and "linear drag on 'ball4'" in message)), message


RESTING_JELLY = """
    duration: 0.2
    solver: {method: backward_euler, dt: 0.0041667, max_cost: 1}
    bodies:
      - name: jelly
        type: lattice
        size: [0.3, 0.3, 0.3]
        resolution: [6, 6, 6]
        position: [0, 0.72, 0]
        orientation: {axis: [1, 0, 1], angle: 35}
        density: 1050
        structural: {stiffness: 6000, damping: 8}
        shear: {stiffness: 3000, damping: 4}
    """


@pytest.mark.slow
def test_backward_euler_step_halving_stops_at_the_budget(monkeypatch):
    """Found by the long fuzz run: a lattice at rest without gravity made the energy guard halve every step ten
    times over (each halving a sparse factorisation; 56 s for 0.03 s). With the guard's rounding floor removed to
    recreate that, the budget stops it within the halvings."""
    from animbatch.sim.integrators import implicit

    monkeypatch.setattr(implicit, "ROUNDING_FLOOR", 0.0)
    start = time.perf_counter()
    with pytest.raises(SimulationError) as caught:
        api.simulate(scene(RESTING_JELLY))
    assert "wall-time budget of 1 s" in str(caught.value) and "halving its steps" in str(caught.value)
    assert time.perf_counter() - start < 8.0


def test_a_resting_lattice_takes_its_steps_whole_and_stays_at_rest():
    """The cause: at rest the springs hold no energy, so the guard's relative tolerance took the rounding of their
    lengths for a rise. Above the floor ε Σ k r² nothing is taken for rounding: the run takes 48 steps (8 per frame,
    none halved), and the block stays where it was (nothing acts on it) to round-off. (Without the scene's 1 s
    budget, which is the halving test's: on a loaded machine the whole run can take longer than that.)"""
    trajectory = api.simulate(scene(RESTING_JELLY, "solver.max_cost=0"))
    stats = trajectory.solver_stats
    assert stats["steps"] == 8 * (len(trajectory.times) - 1)
    assert stats["rhs_evaluations"] <= stats["steps"] + 1  # one per step: a halved step would take two or more
    assert np.max(np.abs(trajectory.positions - trajectory.positions[0])) < 1e-12
    assert np.max(np.abs(trajectory.velocities)) < 1e-10


def test_an_empty_orientation_is_a_located_error():
    """Found by the fuzz test: 'orientation: {}' passed validation and crashed computing the rotation."""
    message = str(refusal("bodies: [{name: b, type: rigid, density: 1, shape: {type: sphere, radius: 1}, "
                          "orientation: {}}]\n"))
    assert "bodies[0].orientation" in message and "got none of them" in message


class FakeClock:
    """time.perf_counter for RenderBudget: ``times`` in order, one per read."""

    def __init__(self, *times: float) -> None:
        self.times = list(times)

    def __call__(self) -> float:
        return self.times.pop(0)


def test_a_render_projected_over_its_budget_stops_after_the_second_frame(monkeypatch):
    """100 frames, the first at 2 s (it also builds the actors), the second 0.5 s later: the rest project to
    2.5 + 0.5 × 98 = 51.5 s. A budget of 10 s stops after frame 2, one of 60 s lets it go on, 0 never stops."""
    from animbatch.errors import RenderError
    from animbatch.farm import frame_files

    monkeypatch.setattr(frame_files.time, "perf_counter", FakeClock(0.0, 2.0, 2.5))
    budget = frame_files.RenderBudget(10.0, 100)
    budget.after_frame(1)
    with pytest.raises(RenderError) as caught:
        budget.after_frame(2)
    message = str(caught.value)
    assert "after 2 of 100 frames" in message and "about 51.5 s at 0.5 s per frame" in message
    assert "render.max_cost" in message and "frames drawn are kept" in message
    for seconds in (60.0, 0.0):
        monkeypatch.setattr(frame_files.time, "perf_counter", FakeClock(0.0, 2.0, 2.5, 3.0))
        budget = frame_files.RenderBudget(seconds, 100)
        budget.after_frame(1)
        budget.after_frame(2)
        budget.after_frame(3)


def test_a_first_frame_longer_than_the_whole_budget_stops_at_once(monkeypatch):
    from animbatch.errors import RenderError
    from animbatch.farm import frame_files

    monkeypatch.setattr(frame_files.time, "perf_counter", FakeClock(0.0, 7.0))
    budget = frame_files.RenderBudget(5.0, 10)
    with pytest.raises(RenderError, match="more than the 7 s the first frame took"):
        budget.after_frame(1)


def test_a_damping_that_swamps_the_masses_names_the_spring_instead_of_a_singular_factor():
    """Found by the long fuzz run: the curtain's damping scaled to 1e35 N·s/m made backward Euler's matrix
    M − h D − h² K singular in rounding (SuperLU's 'Factor is exactly singular' traceback). Now exit 3, naming the
    spring, its numbers and how many times its lighter end's mass it is over one step."""
    loaded = load_scene(REPO / "scenes" / "curtain.yaml",
                        overrides=["duration=0.2", "bodies[curtain].structural.damping=1e35"])
    with pytest.raises(SimulationError) as caught:
        api.simulate(loaded)
    message = str(caught.value)
    assert "spring 'curtain.structural[" in message and "damping 1e+35 N·s/m" in message
    assert "masses vanish in the rounding" in message


def test_an_alias_of_a_mapping_that_overrides_a_merged_key_is_not_a_duplicate():
    """Found in review: PyYAML flattens merge keys in place, so building an aliased mapping a second time took
    its merged keys for its own and reported the override as a duplicate key."""
    from animbatch.scene.yaml_source import load_yaml

    data, source = load_yaml("y: &y {m: 1, r: 2}\na: &x {<<: *y, m: 3}\nb: *x\n", "x.yaml")
    assert data["a"] == data["b"] == {"m": 3, "r": 2}
    assert source.source_of(("b", "m")) == "x.yaml:2:19"  # where the value that counts was written


def test_a_document_is_built_without_recursion():
    """The builder is a loop: 60 levels of nesting (within MAX_DEPTH) build with the recursion limit at 80, which a
    recursive builder (two frames a level) would exceed."""
    import sys

    from animbatch.scene.yaml_source import load_yaml

    text = "a: " + "[" * 60 + "1" + "]" * 60 + "\n"
    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(80)  # pytest's own frames take part of it
    try:
        data, _ = load_yaml(text, "x.yaml")
    finally:
        sys.setrecursionlimit(limit)
    value = data["a"]
    for _ in range(60):
        value = value[0]
    assert value == 1


@pytest.mark.parametrize("method", ["DOP853", "verlet"])
def test_a_start_too_far_for_its_rope_stops_naming_the_body_and_the_joint(method):
    """The fuzzer's rope_swing with the roped ball's z at −9223372036854775808: moving that start onto the rope
    overflows to NaN. It stops before the first step with the body and the joint named (it was scipy's traceback
    under DOP853, and under Verlet a divergence blamed on the step)."""
    loaded = load_scene(REPO / "scenes" / "rope_swing.yaml",
                        [f"solver.method={method}", "bodies[1].position=[1.3, 2, -9223372036854775808]"])
    with pytest.raises(SimulationError, match=r"body 'on_rope', held by joint 'hook_rope--on_rope', starts too far"):
        api.simulate(loaded)
    result = CliRunner().invoke(cli, ["simulate", str(REPO / "scenes" / "rope_swing.yaml"), "-o", os.devnull,
                                      "--set", f"solver.method={method}",
                                      "--set", "bodies[1].position=[1.3, 2, -9223372036854775808]"])
    assert result.exit_code == SimulationError.exit_code and "Traceback" not in result.output
