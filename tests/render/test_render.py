"""Rendering end to end, checked by pixels and video metadata (never by byte hashes)."""

from __future__ import annotations

import math
from pathlib import Path

import imageio_ffmpeg
import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from animbatch import api
from animbatch.cli import cli
from animbatch.errors import RenderError
from animbatch.render import backend as backend_module
from animbatch.render.camera import place_camera
from animbatch.scene.schema import CameraSpec
from support.scenes import counting

pytestmark = pytest.mark.render

WIDTH, HEIGHT = 192, 108
DISTANCE, VIEW_ANGLE = 4.0, 40.0
# A red ball sliding right at 1.5 m/s through the focal plane of a fixed camera looking down -z.
SLIDE = f"""
name: slide
duration: 0.4
fps: 30
solver: {{method: verlet, dt: 0.01}}
bodies: [{{name: ball, radius: 0.12, position: [-0.6, 0, 0], velocity: [1.5, 0, 0], color: "#ff0000"}}]
render:
  resolution: [{WIDTH}, {HEIGHT}]
  background: white
  show_time: false
  camera: {{position: [0, 0, {DISTANCE}], focal_point: [0, 0, 0], view_angle: {VIEW_ANGLE}}}
  formats: [mp4, png]
"""


def red_centroid(image: np.ndarray) -> tuple[float, float]:
    """Pixel centroid (column, row) of the ball: every pixel clearly off the white background, lit or in the ball's
    own shade, so that where the light comes from does not move the centroid."""
    rgb = image.astype(int)
    mask = (255 - rgb).sum(axis=2) > 90
    assert mask.sum() > 10, "ball not visible"
    rows, cols = np.nonzero(mask)
    return float(cols.mean()), float(rows.mean())


@pytest.fixture
def slide_scene(tmp_cwd):
    (tmp_cwd / "slide.yaml").write_text(SLIDE)
    return tmp_cwd / "slide.yaml"


def test_mp4_has_right_metadata_and_shows_motion(slide_scene, tmp_cwd):
    """The MP4 is H.264 yuv420p with the scene's size, fps and frame count, and the ball moves right in it."""
    result = CliRunner().invoke(cli, ["render", str(slide_scene), "--no-progress"])
    assert result.exit_code == 0, result.output
    video = tmp_cwd / "renders" / "slide" / "slide.mp4"
    reader = imageio_ffmpeg.read_frames(str(video))
    meta = next(reader)
    frames = [np.frombuffer(f, np.uint8).reshape(HEIGHT, WIDTH, 3) for f in reader]
    assert meta["size"] == (WIDTH, HEIGHT) and meta["fps"] == 30
    assert meta["codec"].startswith("h264") and meta["pix_fmt"].startswith("yuv420p")
    assert len(frames) == 12  # ceil(0.4 s × 30 fps)
    assert imageio_ffmpeg.count_frames_and_secs(str(video))[0] == 12
    columns = [red_centroid(frame)[0] for frame in frames]
    assert np.all(np.diff(columns) > 0)
    assert "slide: 12 frames 192×108 @ 30 fps" in result.output


def test_ball_appears_where_the_camera_projects_it(slide_scene, tmp_cwd):
    """In the PNG frames the ball's centre is at the pinhole projection of its simulated position (±1 px)."""
    api.run(slide_scene, out_dir="renders")
    pixels_per_metre = HEIGHT / (2 * DISTANCE * math.tan(math.radians(VIEW_ANGLE) / 2))
    for k in (0, 5, 11):
        image = np.asarray(Image.open(tmp_cwd / "renders" / "slide" / "frames" / f"frame_{k:05d}.png"))
        column, row = red_centroid(image)
        x = -0.6 + 1.5 * k / 30
        assert column == pytest.approx(WIDTH / 2 + x * pixels_per_metre - 0.5, abs=1.0)
        assert row == pytest.approx(HEIGHT / 2 - 0.5, abs=1.0)


def test_rendering_from_a_trajectory_gives_the_same_frames(slide_scene, tmp_cwd):
    """simulate -o run.npz then render --trajectory produces frames identical to a direct render."""
    runner = CliRunner()
    assert runner.invoke(cli, ["render", str(slide_scene), "--out", "direct", "--formats", "png"]).exit_code == 0
    assert runner.invoke(cli, ["simulate", str(slide_scene), "-o", "run.npz"]).exit_code == 0
    result = runner.invoke(cli, ["render", str(slide_scene), "--trajectory", "run.npz", "--out", "baked",
                                 "--formats", "png"])
    assert result.exit_code == 0, result.output
    for k in range(12):
        direct = np.asarray(Image.open(tmp_cwd / "direct" / "slide" / "frames" / f"frame_{k:05d}.png"))
        baked = np.asarray(Image.open(tmp_cwd / "baked" / "slide" / "frames" / f"frame_{k:05d}.png"))
        assert np.array_equal(direct, baked)
    assert not (tmp_cwd / "baked" / "slide" / "slide.mp4").exists()  # only the formats asked for


def test_library_render_of_a_simulated_trajectory_writes_what_the_scene_asks_for(slide_scene, tmp_cwd):
    """The README's library example (load, plan, simulate, render) gives the same files as the command line: an
    MP4 of 12 frames, the PNG frames (identical to the CLI's), and the ball moving right. Rendering again draws
    nothing: every frame is complete on disk."""
    scene = api.load_scene(slide_scene)
    plan = api.plan(scene)
    trajectory = api.simulate(plan)
    result = api.render(plan, trajectory, out_dir="library")
    folder = tmp_cwd / "library" / "slide"
    assert [Path(path).resolve() for path in result.outputs] == [folder / "slide.mp4", folder / "frames"]
    assert result.frame_count == 12 and result.resolution == (WIDTH, HEIGHT) and result.fps == 30
    assert imageio_ffmpeg.count_frames_and_secs(str(folder / "slide.mp4"))[0] == 12
    assert CliRunner().invoke(cli, ["render", str(slide_scene), "--out", "cli", "--jobs", "1"]).exit_code == 0
    columns = []
    for k in range(12):
        image = np.asarray(Image.open(folder / "frames" / f"frame_{k:05d}.png"))
        from_cli = tmp_cwd / "cli" / "slide" / "frames" / f"frame_{k:05d}.png"
        assert np.array_equal(image, np.asarray(Image.open(from_cli)))
        columns.append(red_centroid(image)[0])
    assert np.all(np.diff(columns) > 0)
    again = api.render(plan, trajectory, out_dir="library")
    assert again.backend.startswith("(none") and again.frames_drawn == 0


def test_camera_change_renders_from_trajectory_without_simulating(slide_scene, tmp_cwd, monkeypatch):
    """A different resolution and camera render from the saved trajectory; the simulator is not called."""
    runner = CliRunner()
    assert runner.invoke(cli, ["simulate", str(slide_scene), "-o", "run.npz"]).exit_code == 0
    monkeypatch.setattr(api, "simulate", lambda *a, **k: pytest.fail("simulated again"))
    result = runner.invoke(cli, ["render", str(slide_scene), "--trajectory", "run.npz", "--resolution", "96x54",
                                 "--set", "render.camera.view_angle=60", "--formats", "png"])
    assert result.exit_code == 0, result.output
    assert Image.open(tmp_cwd / "renders" / "slide" / "frames" / "frame_00000.png").size == (96, 54)


def interrupt_at_frame_7(monkeypatch) -> tuple[list[int], object]:
    """Make the renderer raise Ctrl-C when asked for frame 7 (t > 0.2 s at 30 fps); returns the frames drawn and the
    renderer's own draw."""
    from animbatch.render.renderer import FrameRenderer

    original = FrameRenderer.draw
    drawn: list[int] = []

    def failing(self, t, *state):
        if t > 0.2:
            raise KeyboardInterrupt
        drawn.append(round(t * 30))
        return original(self, t, *state)

    monkeypatch.setattr(FrameRenderer, "draw", failing)
    return drawn, original


def count_draws(monkeypatch, original) -> list[int]:
    from animbatch.render.renderer import FrameRenderer

    drawn: list[int] = []
    monkeypatch.setattr(FrameRenderer, "draw", lambda self, t, *state: drawn.append(round(t * 30)) or original(
        self, t, *state))
    return drawn


def test_interrupted_streamed_render_leaves_no_video_or_partial_file_and_starts_again(slide_scene, tmp_cwd,
                                                                                         monkeypatch):
    """A render streams its frames into ffmpeg. Interrupted while drawing frame 7: no video, no partial file of any
    kind and no frame files exist. The next run reuses the cache, draws all 12 frames, and the video has 12."""
    drawn, original = interrupt_at_frame_7(monkeypatch)
    result = CliRunner().invoke(cli, ["render", str(slide_scene), "--formats", "mp4"])
    assert result.exit_code == 130 and "interrupted" in result.output
    assert drawn == list(range(7))
    folder = tmp_cwd / "renders" / "slide"
    assert not list(folder.rglob("*.mp4")) and not list(folder.rglob(".*"))  # no video, no hidden partial file
    assert not list(folder.rglob("frame_*"))

    monkeypatch.setattr(api, "simulate", lambda *a, **k: pytest.fail("simulated again"))
    drawn = count_draws(monkeypatch, original)
    result = CliRunner().invoke(cli, ["render", str(slide_scene), "--formats", "mp4"])
    assert result.exit_code == 0, result.output
    assert drawn == list(range(12))
    reader = imageio_ffmpeg.read_frames(str(folder / "slide.mp4"))
    assert next(reader)["size"] == (WIDTH, HEIGHT) and sum(1 for _ in reader) == 12
    assert not (folder / "frames").exists()


def test_interrupted_render_with_png_frames_resumes_from_them(slide_scene, tmp_cwd, monkeypatch):
    """With png among the formats the streamed frames also go to disk: an interrupt at frame 7 leaves the frames
    drawn before as complete PNGs and no video; the next run (mp4 only) draws only frames 7 … 11 and encodes all
    12 (the farm path's rule: a complete frame of the same picture is never drawn twice)."""
    from animbatch.farm.frame_files import frame_is_complete

    drawn, original = interrupt_at_frame_7(monkeypatch)
    result = CliRunner().invoke(cli, ["render", str(slide_scene), "--formats", "png,mp4"])
    assert result.exit_code == 130 and "interrupted" in result.output
    folder = tmp_cwd / "renders" / "slide"
    assert not list(folder.rglob("*.mp4")) and not list(folder.rglob(".*"))  # no video, no hidden partial file
    frames = sorted(path.name for path in (folder / "frames").glob("frame_*"))
    assert frames == [f"frame_{i:05d}.png" for i in range(7)]
    assert all(frame_is_complete(folder / "frames" / name, (WIDTH, HEIGHT)) for name in frames)

    monkeypatch.setattr(api, "simulate", lambda *a, **k: pytest.fail("simulated again"))
    drawn = count_draws(monkeypatch, original)
    result = CliRunner().invoke(cli, ["render", str(slide_scene), "--formats", "mp4"])
    assert result.exit_code == 0, result.output
    assert drawn == list(range(7, 12))
    reader = imageio_ffmpeg.read_frames(str(folder / "slide.mp4"))
    assert next(reader)["size"] == (WIDTH, HEIGHT) and sum(1 for _ in reader) == 12
    assert not (folder / "frames").exists()  # mp4 only: the frames go once the video is encoded


def test_no_backend_gives_one_clear_message(slide_scene, monkeypatch):
    """Without EGL or OSMesa libraries, the render stops with what to install, exit code 4, no traceback."""
    monkeypatch.setattr(backend_module, "library_loads", lambda library: False)
    result = CliRunner().invoke(cli, ["render", str(slide_scene)])
    assert result.exit_code == 4
    assert "no off-screen OpenGL library found" in result.output and "apt-get install libosmesa6" in result.output
    assert "Traceback" not in result.output
    with pytest.raises(RenderError, match="apt-get install libegl1"):
        backend_module.select_backend("egl")


@pytest.mark.parametrize("name", ["egl", "osmesa"])
def test_each_backend_renders_when_installed(slide_scene, tmp_cwd, monkeypatch, name):
    """A forced backend is used (and reported) when its library is present."""
    if not backend_module.is_available(backend_module.BACKENDS[name]):
        pytest.skip(f"{name} libraries not installed")
    from animbatch.render.renderer import FrameRenderer

    created = []
    original = FrameRenderer.draw

    def spy(self, t, *state):
        created.append(self.plotter.ren_win.GetClassName())
        return original(self, t, *state)

    monkeypatch.setattr(FrameRenderer, "draw", spy)
    report = api.run(slide_scene, out_dir="renders", backend=name)
    assert report.backend == name and set(created) == {backend_module.BACKENDS[name].vtk_window_class}
    image = np.asarray(Image.open(tmp_cwd / "renders" / "slide" / "frames" / "frame_00000.png"))
    red_centroid(image)


def test_many_particles_render_as_sprites_with_springs_and_anchors(tmp_cwd):
    """Sprite particles, spring lines, anchors, ground and time label all draw without a mesh per particle."""
    bodies = "\n".join(f"  - {{name: p{i}, position: [{i % 20 * 0.1}, {i // 20 * 0.1}, 0], color: blue}}"
                       for i in range(400))
    (tmp_cwd / "many.yaml").write_text(f"""
name: many
duration: 0.1
bodies:
{bodies}
anchors: [{{name: top, position: [1, 2.5, 0]}}]
springs: [{{between: [top, p399], stiffness: 1}}]
render:
  resolution: [160, 120]
  particles: auto
  ground: {{level: -0.2}}
  formats: [png]
""")
    report = api.run(tmp_cwd / "many.yaml", out_dir="renders")
    assert report.frame_count == 3
    image = np.asarray(Image.open(tmp_cwd / "renders" / "many" / "frames" / "frame_00000.png")).astype(int)
    blue = (image[..., 2] > 120) & (image[..., 0] < 90)
    assert blue.sum() > 500  # the sprites cover a good part of the frame


def test_fitted_camera_keeps_the_whole_motion_in_view():
    """Every corner of the motion's box projects inside the frame, for several directions and aspects."""
    bounds = np.array([[-1.0, 0.0, -0.5], [3.0, 2.0, 0.5]])
    corners = np.array([[bounds[i][0], bounds[j][1], bounds[k][2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    for direction, aspect in (([0.4, 0.35, 1.0], 16 / 9), ([1, 0, 0], 1.0), ([0, 1, 0.01], 4 / 3)):
        placement = place_camera(CameraSpec(direction=direction), bounds, aspect)
        view = placement.focal_point - placement.position
        view /= np.linalg.norm(view)
        right = np.cross(view, placement.up)
        right /= np.linalg.norm(right)
        up = np.cross(right, view)
        rel = corners - placement.position
        depth = rel @ view
        assert np.all(depth > 0)
        tan_half = math.tan(math.radians(placement.view_angle) / 2)
        assert np.all(np.abs(rel @ up) / depth <= tan_half + 1e-9)
        assert np.all(np.abs(rel @ right) / depth <= tan_half * aspect + 1e-9)


ROTATING = f"""
name: turning
duration: 0.5
fps: 4
solver: {{method: DOP853, rtol: 1.0e-10}}
bodies:
  - {{name: bar, type: rigid, shape: {{type: box, size: [1.6, 0.3, 0.3]}}, density: 500,
     angular_velocity: [0, 0, {np.pi}], color: "#ff0000"}}
render:
  resolution: [{WIDTH}, {WIDTH}]
  background: white
  show_time: false
  anti_aliasing: none
  camera: {{position: [0, 0, 5], focal_point: [0, 0, 0], view_angle: 40}}
  formats: [png]
"""


def red_extent(image: np.ndarray) -> tuple[int, int]:
    """Width and height in pixels of the red region."""
    rgb = image.astype(int)
    rows, cols = np.nonzero((rgb[..., 0] > 120) & (rgb[..., 1] < 100) & (rgb[..., 2] < 100))
    return int(np.ptp(cols)), int(np.ptp(rows))


def test_rigid_body_turns_by_its_transform_not_a_new_mesh(tmp_cwd, monkeypatch):
    """A bar spinning at π rad/s about the view axis is wide at t = 0 and tall at t = 0.5 s (turned 90°); the
    renderer only updates the actor's matrix: no mesh is built after the first frame."""
    import pyvista as pv

    (tmp_cwd / "turning.yaml").write_text(ROTATING)
    built = counting(monkeypatch, pv, "Box")
    api.run(tmp_cwd / "turning.yaml", out_dir="renders")
    first = np.asarray(Image.open(tmp_cwd / "renders" / "turning" / "frames" / "frame_00000.png"))
    last = np.asarray(Image.open(tmp_cwd / "renders" / "turning" / "frames" / "frame_00001.png"))
    wide, _ = red_extent(first)
    across, tall = red_extent(last)
    pixels_per_metre = WIDTH / (2 * 5 * math.tan(math.radians(20)))
    assert wide == pytest.approx((1.6 - 0.0) * pixels_per_metre, rel=0.1)
    assert tall == pytest.approx(1.6 * pixels_per_metre * math.sin(math.pi / 4) + 0.3 * pixels_per_metre
                                 * math.cos(math.pi / 4), rel=0.15)  # frame 1 is at t = 0.25 s: turned 45°
    assert built == [1]  # the box mesh was made once


def test_body_axes_are_drawn_in_their_colours(tmp_cwd):
    """show_axes draws red, green and blue arrows along the body's axes."""
    (tmp_cwd / "turning.yaml").write_text(ROTATING.replace("show_time: false", "show_time: false\n  show_axes: true")
                                          .replace('color: "#ff0000"', 'color: "#cccccc"'))
    api.run(tmp_cwd / "turning.yaml", out_dir="renders", overrides=["duration=0.1"])
    image = np.asarray(Image.open(tmp_cwd / "renders" / "turning" / "frames" / "frame_00000.png")).astype(int)
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    red = (r > g + 60) & (r > b + 60)  # shading darkens the arrows, so test which channel dominates
    green = (g > r + 40) & (g > b + 40)
    assert red.sum() > 10 and green.sum() > 20
    assert np.nonzero(red)[1].mean() > WIDTH / 2 + 10  # the x axis points right of the centre
    assert np.nonzero(green)[0].mean() < WIDTH / 2 - 10  # the y axis points up


def test_angular_momentum_arrow_is_drawn(tmp_cwd):
    """show_vectors draws an amber arrow from the body's centre along L (the bar spins about x, so L ∥ +x and the
    arrow points right, past the end of the bar)."""
    scene_text = ROTATING.replace("show_time: false", "show_time: false\n  show_vectors: angular_momentum").replace(
        f"angular_velocity: [0, 0, {np.pi}]", "angular_velocity: [3, 0, 0]").replace('color: "#ff0000"',
                                                                                      'color: "#cccccc"')
    (tmp_cwd / "turning.yaml").write_text(scene_text)
    api.run(tmp_cwd / "turning.yaml", out_dir="renders", overrides=["duration=0.1"])
    image = np.asarray(Image.open(tmp_cwd / "renders" / "turning" / "frames" / "frame_00000.png")).astype(int)
    amber = (image[..., 0] > 150) & (image[..., 1] > 100) & (image[..., 2] < 60)
    columns = np.nonzero(amber)[1]
    assert amber.sum() > 30 and columns.max() > WIDTH / 2 + 40  # along +x (L = I ω ∥ x), past the bar's end


# A 1 × 1 m cloth facing +z (its front), drifting right at 0.6 m/s with no forces, seen along -z from the front.
CLOTH = f"""
name: sheet
duration: 0.5
fps: 4
solver: {{method: backward_euler, dt: 0.05}}
bodies:
  - {{name: sheet, type: cloth, grid: {{size: [1.0, 1.0], resolution: [6, 6]}}, mass: 0.1, velocity: [0.6, 0, 0],
     structural: {{stiffness: 50}}, color: "#ff0000", back_color: "#0000ff"}}
render:
  resolution: [{WIDTH}, {HEIGHT}]
  background: white
  show_time: false
  anti_aliasing: none
  camera: {{position: [0, 0, {DISTANCE}], focal_point: [0, 0, 0], view_angle: {VIEW_ANGLE}}}
  formats: [png]
"""


def dominant(image: np.ndarray, channel: int) -> np.ndarray:
    """Pixels where one colour channel clearly dominates the other two (shading darkens, but keeps the hue)."""
    rgb = image.astype(int)
    others = [rgb[..., k] for k in range(3) if k != channel]
    return (rgb[..., channel] > others[0] + 60) & (rgb[..., channel] > others[1] + 60)


def test_cloth_is_a_two_sided_surface_moved_in_place(tmp_cwd, polydata_built):
    """From the front the cloth shows its front colour, from behind its back colour; its picture moves with the
    simulated vertices (0.6 m/s to the right), and no mesh is built after the first frame."""
    (tmp_cwd / "sheet.yaml").write_text(CLOTH)
    built = polydata_built
    api.run(tmp_cwd / "sheet.yaml", out_dir="renders", overrides=["duration=0.25"])
    one_frame = len(built)
    built.clear()
    api.run(tmp_cwd / "sheet.yaml", out_dir="renders")
    assert len(built) == one_frame  # two frames or one: the same meshes, updated in place
    frames = tmp_cwd / "renders" / "sheet" / "frames"
    first, last = (np.asarray(Image.open(frames / f"frame_{k:05d}.png")) for k in (0, 1))
    pixels_per_metre = HEIGHT / (2 * DISTANCE * math.tan(math.radians(VIEW_ANGLE / 2)))
    for image in (first, last):
        assert dominant(image, 0).sum() > 0.8 * pixels_per_metre**2 and dominant(image, 2).sum() == 0
    shift = np.nonzero(dominant(last, 0))[1].mean() - np.nonzero(dominant(first, 0))[1].mean()
    assert shift == pytest.approx(0.6 * 0.25 * pixels_per_metre, abs=1.5)
    api.run(tmp_cwd / "sheet.yaml", out_dir="renders", overrides=["duration=0.25",
                                                                   f"render.camera.position=[0, 0, -{DISTANCE}]"])
    behind = np.asarray(Image.open(frames / "frame_00000.png"))
    assert dominant(behind, 2).sum() > 0.8 * pixels_per_metre**2 and dominant(behind, 0).sum() == 0


def test_cloth_springs_can_be_drawn_as_lines(tmp_cwd):
    """render.mesh_springs: line draws the cloth's springs over its surface (dark lines on the red sheet)."""
    (tmp_cwd / "sheet.yaml").write_text(CLOTH)
    dark = []
    for choice in ("hidden", "line"):
        api.run(tmp_cwd / "sheet.yaml", out_dir="renders",
                overrides=["duration=0.25", f"render.mesh_springs={choice}"])
        image = np.asarray(Image.open(tmp_cwd / "renders" / "sheet" / "frames" / "frame_00000.png")).astype(int)
        dark.append(int((image.max(axis=2) < 110).sum()))
    assert dark[0] == 0 and dark[1] > 100
