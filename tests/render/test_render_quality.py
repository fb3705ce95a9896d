"""Quality presets and contact shadows, checked by pixels: presets change what they say they change, and a shadow
darkens the ground where the key light projects the body, and moves with it."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from animbatch import api, stages
from animbatch.cli import cli
from animbatch.render.backend import select_backend
from animbatch.render.renderer import FrameRenderer
from animbatch.scene.schema import QUALITY_PRESETS, RenderSpec
from support.scenarios import on_screen_extent

pytestmark = pytest.mark.render

# A ball held 0.8 m above the ground (no gravity) by the camera's default three-quarter view.
HOVER = """
name: hover
duration: 0.1
fps: 30
bodies: [{{name: ball, radius: 0.2, position: [{x}, 1.0, 0], color: "#ff0000"}}]
render:
  resolution: [320, 180]
  show_time: false
  ground: {{level: 0, size: 6, grid: false}}
  camera: {{position: [0.0, 3.0, 6.0], focal_point: [0.0, 0.5, 0.0]}}
  shadows: {shadows}
"""


@pytest.mark.parametrize("quality", sorted(QUALITY_PRESETS))
def test_a_preset_sets_exactly_its_keys_where_the_scene_is_silent(quality):
    """Each preset fills every key it lists; a key the scene sets wins over the preset; other keys keep their own
    defaults."""
    preset = QUALITY_PRESETS[quality]
    spec = RenderSpec.model_validate({"quality": quality})
    assert {name: getattr(spec, name) for name in preset} == preset
    mine = RenderSpec.model_validate({"quality": quality, "resolution": [320, 240], "anti_aliasing": "fxaa"})
    assert mine.resolution == [320, 240] and mine.anti_aliasing == "fxaa"
    assert spec.background == RenderSpec().background and spec.springs == RenderSpec().springs


def test_the_default_quality_is_the_preview_look():
    """Without a quality, a scene renders as before presets existed: preview's values are the keys' defaults."""
    spec = RenderSpec()
    assert spec.quality == "preview"
    assert {name: getattr(spec, name) for name in QUALITY_PRESETS["preview"]} == QUALITY_PRESETS["preview"]


def test_quality_on_the_command_line_sets_the_frame_size_and_a_wrong_one_is_named(tmp_path):
    """--quality draft renders 640×360 frames where the scene gives no size; a misspelt preset gets the allowed
    values and a suggestion, naming the setting."""
    scene = tmp_path / "hover.yaml"
    scene.write_text(HOVER.format(x=0.0, shadows="false").replace("  resolution: [320, 180]\n", ""))
    result = CliRunner().invoke(cli, ["render", str(scene), "--quality", "draft", "--formats", "png",
                                      "--out", str(tmp_path / "out"), "--no-progress"])
    assert result.exit_code == 0, result.output
    frame = Image.open(tmp_path / "out" / "hover" / "frames" / "frame_00000.png")
    assert frame.size == (640, 360)
    wrong = CliRunner().invoke(cli, ["validate", str(scene), "--set", "render.quality=fnial"])
    assert wrong.exit_code == 1
    assert "render.quality: must be one of draft, preview, final (got 'fnial'); did you mean 'final'?" in wrong.output


def hover_frame(x: float, shadows: bool) -> tuple[np.ndarray, tuple[float, float]]:
    """The hovering ball at ``x`` [m] drawn, and where on screen (column, row) its shadow's centre must fall: the
    ball's centre projected onto the ground along the key light, then through the camera."""
    scene = stages.parse_scene(HOVER.format(x=x, shadows=str(shadows).lower()))
    model = api.compile_model(scene)
    trajectory = api.simulate(scene, model=model)
    geometry = stages.frame_geometry(stages.plan(scene, model=model), trajectory)
    with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
        image = renderer.draw(0.0, trajectory.positions[0], trajectory.orientations[0])
        expected = (np.nan, np.nan)
        if renderer._shadows is not None:
            light = renderer._shadows.direction  # travelling down: from the ball's centre to the ground (y = 0)
            assert light[1] < 0
            centre = np.array([x, 1.0, 0.0]) + (1.0 / -light[1]) * light
            display = renderer.plotter.renderer
            display.SetWorldPoint(*centre, 1.0)
            display.WorldToDisplay()
            column, row, _ = display.GetDisplayPoint()
            expected = (column, image.shape[0] - 1 - row)  # display rows count from the bottom
    return image.astype(int), expected


def test_a_shadow_darkens_the_ground_where_the_key_light_projects_the_body_and_moves_with_it():
    """With shadows on, ground pixels darken (and nothing else changes) in a blob centred where the ball's centre
    projects onto the ground along the key light, to within a few pixels; moved 1 m to the right, the ball takes
    its shadow with it."""
    centres = []
    for x in (-0.5, 0.5):
        lit, expected = hover_frame(x, shadows=True)
        plain, _ = hover_frame(x, shadows=False)
        darker = (plain - lit).sum(axis=2)
        rows, columns = np.nonzero(darker > 60)
        assert len(rows) > 80, "no shadow on the ground"
        assert (lit - plain).max() <= 3, "a shadow only darkens"
        centre = (columns.mean(), rows.mean())
        assert abs(centre[0] - expected[0]) < 4 and abs(centre[1] - expected[1]) < 4, (centre, expected)
        red = (plain[..., 0] > 150) & (plain[..., 1] < 100)
        assert rows.mean() > np.nonzero(red)[0].mean(), "the shadow lies below the ball on screen"
        centres.append(centre)
    assert centres[1][0] - centres[0][0] > 20, "the shadow follows the ball"


def test_the_shadow_matrix_lands_points_on_the_ground_along_the_light():
    """For any ground plane and light: every point lands on the plane (n · p' = c), moved along the light only, and
    points already on the plane stay put."""
    from animbatch.render.shadows import key_light_direction, planar_projection

    rng = np.random.default_rng(7)
    for _ in range(5):
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        light = key_light_direction(normal, rng.normal(size=3))
        assert np.dot(light, normal) < -0.5  # downwards
        matrix = planar_projection(normal, 0.3, light)
        points = rng.normal(size=(20, 3))
        landed = (np.c_[points, np.ones(20)] @ matrix.T)[:, :3]
        assert np.allclose(landed @ normal, 0.3)
        moved = landed - points
        assert np.allclose(np.cross(moved, light), 0.0, atol=1e-12)
        assert np.allclose((np.c_[landed, np.ones(20)] @ matrix.T)[:, :3], landed)


def test_a_plane_collider_in_the_ground_is_drawn_once_as_the_ground():
    """A floor collider at the ground's level is the ground: drawing both squares in one plane made them fight over
    every pixel (a blotchy floor). The collider's own colour appears nowhere; the ground's does."""
    text = HOVER.format(x=0.0, shadows="false") + 'colliders: [{type: plane, color: "#00ff00"}]\n'
    scene = stages.parse_scene(text)
    model = api.compile_model(scene)
    trajectory = api.simulate(scene, model=model)
    geometry = stages.frame_geometry(stages.plan(scene, model=model), trajectory)
    with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
        image = renderer.draw(0.0, trajectory.positions[0], trajectory.orientations[0]).astype(int)
    green = (image[..., 1] > 150) & (image[..., 0] < 100) & (image[..., 2] < 100)
    assert green.sum() == 0
    ground = np.abs(image - np.array([0xd8, 0xd8, 0xd8])).sum(axis=2) < 60
    assert ground.sum() > 0.1 * image.shape[0] * image.shape[1]


THROW = """
name: throw
duration: 1.2
fps: 30
solver: {method: RK45, rtol: 1.0e-9, atol: 1.0e-11}
bodies: [{name: ball, radius: 0.08, position: [-1.5, 0, 0], velocity: [2.5, 5.0, 0], color: "#ff0000"}]
fields: [{type: gravity, g: [0, -9.81, 0]}]
render:
  resolution: [480, 270]
  show_time: false
  camera: {position: [0, 1.0, 7.0], focal_point: [0, 1.0, 0]}
  trails: {length: 0.6, width: 2, fade: false}
"""


def test_a_trail_follows_the_closed_form_path_over_its_length_only():
    """At t = 1 s the trail of a thrown ball covers the parabola x = x0 + vx t, y = vy t − g t²/2 from t = 0.4 s to
    1 s, as the camera projects it: every trail pixel lies within 2.5 px of that curve, the curve is drawn along
    its whole length, and the path before 0.4 s is not drawn."""
    scene = stages.parse_scene(THROW)
    model = api.compile_model(scene)
    trajectory = api.simulate(scene, model=model)
    geometry = stages.frame_geometry(stages.plan(scene, model=model), trajectory)
    frame = 30  # t = 1 s

    def path(t: np.ndarray) -> np.ndarray:
        return np.stack([-1.5 + 2.5 * t, 5.0 * t - 9.81 * t**2 / 2, 0 * t], axis=1)

    with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
        image = renderer.draw(float(trajectory.times[frame]), trajectory.positions[frame],
                              trajectory.orientations[frame]).astype(int)
        display = renderer.plotter.renderer

        def on_screen(points: np.ndarray) -> np.ndarray:
            pixels = []
            for point in points:
                display.SetWorldPoint(*point, 1.0)
                display.WorldToDisplay()
                column, row, _ = display.GetDisplayPoint()
                pixels.append((column, image.shape[0] - 1 - row))
            return np.array(pixels)

        curve = on_screen(path(np.linspace(0.4, 1.0, 400)))
        older = on_screen(path(np.linspace(0.05, 0.3, 50)))
        ball = on_screen(path(np.array([1.0])))[0]
    red = (image[..., 0] > 150) & (image[..., 1] < 120) & (image[..., 2] < 120)
    rows, columns = np.nonzero(red)
    pixels = np.stack([columns, rows], axis=1).astype(float)
    radius_px = 8.0  # the ball's disc on screen is about 6 px across: leave it out
    trail = pixels[np.linalg.norm(pixels - ball, axis=1) > radius_px]
    assert len(trail) > 100
    nearest = np.min(np.linalg.norm(trail[:, None, :] - curve[None, :, :], axis=2), axis=1)
    assert nearest.max() < 2.5, f"a trail pixel {nearest.max():.1f} px off the closed-form path"
    along = curve[np.linalg.norm(curve - ball, axis=1) > radius_px]
    reach = np.min(np.linalg.norm(along[:, None, :] - pixels[None, :, :], axis=2), axis=1)
    assert reach.max() < 2.0, "the trail has a gap"
    before = np.min(np.linalg.norm(older[:, None, :] - pixels[None, :, :], axis=2), axis=1)
    assert before.min() > 4.0, "the trail reaches further back than its length"


def test_a_trail_of_an_unknown_body_or_of_a_cloth_is_refused_where_it_is_named(tmp_path):
    """render.trails.bodies names particles or rigid bodies: a misspelt name gets a suggestion, a cloth is refused
    with the reason, both at the list item, with file, line and column."""
    scene = tmp_path / "scene.yaml"
    scene.write_text(THROW + "  # trails of\n")
    result = CliRunner().invoke(cli, ["validate", str(scene), "--set", "render.trails.bodies=[bal]"])
    assert result.exit_code == 1
    assert "render.trails.bodies[0]: unknown body 'bal'; did you mean 'ball'? Particles and rigid bodies: ball" in (
        result.output)
    cloth = THROW.replace('color: "#ff0000"}]', 'color: "#ff0000"}, {name: sheet, type: cloth, density: 0.15, '
                                                 'grid: {size: [1, 1], resolution: [3, 3]}, position: [0, 2, 0]}]')
    scene.write_text(cloth)
    result = CliRunner().invoke(cli, ["validate", str(scene), "--set", "render.trails.bodies=[sheet]"])
    assert result.exit_code == 1 and result.output.count("\n") == 1  # this problem only
    assert "render.trails.bodies[0]: unknown body 'sheet' (a cloth or lattice has no one point to follow" in (
        result.output)


HUD_LABEL = "t = {t:.2f} s, frame {frame}/{frames} at {fps:g} fps\\nE = {E:.4f} J, KE = {KE:.4f} J, v = {speed[ball]:.3f} m/s"


def test_the_text_overlay_shows_the_frame_energies_and_speeds_of_the_closed_form():
    """The overlay's fields at t = 0.5 s of the throw: frame 15 of 36 (1.2 s at 30 fps), total energy m (v0²/2) (the ground
    of potential energy is y = 0, where the ball starts), kinetic energy m v²/2 and speed |v| of the closed form."""
    scene = stages.parse_scene(THROW.replace("  show_time: false\n", f'  time_label: "{HUD_LABEL}"\n'))
    model = api.compile_model(scene)
    trajectory = api.simulate(scene, model=model)
    geometry = stages.frame_geometry(stages.plan(scene, model=model), trajectory)
    with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
        renderer.draw(0.5, trajectory.positions[15], trajectory.orientations[15])
        text = renderer._label.GetInput()
    mass = float(model.bodies.mass[0])
    speed = np.hypot(2.5, 5.0 - 9.81 * 0.5)
    assert text == (f"t = 0.50 s, frame 15/36 at 30 fps\nE = {mass * (2.5**2 + 5**2) / 2:.4f} J, "
                    f"KE = {mass * speed**2 / 2:.4f} J, v = {speed:.3f} m/s")


@pytest.mark.parametrize("corner", ["upper_left", "upper_right", "lower_left", "lower_right"])
def test_the_overlay_sits_in_its_corner_and_scales_with_the_frame(corner):
    """The overlay's dark pixels lie in the quadrant of its corner only, and its font size is label_size of the
    frame height: the text is the same fraction of the frame tall at 240 and at 960 rows (within rounding)."""
    heights = []
    for width, height in ((320, 240), (1280, 960)):
        text = (THROW.replace("  show_time: false\n", f"  label_corner: {corner}\n  label_size: 0.05\n")
                .replace("resolution: [480, 270]", f"resolution: [{width}, {height}]"))
        scene = stages.parse_scene(text.replace("trails: {length: 0.6, width: 2, fade: false}", "ground: null"))
        model = api.compile_model(scene)
        trajectory = api.simulate(scene, model=model)
        geometry = stages.frame_geometry(stages.plan(scene, model=model), trajectory)
        with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
            image = renderer.draw(0.0, trajectory.positions[0] + 100.0, trajectory.orientations[0])  # ball away
        dark = image.sum(axis=2) < 200
        rows, columns = np.nonzero(dark)
        assert len(rows), "no text drawn"
        upper, left = corner.startswith("upper"), corner.endswith("left")
        assert (rows < height / 2).all() if upper else (rows > height / 2).all()
        assert (columns < width / 2).all() if left else (columns > width / 2).all()
        heights.append((rows.max() - rows.min() + 1) / height)
    assert heights[0] == pytest.approx(heights[1], abs=2.5 / 240)
    assert 0.05 <= heights[1] < 0.09  # the font size, with the line's ascenders and descenders about 1.5 times it


def test_a_speed_of_an_unknown_body_in_the_overlay_is_refused_with_a_suggestion(tmp_path):
    """{speed[NAME]} names a body: a misspelt one is reported at render.time_label with the closest name."""
    scene = tmp_path / "scene.yaml"
    scene.write_text(THROW)
    result = CliRunner().invoke(cli, ["validate", str(scene), "--set", "render.time_label='{speed[bal]}'"])
    assert result.exit_code == 1
    assert "render.time_label: {speed[bal]}: unknown body 'bal'; did you mean 'ball'? Bodies: ball" in result.output


FRAMED_SCENES = ["projectile", "bouncing_balls", "two_body_orbit", "tumbling_box", "dumbbell"]


@pytest.mark.slow
@pytest.mark.parametrize("name", FRAMED_SCENES)
def test_the_fitted_camera_keeps_every_body_inside_the_frame_with_a_margin_over_the_whole_run(name):
    """The default camera is fitted to the whole motion: at every frame of the run every body, with its full
    extent, stays at least 3 % of the frame away from each edge (a pinhole projection of the trajectory through the
    camera the renderer uses)."""
    from animbatch.compile.frame_geometry import body_extents
    from animbatch.render.camera import place_camera

    scene = stages.load_scene(f"scenes/{name}.yaml")
    assert scene.spec.render.camera.position is None, "this test is about the fitted camera"
    model = api.compile_model(scene)
    trajectory = api.simulate(scene, model=model)
    geometry = stages.frame_geometry(stages.plan(scene, model=model), trajectory)
    width, height = scene.spec.render.resolution
    placement = place_camera(scene.spec.render.camera, geometry.bounds, width / height)
    extent = on_screen_extent(placement, width / height, trajectory.positions, body_extents(model)[None, :])
    assert extent.max() <= 0.97, f"a body reaches {extent.max():.3f} of the half-frame"


def test_a_ball_tossed_up_with_nothing_else_in_the_scene_is_drawn_at_every_frame():
    """A red ball thrown upward, no floor, the fitted camera: every frame shows it, about as large as on the first.
    (The near and far clipping planes were set once, around the first frame's props: the camera looks down, so the
    rising ball left that range and vanished for the top of its arc.)"""
    scene = stages.parse_scene("""
duration: 1
fps: 24
bodies: [{name: ball, radius: 0.1, position: [0, 1, 0], velocity: [1, 3, 0], color: "#ff0000"}]
fields: [{type: gravity}]
render: {resolution: [160, 90], show_time: false}
""")
    assert scene.spec.render.camera.position is None
    model = api.compile_model(scene)
    trajectory = api.simulate(scene, model=model)
    geometry = stages.frame_geometry(stages.plan(scene, model=model), trajectory)
    with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
        red = []
        for t, positions in zip(trajectory.times, trajectory.positions):
            image = renderer.draw(float(t), positions).astype(int)
            red.append(int(np.count_nonzero((image[..., 0] > 120) & (image[..., 1] < 90) & (image[..., 2] < 90))))
    assert red[0] >= 6
    assert min(red) >= 0.4 * red[0], f"red pixels per frame: {red}"


def test_bars_in_the_overlay_are_drawn_as_bars():
    """'|v|' is plain text: the overlay '| | | |' shows four separate upright strokes (VTK's default text backend
    sent any '|' to MathText, which drew the label in another font and dropped the bars)."""
    scene = stages.parse_scene(THROW.replace("  show_time: false\n", '  time_label: "| | | |"\n  label_size: 0.1\n'))
    model = api.compile_model(scene)
    trajectory = api.simulate(scene, model=model)
    geometry = stages.frame_geometry(stages.plan(scene, model=model), trajectory)
    with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
        image = renderer.draw(0.0, trajectory.positions[0] + 100.0, trajectory.orientations[0]).astype(int)
    dark = image.sum(axis=2) < 300
    rows, columns = np.nonzero(dark)
    inked = np.zeros(image.shape[1], bool)
    inked[columns] = True
    strokes = np.count_nonzero(inked[1:] & ~inked[:-1]) + int(inked[0])
    assert strokes == 4
    assert rows.max() - rows.min() > 3 * (np.count_nonzero(inked) / 4), "strokes are upright"
