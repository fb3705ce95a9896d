"""animbatch in Jupyter: the example notebooks in docs/notebooks/ run from top to bottom (nbclient) and their outputs
hold the videos, the ledgers, the plots and the closed-form checks; the ``%%animbatch`` cell magic renders the scene
written in a cell, with ``animbatch render``'s options; progress bars become notebook widgets in a kernel."""

from __future__ import annotations

import base64
import importlib.util
import re
import types

import imageio.v3 as iio
import pytest

from animbatch.progress import Progress
from support.paths import REPO

NOTEBOOKS = REPO / "docs" / "notebooks"
CELL = """name: hop
duration: 0.5
fps: 20
bodies:
  - {name: ball, mass: 1, radius: 0.1, position: [0, 0, 0], velocity: [1, 3, 0]}
fields: [{type: gravity}]
render: {resolution: [128, 72]}
"""


def _executor():
    """scripts/notebooks.py, which also writes the committed outputs."""
    spec = importlib.util.spec_from_file_location("notebook_runner", REPO / "scripts" / "notebooks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _run_notebook(name, tmp_path):
    """Run docs/notebooks/NAME.ipynb in a copy of its folder (its renders stay out of the repository); the scenes
    are where the notebook expects them, two folders up."""
    folder = tmp_path / "docs" / "notebooks"
    folder.mkdir(parents=True)
    (tmp_path / "scenes").symlink_to(REPO / "scenes")
    notebook = _executor().execute(NOTEBOOKS / f"{name}.ipynb", workdir=folder)
    return [cell for cell in notebook.cells if cell.cell_type == "code"]


def _html(cell):
    return "".join(output.get("data", {}).get("text/html", "") for output in cell.outputs)


def _text(cell):
    return "".join(output.get("text", "") for output in cell.outputs if output.output_type == "stream")


def _video_frames(page, tmp_path, name):
    """The frames of the video embedded in ``page``."""
    found = re.search(r'<video[^>]* src="data:video/(mp4|webm);base64,([^"]+)"', page)
    assert found is not None, "no embedded video"
    path = tmp_path / f"{name}.{found.group(1)}"
    path.write_bytes(base64.b64decode(found.group(2)))
    return iio.imread(path, index=None)


@pytest.mark.render
@pytest.mark.slow
def test_the_teaching_notebook_runs_and_shows_the_throw_its_closed_form_the_drag_and_the_study(tmp_path):
    cells = _run_notebook("teaching", tmp_path)
    vacuum, check, dragged, compare, study = (cells[index] for index in (0, 1, 2, 3, 4))
    # the throw: its video (1.45 s at 30 fps), its ledger and its energy plot
    assert _video_frames(_html(vacuum), tmp_path, "vacuum").shape[:3] == (44, 270, 480)
    assert "<th>energy</th><td>conserved: all forces derive from potentials: gravity</td>" in _html(vacuum)
    assert _html(vacuum).count('src="data:image/png;base64,') == 1
    # against the closed-form parabola, and the apex v0y²/2g above the start
    miss = float(re.search(r"parabola over 1.43 s: ([0-9.e+-]+) m", _text(check)).group(1))
    assert miss < 1e-9
    apex = re.search(r"apex: ([0-9.]+) m in vacuum \(closed form ([0-9.]+) m\), ([0-9.]+) m with drag", _text(compare))
    assert apex is not None and apex.group(1) == apex.group(2) == f"{0.11 + 7.0**2 / (2 * 9.81):.3f}"
    assert float(apex.group(3)) < float(apex.group(1))  # drag takes energy: the ball rises less high
    assert "<th>energy</th><td>not conserved: drag dissipates it</td>" in _html(dragged)
    assert any("image/png" in output.get("data", {}) for output in compare.outputs)  # the two paths, inline
    # the study: its work-precision plot and table, Euler's order 1
    assert "what accuracy costs in time" in _html(study) and 'src="data:image/png;base64,' in _html(study)
    order = re.search(r"\neuler +.* ([0-9.]+) +0\s*</pre>", _html(study))  # the last row: euler's order, 0 failed
    assert order is not None and abs(float(order.group(1)) - 1) < 0.1


@pytest.mark.render
@pytest.mark.slow
def test_the_animation_notebook_renders_a_cloth_and_a_burst_of_sparks_from_cells(tmp_path):
    cells = _run_notebook("animation", tmp_path)
    napkin, burst, grinder = (cell for cell in cells if "text/html" in str(cell.outputs))
    frames = _video_frames(_html(napkin), tmp_path, "napkin")
    assert frames.shape[:3] == (40, 270, 480)  # 1.6 s at 25 fps
    # 4 backward-Euler steps between each of the 40 frames
    assert f"<th>work (bodies)</th><td colspan=2>{39 * 4} steps, {39 * 4} right-hand sides" in _html(napkin)
    assert "napkin: 40 frames" in _text(napkin)  # the magic prints the run's summary line too
    sparks = _video_frames(_html(burst), tmp_path, "burst")
    assert sparks.shape[0] == 45
    # before the burst (t = 0.2 s) the night sky is dark; after it, bright sparks fill it
    sky = (slice(30, 110), slice(0, 480))  # below the time label
    assert sparks[2][sky].max() < 80 and (sparks[8][sky].max(axis=-1) > 200).sum() > 200
    assert "1500 born" in _text(burst)
    assert "<th>work (particles)</th>" in _html(burst) and "<th>energy</th>" not in _html(burst)
    assert _video_frames(_html(grinder), tmp_path, "grinder").shape[0] == 30  # duration set to 1 s from Python


@pytest.fixture
def shell():
    """An IPython shell in this process with ``%load_ext animbatch`` done."""
    from IPython.core.interactiveshell import InteractiveShell

    ipython = InteractiveShell.instance()
    ipython.run_line_magic("load_ext", "animbatch")
    yield ipython
    InteractiveShell.clear_instance()


@pytest.mark.render
def test_the_cell_magic_renders_the_cell_with_the_command_line_options(shell, tmp_path, capsys):
    report = shell.run_cell_magic("animbatch", f"--formats webm --set duration=0.3 --out {tmp_path}", CELL)
    assert report.outputs == [str(tmp_path / "hop" / "hop.webm")]
    assert iio.imread(report.outputs[0], index=None).shape[:3] == (6, 72, 128)  # 0.3 s at 20 fps
    assert report.scene_file is None  # the scene came from the cell
    assert "hop: 6 frames" in capsys.readouterr().out
    assert "<video" in report._repr_html_()


def test_a_cell_that_does_not_validate_shows_its_errors_by_line_and_column_without_a_traceback(shell):
    result = shell.run_cell("%%animbatch\n" + CELL.replace("mass: 1", "mas: 1"))
    assert not result.success
    error = result.error_in_exec
    assert error is not None and type(error).__name__ == "CellError"
    shown = "\n".join(error._render_traceback_())  # what IPython prints instead of the traceback
    assert "<cell>:5:18:" in shown and "did you mean 'mass'" in shown and "Traceback" not in shown


def test_a_bad_option_on_the_magic_line_is_named_with_the_options_it_may_have_meant(shell):
    result = shell.run_cell("%%animbatch --qualty draft\n" + CELL)
    assert not result.success
    assert "No such option '--qualty'" in str(result.error_in_exec) and "--quality" in str(result.error_in_exec)


def test_progress_bars_are_notebook_widgets_in_a_kernel_and_text_on_a_terminal(monkeypatch):
    assert not Progress().notebook  # here: no kernel
    import IPython
    import tqdm.notebook

    kernel_shell = types.SimpleNamespace(kernel=object())
    monkeypatch.setattr(IPython, "get_ipython", lambda: kernel_shell)
    created = []

    class Recorded(tqdm.notebook.tqdm):
        def __init__(self, *arguments, **options):
            super().__init__(*arguments, **options)
            created.append(self)

    monkeypatch.setattr(tqdm.notebook, "tqdm", Recorded)
    progress = Progress()  # stderr is no terminal here, but a kernel shows the bar
    assert progress.notebook and progress.enabled
    with progress.task("render", 5) as on_frame:
        for index in range(5):
            on_frame(index, index / 30)
        assert created and created[0].n == 5 and created[0].total == 5
