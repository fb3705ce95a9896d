"""Kinematic mode (solver.method: analytic): bodies move by closed forms with no integration, match an integrated
run to its error, and anything without a closed form is refused by name; two renders side by side."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import api
from animbatch.errors import SceneError
from support.paths import REPO
from support.scenes import body, run, scene


def test_a_projectile_moves_exactly_by_its_closed_form():
    _, trajectory = run("""
        duration: 1.3
        fps: 20
        solver: {method: analytic}
        bodies: [{name: ball, position: [1, 2, 3], velocity: [3, 7, -1]}]
        fields: [{type: gravity, g: [0, -9.81, 0]}]
    """)
    t = trajectory.times[:, None]
    x, v = body(trajectory, "ball")
    np.testing.assert_allclose(x, [1, 2, 3] + np.array([3, 7, -1]) * t + 0.5 * np.array([0, -9.81, 0]) * t**2,
                               atol=1e-13)
    np.testing.assert_allclose(v, np.array([3, 7, -1]) + np.array([0, -9.81, 0]) * t, atol=1e-13)
    assert trajectory.solver_stats["rhs_evaluations"] == 0 and trajectory.solver_stats["steps"] == 0


def test_the_bundled_kinematics_scene_matches_a_tight_integrated_run_of_the_same_scene():
    """Projectile, linear drag with gravity and a damped spring: analytic against DOP853 at rtol 1e-11."""
    path = REPO / "scenes" / "kinematics.yaml"
    analytic = api.simulate(api.load_scene(path))
    integrated = api.simulate(api.load_scene(path, ["solver.method=DOP853", "solver.rtol=1e-11",
                                                    "solver.atol=1e-13"]))
    np.testing.assert_allclose(analytic.positions, integrated.positions, atol=1e-8)
    np.testing.assert_allclose(analytic.velocities, integrated.velocities, atol=1e-7)


@pytest.mark.parametrize("text, fragment", [
    ("bodies: [{name: feather}]\nfields: [{type: drag, model: quadratic, coefficient: 0.1}]",
     "body 'feather' has no closed form: it feels quadratic drag"),
    ("bodies: [{name: box, type: rigid, shape: {type: box, size: [1, 1, 1]}, density: 1}]", "body 'box'"),
    ("bodies: [{name: a}]\nclocks: {c: 1}", "clocks"),
    ("bodies: [{name: a}]\nfields: [{type: wind, velocity: [1, 0, 0], model: linear, coefficient: 0.1}, "
     "{type: force, force: [1, 0, 0]}]", "it feels force"),
])
def test_anything_without_a_closed_form_is_refused_naming_it(text, fragment):
    with pytest.raises(SceneError) as error:
        scene("duration: 1\nsolver: {method: analytic}\n" + text)
    message = str(error.value)
    assert fragment in message and "solver.method" in message and "choose a method that integrates" in message


def test_emitters_are_refused_under_the_analytic_method():
    with pytest.raises(SceneError, match="emitted particles are integrated step by step"):
        scene("duration: 1\nsolver: {method: analytic}\nemitters: [{name: spray, rate: 10}]")


@pytest.mark.slow
@pytest.mark.render
def test_two_renders_composed_side_by_side_keep_frames_size_and_fps(tmp_path):
    import imageio_ffmpeg

    from animbatch.encode.compose import side_by_side

    videos = []
    for method in ("analytic", "DOP853"):
        report = api.run(REPO / "scenes" / "kinematics.yaml", out_dir=tmp_path / method, jobs=1,
                         overrides=[f"solver.method={method}", "render.resolution=[160, 120]", "duration=0.5",
                                    "render.ground=null", "render.background=white", "render.show_time=false",
                                    "render.trails=null", "bodies[ball].radius=0.3"])
        videos.append(report.outputs[0])
    out = side_by_side([videos[0], videos[1]], tmp_path / "both.mp4", gap=4)
    reader = imageio_ffmpeg.read_frames(str(out))
    meta = next(reader)
    assert tuple(meta["size"]) == (324, 120) and meta["fps"] == 30
    frames = [np.frombuffer(f, np.uint8).reshape(120, 324, 3).astype(int) for f in reader]
    assert len(frames) == 15
    last = frames[-1]
    red = (last[..., 0] > 150) & (last[..., 1] < 110)  # the tomato ball in each half
    left, right = np.nonzero(red[:, :160]), np.nonzero(red[:, 164:])
    assert len(left[0]) > 5 and len(right[0]) > 5
    assert abs(left[0].mean() - right[0].mean()) < 1.5 and abs(left[1].mean() - right[1].mean()) < 1.5
