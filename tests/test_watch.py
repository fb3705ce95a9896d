"""``animbatch watch``: the live preview, driven as a user would, in a real browser (Debian's Chromium, headless,
through Playwright): the page shows a video, a save swaps in a new one (a save during a render starts it over), an
invalid scene shows its errors with their line while the last video stays, and a fix brings a video back. The
server listens on the loopback address only."""

from __future__ import annotations

import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from animbatch import api
from animbatch.watch import Broadcast, PreviewLoop, make_server

pytestmark = pytest.mark.render

BALL = """name: watched
duration: 1.0
fps: 12
bodies:
  - {{name: ball, radius: 0.2, position: [0, 1, 0], velocity: [1, 3, 0], color: "{color}"}}
fields:
  - {{type: gravity}}
render:
  resolution: [320, 180]
"""
#: Seconds a render of the ball may take before the test gives up (a draft render takes about two here).
PATIENCE = 90_000


def test_the_server_listens_on_the_loopback_address_only():
    server = make_server(Broadcast(), "scene.yaml")
    try:
        host, port = server.server_address[:2]
        assert host == "127.0.0.1" and port > 0
        addresses = {info[4][0] for info in socket.getaddrinfo(socket.gethostname(), None, socket.AF_INET)}
        for address in addresses - {"127.0.0.1"}:  # this machine's other addresses do not answer
            with pytest.raises(OSError):
                socket.create_connection((address, port), timeout=1).close()
    finally:
        server.server_close()


def _watching(folder: Path) -> tuple[Path, subprocess.Popen, list[str]]:
    """``animbatch watch`` of the red ball written to ``folder``, started as a user starts it: the scene, the
    process, and its output lines as they come."""
    scene = folder / "scene.yaml"
    scene.write_text(BALL.format(color="#ff0000"))
    process = subprocess.Popen([sys.executable, "-m", "animbatch", "watch", str(scene), "--seconds", "0.5"],
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=folder)
    lines: list[str] = []
    threading.Thread(target=lambda: lines.extend(iter(process.stdout.readline, "")), daemon=True).start()
    return scene, process, lines


@pytest.mark.slow
def test_a_save_re_renders_an_error_shows_its_line_and_a_fix_brings_the_video_back(browser, tmp_path):
    scene, process, lines = _watching(tmp_path)
    try:
        deadline = time.monotonic() + 60
        while not any("http://127.0.0.1:" in line for line in lines):
            assert time.monotonic() < deadline and process.poll() is None, "".join(lines)
            time.sleep(0.1)
        url = next(line for line in lines if "http://127.0.0.1:" in line).split("open ")[1].split()[0]
        page = browser.new_page()
        page.goto(url)
        page.wait_for_function("document.getElementById('video').src.includes('/video/')", timeout=PATIENCE)
        first = page.eval_on_selector("#video", "video => video.src")
        # the video is served whole: the browser reads its metadata (its duration: 0.5 s of frames)
        page.wait_for_function("document.getElementById('video').readyState >= 1", timeout=PATIENCE)
        assert 0.3 < page.eval_on_selector("#video", "video => video.duration") < 0.8

        scene.write_text(BALL.format(color="#ffff00"))  # a save, and another during its render (a render takes
        time.sleep(1.0)  # seconds: a process starts, simulates, draws, encodes): the first is killed, the second shown
        scene.write_text(BALL.format(color="#0000ff"))
        page.wait_for_function(f"document.getElementById('video').src !== {first!r}", timeout=PATIENCE)
        second = page.eval_on_selector("#video", "video => video.src")
        assert any("starting over" in line for line in lines), "".join(lines)
        time.sleep(1.0)
        assert page.eval_on_selector("#video", "video => video.src") == second, "one new video, not two"

        scene.write_text(BALL.format(color="#0000ff").replace("radius: 0.2", "radius: -0.2"))
        page.wait_for_function("!document.getElementById('errors').hidden", timeout=PATIENCE)
        errors = page.inner_text("#errors")
        assert "scene.yaml:5:" in errors and "radius" in errors, errors
        assert page.eval_on_selector("#video", "video => video.src") == second, "the last good video stays"

        scene.write_text(BALL.format(color="#00ff00"))  # fixed: a video again, the errors gone
        page.wait_for_function(f"document.getElementById('video').src !== {second!r}", timeout=PATIENCE)
        assert page.eval_on_selector("#errors", "errors => errors.hidden")
    finally:
        process.terminate()
        process.wait(timeout=20)
    assert any("rendered" in line for line in lines), "".join(lines)


def _red_centroid(image):
    red = (image[..., 0] > 150) & (image[..., 1] < 90) & (image[..., 2] < 90)
    rows, columns = np.nonzero(red)
    return np.array([columns.mean(), rows.mean()])


@pytest.mark.slow
def test_a_frame_range_previews_those_frames_as_the_whole_render_draws_them(tmp_path):
    """--frames 6-11: six frames, the first of which shows the ball where frame 6 of the whole render has it (at
    t = 0.5 s it has flown 0.5 m right and 0.27 m up), framed alike; not where it starts."""
    scene = tmp_path / "scene.yaml"
    scene.write_text(BALL.format(color="#ff0000"))
    broadcast = Broadcast()
    loop = PreviewLoop(scene, broadcast, tmp_path / "work", frames="6-11", say=lambda line: None)
    loop._render_once()
    (preview,) = broadcast.videos.values()
    frames = iio.imread(preview, index=None)
    assert frames.shape[:3] == (6, 180, 320)
    whole = api.render(scene, out_dir=tmp_path / "whole", formats="png", progress=False, plot=False)
    folder = Path(whole.outputs[0])
    at = {index: _red_centroid(iio.imread(folder / f"frame_{index:05d}.png")) for index in (0, 6, 11)}
    assert np.linalg.norm(_red_centroid(frames[0]) - at[6]) < 3  # pixels (the WebM's loss moves the edge a little)
    assert np.linalg.norm(_red_centroid(frames[-1]) - at[11]) < 3
    assert np.linalg.norm(at[6] - at[0]) > 20
    # a range the scene does not have is named on the page, and nothing is rendered
    loop.frames = "20-30"
    loop._render_once()
    assert broadcast.event == "errors" and "the scene has 12 frames (0-11)" in broadcast.data
    assert len(broadcast.videos) == 1


def test_a_terminated_watch_stops_and_takes_its_folder_of_renders_with_it(tmp_path):
    """SIGTERM (kill, a service manager's stop) ends the watch as Ctrl-C does: it exits cleanly
    and its folder in the temporary directory is gone (before, the process died before any cleanup, and every
    terminated watch left its folder of renders behind)."""
    _, process, lines = _watching(tmp_path)
    folders = Path(tempfile.gettempdir()).glob
    try:
        deadline = time.monotonic() + 60
        while not any("http://127.0.0.1:" in line for line in lines) or not list(
                folders(f"animbatch-watch-{process.pid}-*")):
            assert time.monotonic() < deadline and process.poll() is None, "".join(lines)
            time.sleep(0.1)
    finally:
        process.terminate()
        code = process.wait(timeout=20)
    assert code == 0, "".join(lines)
    assert not list(folders(f"animbatch-watch-{process.pid}-*"))
