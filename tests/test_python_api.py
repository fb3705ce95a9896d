"""The entry points from Python (``animbatch.load``, ``.render``, ``.simulate``, ``.study``) and scene changes by the
same key paths as ``--set``: a changed value reaches the physics, a bad one is refused as a file's would be."""

from __future__ import annotations

import base64
import re

import imageio.v3 as iio
import matplotlib
import numpy as np
import pytest

import animbatch
from animbatch import api
from animbatch.errors import SceneError
from animbatch.scene.overrides import as_overrides
from animbatch.trajectory import Trajectory

G = 9.81
THROW = """
name: throw
duration: 1.0
fps: 20
solver: {method: DOP853, rtol: 1.0e-10, atol: 1.0e-12}
bodies:
  - {name: ball, mass: 0.5, radius: 0.05, position: [0, 0, 0], velocity: [3, 4, 0]}
fields:
  - {type: gravity, g: [0, -9.81, 0]}
render: {resolution: [160, 96]}
"""


def throw(tmp_path):
    path = tmp_path / "throw.yaml"
    path.write_text(THROW)
    return path


def test_the_top_level_entry_points_are_functions_even_after_their_namesake_subpackages_are_imported():
    import animbatch.render.camera  # noqa: F401 (the drawing subpackage of the same name)
    import animbatch.study.report  # noqa: F401

    assert animbatch.render is api.render and animbatch.study is api.study
    assert animbatch.load is api.load and animbatch.simulate is api.simulate
    from animbatch.render.camera import place_camera  # the subpackages are still importable by name

    assert callable(place_camera)


def test_a_changed_velocity_and_gravity_reach_the_physics_and_leave_the_scene_they_came_from_as_it_was(tmp_path):
    """x = vx t, y = vy t − g t²/2 with the values set from Python, not the file's."""
    original = animbatch.load(throw(tmp_path))
    changed = original.changed({"bodies[ball].velocity": np.array([1.0, 6.0, 0.0]), "fields[0].g": (0, -3.7, 0)})
    assert original.spec.bodies[0].velocity == [3, 4, 0]  # unchanged: changed() returns a new scene
    trajectory = animbatch.simulate(changed)
    t = trajectory.times
    x, y = trajectory.positions[:, 0, 0], trajectory.positions[:, 0, 1]
    np.testing.assert_allclose(x, 1.0 * t, atol=1e-9)
    np.testing.assert_allclose(y, 6.0 * t - 3.7 * t**2 / 2, atol=1e-9)
    # simulate(path, set=...) is the same change
    again = animbatch.simulate(throw(tmp_path), set={"bodies[ball].velocity": [1, 6, 0], "fields[0].g": [0, -3.7, 0]})
    np.testing.assert_allclose(again.positions, trajectory.positions, atol=1e-12)


def test_changes_stack_and_override_texts_work_as_on_the_command_line(tmp_path):
    scene = animbatch.load(throw(tmp_path), set=["bodies[ball].mass=2"]).changed(["duration=0.5"])
    scene = scene.changed({"solver.method": "RK45"})
    assert (scene.spec.bodies[0].mass, scene.spec.duration, scene.spec.solver.method) == (2, 0.5, "RK45")


def test_python_values_are_read_back_as_the_same_values():
    """Text stays text (``"yes"`` is not a boolean, ``"1e-3"`` not a number, a newline stays one); numpy values
    become plain numbers; None clears a value."""
    for value in ("yes", "1e-3", "a\nb", "x: y", 'quote " and \\ backslash', 2.5, np.float64(0.25), True, None,
                  [640, 360], {"a": [1, 2]}, float("inf")):
        (text, _label), = as_overrides({"key": value})
        assert text.startswith("key=")
        read = _yaml_value(text.removeprefix("key="))  # as the scene reader reads an override's value
        if isinstance(value, np.floating):
            value = float(value)
        assert read == value and type(read) is type(value), (value, text)


def _yaml_value(text):
    from animbatch.scene.yaml_source import load_yaml

    return load_yaml(text, "value")[0]


def test_a_bad_change_names_the_key_says_it_came_from_python_and_suggests_the_fix(tmp_path):
    scene = animbatch.load(throw(tmp_path))
    with pytest.raises(SceneError) as caught:
        scene.changed({"bodies[ball].mas": 2, "solver.method": "RK4S"})
    message = str(caught.value)
    assert "bodies[ball].mas = 2 (set from Python)" in message and "did you mean 'mass'" in message
    assert "solver.method = \"RK4S\" (set from Python)" in message and "did you mean 'RK45'" in message
    with pytest.raises(SceneError, match="no item named 'bal'"):
        scene.changed({"bodies[bal].mass": 2})


@pytest.mark.render
def test_render_from_python_returns_a_run_whose_display_holds_its_video_ledger_and_plot(tmp_path):
    report = animbatch.render(throw(tmp_path), quality="draft", resolution=(128, 72), formats="webm",
                              set={"duration": 0.5}, out_dir=tmp_path / "out", progress=False)
    video = tmp_path / "out" / "throw" / "throw.webm"
    assert report.outputs == [str(video)]
    frames = iio.imread(video, index=None)
    assert frames.shape[:3] == (10, 72, 128)  # 0.5 s at 20 fps
    page = report._repr_html_()
    embedded = re.search(r'<video[^>]* src="data:video/webm;base64,([^"]+)"', page)
    assert embedded is not None and base64.b64decode(embedded.group(1)) == video.read_bytes()
    assert 'src="data:image/png;base64,' in page  # the energy plot: on by default from Python
    # the ledger: the method, energy conserved (gravity alone) with its drift as a share of its scale, as the
    # energy plot says it; momentum not, and why
    assert "<th>method</th><td colspan=2>DOP853 (adaptive)" in page
    assert re.search(r"<th>energy</th><td>conserved: all forces derive from potentials: gravity</td><td>drift "
                     r"[0-9.e+-]+ % of [0-9.]+ J</td>", page)
    assert "<th>momentum</th><td>not conserved: gravity is an external force</td>" in page
    assert report.summary().split(" | ")[0].replace(">", "&gt;") in page  # the run's line under it
    from IPython.lib.pretty import pretty

    assert pretty(report) == report.summary()


@pytest.mark.render
@pytest.mark.slow
def test_a_scene_with_no_file_renders_in_worker_processes_from_a_trajectory_given_in_memory(tmp_path):
    """--jobs from Python: the workers rebuild the scene from its text and read the trajectory from a temporary
    file, removed afterwards; the video has every frame, and the ball is where the closed form puts it."""
    scene = api.parse_scene(THROW.replace("duration: 1.0", "duration: 2.4"), filename="<text>")
    trajectory = animbatch.simulate(scene)
    report = animbatch.render(scene, trajectory, jobs=2, out_dir=tmp_path, progress=False, formats="mp4")
    assert report.workers == 2 and report.frames_drawn == 48
    assert iio.imread(tmp_path / "throw" / "throw.mp4", index=None).shape[0] == 48
    assert not list((tmp_path / "throw").glob(".trajectory-*"))  # the workers' copy is gone
    t, final = trajectory.times[-1], trajectory.positions[-1, 0]
    np.testing.assert_allclose(final[:2], [3 * t, 4 * t - G * t**2 / 2], atol=1e-8)


def test_a_trajectory_shows_its_ledger(tmp_path):
    trajectory = animbatch.simulate(throw(tmp_path))
    assert isinstance(trajectory, Trajectory)
    page = trajectory._repr_html_()
    assert "throw: 20 frames, 0–0.95 s, 1 body" in page
    assert "<th>method</th><td colspan=2>DOP853 (adaptive)" in page
    from IPython.lib.pretty import pretty  # what IPython's terminal prints: the heading, not every array

    assert pretty(trajectory) == "Trajectory(throw: 20 frames, 0–0.95 s, 1 body)"


def test_a_study_from_python_shows_its_work_precision_plot_and_table_and_leaves_the_plotting_backend_alone(tmp_path):
    matplotlib.use("svg")  # as a notebook or script may have chosen; drawing the plots must not switch it
    try:
        report = animbatch.study(throw(tmp_path), methods=["RK45", "euler"], out_dir=tmp_path / "study",
                                 set={"study.repeats": 1, "study.closed_form": True})
        assert matplotlib.get_backend() == "svg"
    finally:
        matplotlib.use("agg")
    page = report._repr_html_()
    plot = re.search(r'src="data:image/png;base64,([^"]+)"', page)
    assert plot is not None and base64.b64decode(plot.group(1)) == (tmp_path / "study" / "study.png").read_bytes()
    # Euler's error falls as its step does (order 1), which the table reports
    euler = next(merit for merit in report.result.merits if merit.method == "euler")
    assert euler.order == pytest.approx(1.0, abs=0.1)
    assert "euler" in page and "RK45" in page
