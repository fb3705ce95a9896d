"""Trajectory files: readable with numpy alone, round-trip, written atomically, refused for another scene."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from animbatch import api
from animbatch.cli import cli
from animbatch.errors import TrajectoryError
from animbatch.trajectory import Trajectory
from support.scenes import run, scene

SCENE = """
    name: throw
    duration: 1
    fps: 10
    anchors: [{name: pin, position: [0, 3, 0]}]
    bodies: [{name: ball, velocity: [1, 4, 0]}, {name: bob, position: [0, 2, 0]}]
    springs: [{between: [pin, bob], stiffness: 5}]
    fields: [{type: gravity}]
"""


def test_trajectory_file_is_plain_numpy(tmp_path):
    """np.load without pickles gives times, named bodies' positions/velocities, hash, version and solver stats."""
    _, trajectory = run(SCENE)
    path = trajectory.save(tmp_path / "run.npz")
    with np.load(path, allow_pickle=False) as data:
        assert str(data["format"]) == "animbatch-trajectory" and int(data["format_version"]) == 3
        assert np.array_equal(data["times"], np.arange(10) / 10)
        names = list(data["body_names"])
        assert names == ["ball", "bob"]
        ball = data["positions"][:, names.index("ball")]
        t = data["times"]
        assert np.allclose(ball[:, 1], 4 * t - 0.5 * 9.81 * t**2, atol=1e-6)
        assert data["velocities"].shape == (10, 2, 3)
        assert list(data["anchor_names"]) == ["pin"]
        assert len(str(data["physics_hash"])) == 64
        stats = json.loads(str(data["solver_stats"]))
        assert stats["method"] == "RK45" and stats["rhs_evaluations"] > 0 and stats["steps"] > 0
        assert json.loads(str(data["solver"]))["rtol"] == 1e-6


def test_round_trip(tmp_path):
    """Saving and loading keeps every array and field."""
    _, trajectory = run(SCENE)
    loaded = Trajectory.load(trajectory.save(tmp_path / "run"))
    assert loaded.body_names == trajectory.body_names and loaded.anchor_names == ("pin",)
    assert np.array_equal(loaded.positions, trajectory.positions)
    assert np.array_equal(loaded.velocities, trajectory.velocities)
    assert loaded.physics_hash == trajectory.physics_hash and loaded.solver_stats == trajectory.solver_stats


def test_interrupted_save_leaves_nothing(tmp_path, monkeypatch):
    """A failure while writing leaves neither the target nor a temporary file."""
    _, trajectory = run(SCENE)

    def broken(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(np, "savez", broken)
    with pytest.raises(KeyboardInterrupt):
        trajectory.save(tmp_path / "run.npz")
    assert list(tmp_path.iterdir()) == []


def test_physics_hash_ignores_presentation_but_not_physics():
    """Camera, colours, solver and name do not change the hash; a mass or fps does."""
    base = api.physics_fingerprint(scene(SCENE).spec)
    assert api.physics_fingerprint(scene(SCENE, "render.resolution=[320, 240]", "bodies[ball].color=red",
                                         "solver.method=verlet", "name=other").spec) == base
    assert api.physics_fingerprint(scene(SCENE, "bodies[ball].mass=2").spec) != base
    assert api.physics_fingerprint(scene(SCENE, "fps=20").spec) != base


def test_trajectory_from_other_physics_is_refused(tmp_path):
    """Rendering a trajectory simulated from different physics fails with the command that fixes it."""
    loaded = scene(SCENE)
    _, trajectory = run(SCENE, "bodies[ball].mass=2")
    with pytest.raises(TrajectoryError, match="simulated from different physics.*Re-run 'animbatch simulate"):
        api.check_trajectory(loaded, api.compile_model(loaded), trajectory, "run.npz")


def test_not_a_trajectory(tmp_path):
    """Files that are not trajectories are refused with a reason."""
    bogus = tmp_path / "x.npz"
    np.savez(bogus, times=np.zeros(3))
    with pytest.raises(TrajectoryError, match="not an animbatch trajectory"):
        Trajectory.load(bogus)
    (tmp_path / "y.npz").write_text("garbage")
    with pytest.raises(TrajectoryError, match="not a readable"):
        Trajectory.load(tmp_path / "y.npz")
    with pytest.raises(TrajectoryError, match="no such trajectory file"):
        Trajectory.load(tmp_path / "missing.npz")


def test_simulate_command_writes_the_trajectory(tmp_path):
    """'animbatch simulate scene -o run.npz' writes a loadable file and prints solver work."""
    path = tmp_path / "throw.yaml"
    path.write_text(SCENE)
    result = CliRunner().invoke(cli, ["simulate", str(path), "-o", str(tmp_path / "run.npz"), "--method", "DOP853"])
    assert result.exit_code == 0, result.output
    assert "throw: 10 frames" in result.output and "DOP853" in result.output
    assert Trajectory.load(tmp_path / "run.npz").solver_stats["method"] == "DOP853"


RIGID = """
    name: spin
    duration: 1
    fps: 10
    bodies:
      - {name: dot, velocity: [1, 0, 0]}
      - {name: brick, type: rigid, shape: {type: box, size: [1, 2, 3]}, mass: 2, angular_velocity: [0.2, 1, 0.1]}
"""


def test_rigid_trajectory_round_trip_and_states(tmp_path):
    """Orientations and angular velocities are saved, and rebuild the exact states (particles first)."""
    model, trajectory = run(RIGID)
    loaded = Trajectory.load(trajectory.save(tmp_path / "spin.npz"))
    assert loaded.body_names == ("dot", "brick") and loaded.body_kinds == ("particle", "rigid")
    assert np.array_equal(loaded.orientations, trajectory.orientations)
    assert np.allclose(loaded.orientations[:, 0], [1, 0, 0, 0])  # particles: identity
    states = model.states_from(loaded.positions, loaded.velocities, loaded.orientations, loaded.angular_velocities)
    assert np.allclose(model.positions(states), loaded.positions)
    assert np.allclose(model.angular_velocities(states), loaded.angular_velocities)
    assert np.allclose(states[0], model.y0)
