"""The report page of a batch, opened from disk in a real browser: Debian's Chromium, headless, driven by Playwright.

Every video loads (readyState ≥ 2) with its run's duration and size, seeking to a time shows the frame of that time,
the sweep's table sorts by a column as numbers, and the page logs no errors."""

from __future__ import annotations

import io

import imageio_ffmpeg
import numpy as np
import pytest
from click.testing import CliRunner

from animbatch.cli import cli

pytestmark = pytest.mark.render

FPS = 12
WIDTH, HEIGHT = 160, 96

#: A ball crossing the view at constant speed (no force on it), the time printed on every frame: no two frames alike.
SCENE = f"""
name: crossing
duration: 1
fps: {FPS}
bodies: [{{name: ball, mass: 1, radius: 0.15, position: [-1, 0.5, 0], velocity: [2, 0, 0], color: "#e4572e"}}]
render: {{resolution: [{WIDTH}, {HEIGHT}], camera: {{position: [0, 0.5, 3], focal_point: [0, 0.5, 0]}}}}
"""
MASSES = ("5", "20", "100")  # as text "100" < "20" < "5": only a numeric sort gives 5, 20, 100


@pytest.fixture(scope="module")
def sweep_page(tmp_path_factory, dask_scheduler):
    folder = tmp_path_factory.mktemp("page")
    (folder / "crossing.yaml").write_text(SCENE)
    result = CliRunner().invoke(cli, ["batch", str(folder / "crossing.yaml"), "--scheduler", dask_scheduler, "--out",
                                      str(folder / "renders"), "--sweep", f"bodies[ball].mass={','.join(MASSES)}"])
    assert result.exit_code == 0, result.output
    page = folder / "renders" / "crossing-sweep" / "index.html"
    assert f"page: {page}" in result.output
    return page


def decoded_frames(video) -> np.ndarray:
    reader = imageio_ffmpeg.read_frames(str(video), pix_fmt="rgb24")
    width, height = next(reader)["size"]
    return np.stack([np.frombuffer(frame, np.uint8).reshape(height, width, 3) for frame in reader])


@pytest.mark.slow
@pytest.mark.xdist_group("dask")
def test_the_page_plays_every_video_at_its_size_and_duration_and_seeks_to_the_frame_of_a_time(browser, sweep_page):
    """Three variants of 12 frames at 12 fps: each video reaches readyState ≥ 2 with duration 1 s and 160×96 pixels;
    its poster and energy plot load. Seeking the first to the middle of frame k's interval [k/fps, (k+1)/fps) shows
    frame k: of all the video's frames (decoded by ffmpeg), the element's pixels are closest to frame k's."""
    from PIL import Image

    messages: list[str] = []
    page = browser.new_page(viewport={"width": 1400, "height": 1000})
    page.on("console", lambda message: messages.append(f"{message.type}: {message.text}"))
    page.on("pageerror", lambda error: messages.append(f"pageerror: {error}"))
    page.goto(sweep_page.as_uri())
    page.wait_for_function("[...document.querySelectorAll('video')].every(v => v.readyState >= 2)", timeout=30_000)
    videos = page.evaluate("[...document.querySelectorAll('video')].map(v => ({ready: v.readyState, "
                           "duration: v.duration, width: v.videoWidth, height: v.videoHeight, error: v.error}))")
    assert len(videos) == 3
    for video in videos:
        assert video["ready"] >= 2 and video["error"] is None
        assert video["duration"] == pytest.approx(1.0, abs=0.5 / FPS)
        assert (video["width"], video["height"]) == (WIDTH, HEIGHT)
    images = page.evaluate("[...document.querySelectorAll('img')].map(i => i.complete && i.naturalWidth > 0)")
    posters = page.evaluate("[...document.querySelectorAll('video')].map(v => v.poster)")
    assert len(images) == 3 and all(images) and all(poster.endswith(".poster.png") for poster in posters)

    source = page.evaluate("document.querySelector('video source').src")
    frames = decoded_frames(source.removeprefix("file://")).astype(float)
    assert len(frames) == FPS
    element = page.locator("video").first
    element.evaluate("v => { v.controls = false; v.pause(); }")  # nothing drawn over the picture
    for frame in (3, 8):
        element.evaluate("(v, t) => new Promise(done => { v.addEventListener('seeked', done, {once: true}); "
                         "v.currentTime = t; })", (frame + 0.5) / FPS)
        page.wait_for_timeout(100)  # the seeked frame reaches the compositor
        shot = np.asarray(Image.open(io.BytesIO(element.screenshot())).convert("RGB"), float)
        assert abs(shot.shape[0] - HEIGHT) <= 1 and abs(shot.shape[1] - WIDTH) <= 1  # a box at a fractional place
        shot = shot[:HEIGHT, :WIDTH]
        distances = np.abs(frames - shot).mean(axis=(1, 2, 3))
        assert int(np.argmin(distances)) == frame, distances.round(2)
    assert not [m for m in messages if m.startswith(("error", "pageerror"))], messages
    page.close()


@pytest.mark.slow
@pytest.mark.xdist_group("dask")
def test_the_sweep_table_sorts_by_a_column_as_numbers(browser, sweep_page):
    """Clicking the mass column's header sorts the rows 5, 20, 100 (numbers, not text); again, 100, 20, 5; the
    variant column sorts with them, and each variant's name links to its section."""
    page = browser.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.goto(sweep_page.as_uri())
    headers = page.evaluate("[...document.querySelectorAll('#sweep th')].map(h => h.textContent)")
    column = headers.index("bodies[ball].mass")

    def column_values(index: int) -> list[str]:
        return page.evaluate(f"[...document.querySelectorAll('#sweep tbody tr')].map(r => r.cells[{index}]"
                             ".textContent)")

    assert column_values(column) == list(MASSES)
    page.locator("#sweep th").nth(column).click()
    page.locator("#sweep th").nth(column).click()
    assert column_values(column) == ["100", "20", "5"]
    page.locator("#sweep th").nth(column).click()
    assert column_values(column) == ["5", "20", "100"]
    assert column_values(0) == [f"crossing-mass-{mass}" for mass in MASSES]
    page.get_by_role("link", name="crossing-mass-100").click()  # a variant's name leads to its section
    assert page.evaluate("location.hash") == "#run-2"
    assert "crossing-mass-100" in page.evaluate("document.querySelector(location.hash + ' h2').textContent")
    assert not errors
    page.close()


@pytest.mark.slow
def test_render_with_report_html_writes_the_page_of_that_render(tmp_cwd):
    """`render --report html`: renders/<scene>/index.html links the video (with its poster, the middle frame) and
    the energy plot, which it draws; every path in it is relative and exists."""
    import re

    from PIL import Image

    (tmp_cwd / "crossing.yaml").write_text(SCENE)
    result = CliRunner().invoke(cli, ["render", "crossing.yaml", "--report", "html", "--no-progress"])
    assert result.exit_code == 0, result.output
    folder = tmp_cwd / "renders" / "crossing"
    text = (folder / "index.html").read_text()
    links = re.findall(r"(?:src|poster)='([^']+)'", text)
    assert sorted(links) == ["crossing.mp4", "crossing.mp4.poster.png", "quantities.png"]
    assert all((folder / link).is_file() for link in links)
    middle = decoded_frames(folder / "crossing.mp4")[FPS // 2]
    assert np.array_equal(np.asarray(Image.open(folder / "crossing.mp4.poster.png").convert("RGB")), middle)
    assert "no accuracy warnings" in text and "energy drift" in text
