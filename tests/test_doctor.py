"""animbatch doctor: what this machine can do, checked for real (a test frame judged by its pixels, test encodes), and
the exact command for each thing missing."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from animbatch import doctor
from animbatch.cli import cli
from animbatch.render import backend as backends


@pytest.mark.slow
def test_doctor_draws_a_test_frame_with_each_available_backend_and_encodes_each_format():
    """On this machine (EGL and/or OSMesa, the ffmpeg of imageio-ffmpeg): every backend whose libraries load draws
    the test ball (checked by its pixels) with a first-frame and a per-frame time; mp4, webm and gif encode; exit 0."""
    result = CliRunner().invoke(cli, ["doctor", "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.output)
    assert report["can_render"] and report["probed"]
    available = [check for check in report["backends"] if backends.is_available(backends.BACKENDS[check["name"]])]
    assert available, "this machine renders the test suite, so a backend must be available"
    for check in available:
        assert check["ok"], check
        first, steady = (float(part.split()[0]) for part in check["detail"].split("first ")[1].split(", then "))
        assert first > 0 and steady > 0
    video = {check["name"]: check for check in report["video"]}
    assert all(video[kind]["ok"] for kind in ("ffmpeg", "mp4", "webm", "gif")), video


@pytest.mark.slow
def test_a_backend_without_its_library_is_reported_with_the_command_that_installs_it(monkeypatch):
    """OSMesa's library 'missing': its line says which library cannot be loaded, and the fixes list the apt-get
    command; EGL is still checked and usable."""
    real = backends.library_loads
    monkeypatch.setattr(backends, "library_loads", lambda name: "OSMesa" not in name and real(name))
    report = doctor.diagnose(probe=False, encode=False)
    osmesa = next(check for check in report.backends if check.name == "osmesa")
    assert not osmesa.ok and "libOSMesa.so.8 or libOSMesa.so.6 or libOSMesa.so cannot be loaded" in osmesa.detail
    text = doctor.format_report(report)
    assert "osmesa: apt-get install libosmesa6" in text


@pytest.mark.slow
def test_no_backend_at_all_exits_1_and_says_what_to_install(monkeypatch):
    """With no off-screen OpenGL library, doctor exits 1, names both backends' packages and says it cannot render."""
    monkeypatch.setattr(backends, "library_loads", lambda name: False)
    result = CliRunner().invoke(cli, ["doctor"])
    assert result.exit_code == 1
    assert "Cannot render: no off-screen OpenGL library found" in result.output
    assert "egl: apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri" in result.output
    assert "osmesa: apt-get install libosmesa6" in result.output


def import_without(monkeypatch, missing: str) -> None:
    """Make doctor's imports of ``missing`` fail as an uninstalled library's would."""
    real_import = doctor.importlib.import_module

    def imported(name, *args):
        if name == missing:
            raise ImportError(f"No module named '{missing}'")
        return real_import(name, *args)

    monkeypatch.setattr(doctor.importlib, "import_module", imported)


def test_a_missing_python_library_and_a_missing_encoder_are_named_with_their_fix(monkeypatch):
    """A library that fails to import is marked missing with the set-up command; an ffmpeg without the MP4
    encoder makes the machine unable to render videos, and the fix says how to get an ffmpeg that has it."""
    import_without(monkeypatch, "trimesh")
    monkeypatch.setitem(doctor.ENCODERS, "mp4", "libx264-that-is-not-there")
    report = doctor.diagnose(probe=False, encode=False)
    trimesh = next(check for check in report.libraries if check.name == "trimesh")
    assert not trimesh.ok and trimesh.required and "bash scripts/dev.sh setup" in trimesh.fix
    mp4 = next(check for check in report.video if check.name == "mp4")
    assert not mp4.ok and "no libx264-that-is-not-there encoder" in mp4.detail
    assert not report.can_render
    assert "!! trimesh" in doctor.format_report(report)


def test_a_blank_test_frame_is_not_taken_for_a_drawn_one(tmp_path):
    """The probe's frame counts as drawn only when the red test ball is on it: a white frame (a backend that
    renders nothing) has no ball pixels, a frame with a red disc has them."""
    blank = np.full((240, 320, 3), 255, np.uint8)
    Image.fromarray(blank).save(tmp_path / "blank.png")
    assert doctor.ball_pixels(tmp_path / "blank.png") == 0
    y, x = np.mgrid[:240, :320]
    drawn = blank.copy()
    drawn[(x - 160) ** 2 + (y - 120) ** 2 < 30 ** 2] = (200, 30, 30)
    Image.fromarray(drawn).save(tmp_path / "drawn.png")
    assert doctor.ball_pixels(tmp_path / "drawn.png") > 2000


def test_the_optional_parts_are_checked_too_each_with_its_fix(monkeypatch):
    """numba (the compiled kernels), usd-core (the default export format) and the browser the report page's test
    uses are listed; missing, each is marked optional with the command that installs it (issue 40: none was
    checked), and the machine can still render."""
    import_without(monkeypatch, "pxr")
    monkeypatch.setattr(doctor, "BROWSERS", ("no-such-browser-for-animbatch",))
    report = doctor.diagnose(probe=False, encode=False)
    checks = {check.name: check for check in report.libraries}
    assert checks["numba"].ok and not checks["numba"].required
    usd, browser = checks["usd-core"], checks["chromium"]
    assert not usd.ok and not usd.required and usd.fix.endswith("-m pip install usd-core")
    assert not browser.ok and not browser.required and "apt-get install chromium" in browser.fix
    text = doctor.format_report(report)
    assert "usd-core" in text and "chromium" in text
