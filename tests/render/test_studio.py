"""The studio, checked by pixels: a gradient backdrop, a ground that fades into it without an edge, a floor collider
drawn as the ground (and shadowed), and a light rig whose key light is the one the shadows fall from."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import api, stages
from animbatch.render.backend import select_backend
from animbatch.render.renderer import FrameRenderer
from animbatch.render.shadows import key_light_direction
from animbatch.render.studio import three_point_rig

pytestmark = pytest.mark.render

EMPTY = """
name: studio
duration: 0.1
fps: 30
bodies: [{{name: ball, radius: 0.2, position: [0, 0.5, 0], color: "#ff0000"}}]
render:
  resolution: [320, 180]
  show_time: false
  camera: {{position: [0, 1.2, 6], focal_point: [0, 0.5, 0]}}
{render}
"""


def first_frame(render: str, extra: str = "") -> np.ndarray:
    scene = stages.parse_scene(EMPTY.format(render=render) + extra)
    model = api.compile_model(scene)
    trajectory = api.simulate(scene, model=model)
    geometry = stages.frame_geometry(stages.plan(scene, model=model), trajectory)
    with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
        return renderer.draw(0.0, trajectory.positions[0], trajectory.orientations[0]).astype(int)


def test_the_backdrop_is_a_vertical_gradient_unless_a_plain_colour_is_asked_for():
    image = first_frame('  background: "#ffffff"\n  background_top: "#000080"\n')
    assert np.abs(image[0, 5] - [0, 0, 128]).max() <= 3, "top row: background_top"
    assert np.abs(image[-1, 5] - [255, 255, 255]).max() <= 3, "bottom row: background"
    middle = image[90, 5]
    assert np.abs(middle - [128, 128, 191]).max() <= 6, "linear in between"
    plain = first_frame("  background: black\n")
    assert plain[0, 5].max() <= 2 and plain[-1, 5].max() <= 2, "background alone: a plain backdrop"


def column_steps(image: np.ndarray, column: int) -> np.ndarray:
    """The colour change (sum over RGB) between vertically adjacent pixels of one column."""
    return np.abs(np.diff(image[:, column], axis=0)).sum(axis=1)


def test_a_fading_ground_meets_the_backdrop_without_an_edge():
    """A dark ground (#505050) under a light plain backdrop: faded, no two neighbouring pixels of a column far from
    the ball differ by more than a small step all the way up to the horizon; a hard square shows its far edge as one
    big step."""
    ground = '  background: "#f0f0f0"\n  ground: {{size: 4, color: "#505050", grid: false, fade: {fade}}}\n'
    faded = first_frame(ground.format(fade="true"))
    hard = first_frame(ground.format(fade="false"))
    column = 20
    assert faded[-1, column].sum() < 3 * 0x70, "the ground near the camera keeps its colour"
    assert np.abs(faded[0, column] - 0xf0).max() <= 2
    assert column_steps(faded, column).max() < 40
    assert column_steps(hard, column).max() > 250


def test_a_floor_collider_is_drawn_as_a_ground_and_takes_the_shadows():
    """No render.ground: the plane collider facing up is the ground, in its own colour, and with shadows on the
    ball's shadow darkens it."""
    floor = 'colliders: [{type: plane, size: 8, color: "#3060c0"}]\n'
    lit = first_frame("  shadows: true\n", floor)
    plain = first_frame("  shadows: false\n", floor)
    blue = (lit[..., 2] > lit[..., 0] + 60)
    assert blue[-40:].mean() > 0.9, "the collider's colour covers the floor under the camera"
    assert ((plain - lit).sum(axis=2) > 40).sum() > 40, "a shadow on it"


TABLE = """
name: table
duration: 0.1
fps: 30
bodies:
  - {body}
colliders:
  - {{type: box, position: [0, 0.4, 0], size: [2.4, 0.8, 1.6], orientation: {{axis: [0, 0, 1], angle: {tilt}}},
     color: "#3060c0"}}
  - {{type: plane, size: 8, color: "#e0e0e0"}}
render:
  resolution: [320, 180]
  show_time: false
  shadows: {shadows}
  ambient_occlusion: false
  camera: {{position: [0.5, 2.6, 4.0], focal_point: [0, 0.8, 0]}}
"""


#: A rigid body's shadow is its mesh flattened; a particle's, its sphere glyph (drawn in one set per receiving face).
OVER_THE_TABLE = {
    "rigid cube": '{{name: cube, type: rigid, shape: {{type: box, size: [0.3, 0.3, 0.3]}}, density: 500, '
                  'position: [0, 1.3, 0], color: "#ff0000"}}',
    "particle": '{{name: ball, radius: 0.15, position: [0, 1.3, 0], color: "#ff0000"}}',
}


@pytest.mark.parametrize("body", OVER_THE_TABLE.values(), ids=OVER_THE_TABLE.keys())
@pytest.mark.parametrize("tilt", [0, 10])
def test_a_body_over_a_raised_box_casts_its_shadow_on_the_box_not_through_it_onto_the_ground(tilt, body):
    """A cube or a ball hovering over a blue table (flat, then tilted as a ramp): every pixel its shadow darkens is
    on the table's top, none on the ground; before, the shadow fell through the table onto the ground beneath it."""

    def frame(shadows: str) -> np.ndarray:
        scene = stages.parse_scene(TABLE.format(tilt=tilt, shadows=shadows, body=body.format()))
        model = api.compile_model(scene)
        trajectory = api.simulate(scene, model=model)
        geometry = stages.frame_geometry(stages.plan(scene, model=model), trajectory)
        with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
            return renderer.draw(0.0, trajectory.positions[0], trajectory.orientations[0]).astype(int)

    plain, shaded = frame("false"), frame("true")
    darker = (plain - shaded).sum(axis=2) > 40
    table = (plain[..., 2] > plain[..., 0] + 60) & (plain[..., 2] > plain[..., 1] + 30)
    assert darker.sum() > 100, "a shadow is drawn"
    assert (darker & table).sum() > 0.95 * darker.sum(), "on the table's top"


def test_the_key_light_is_the_light_the_shadows_fall_from_and_the_rig_lights_from_three_sides_and_below():
    up = np.array([0.0, 1.0, 0.0])
    toward_camera = np.array([0.4, 0.35, 1.0]) / np.linalg.norm([0.4, 0.35, 1.0])
    key, fill, rim, bounce = three_point_rig(up, toward_camera)
    assert np.allclose(key.toward_light, -key_light_direction(up, toward_camera))
    level = toward_camera - toward_camera @ up * up
    assert key.toward_light @ up > 0.5 and rim.toward_light @ up > 0.3, "key and rim from above"
    assert fill.toward_light @ level > 0 > rim.toward_light @ level, "fill from the camera's side, rim from behind"
    assert key.intensity > fill.intensity and key.intensity > rim.intensity
    right = np.cross(up, level)
    assert (key.toward_light @ right) * (fill.toward_light @ right) < 0, "key and fill on opposite sides"
    assert bounce.toward_light @ up < 0 < bounce.toward_light @ level, "the bounce from below, on the camera's side"
    assert bounce.intensity < key.intensity


def test_ambient_occlusion_darkens_the_ground_where_a_body_touches_it_and_nothing_far_from_it():
    """A ball resting on the ground: with ambient occlusion the ground right around the contact darkens, less with
    distance from it, while the ground far from the ball, the ball itself and the backdrop keep their colour."""
    resting = EMPTY.replace("position: [0, 0.5, 0]", "position: [0, 0.2, 0]")
    render = '  ground: {size: 4, grid: false}\n  camera: {position: [0, 0.9, 2.2], focal_point: [0, 0.2, 0]}\n'

    def frame(occlusion: str) -> np.ndarray:
        scene = stages.parse_scene(resting.replace("  camera: {{position: [0, 1.2, 6], focal_point: [0, 0.5, 0]}}\n",
                                                   "").format(render=render + f"  ambient_occlusion: {occlusion}\n"))
        model = api.compile_model(scene)
        trajectory = api.simulate(scene, model=model)
        geometry = stages.frame_geometry(stages.plan(scene, model=model), trajectory)
        with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
            return renderer.draw(0.0, trajectory.positions[0]).astype(int)

    plain, occluded = frame("false"), frame("true")
    darker = (plain - occluded).sum(axis=2)
    ball = (plain[..., 0] - plain[..., 1]) > 20
    rows, columns = np.nonzero(ball)
    middle = int(round(columns.mean()))
    below = [darker[row, middle - 3: middle + 4].mean() for row in range(rows.max() + 3, rows.max() + 40, 6)]
    assert below[0] > 60, "the ground at the contact darkens"
    assert all(a >= b for a, b in zip(below, below[1:])) and below[-1] < below[0] / 3, "less further away"
    inside = ball.copy()  # the ball less its outline, whose pixels blend with the ground's
    for shift in (-3, 3):
        inside &= np.roll(ball, shift, axis=0) & np.roll(ball, shift, axis=1)
    assert np.abs(darker[inside]).max() <= 3, "the ball does not"
    assert np.abs(darker[:20]).max() == 0, "nor the backdrop"
    assert np.abs(darker[-10:, :40]).max() <= 3, "nor the ground far from the ball"


@pytest.mark.slow
def test_the_overlay_draws_the_notes_symbols():
    """π, ω, τ, γ and ≈ (proper time, periods, γ factors) are drawn, not dropped: VTK's own fonts lack them."""
    def ink(label: str) -> int:
        text = EMPTY.replace("show_time: false", "show_time: true").format(
            render=f'  time_label: "{label}"\n  label_size: 0.2\n')
        scene = stages.parse_scene(text)
        model = api.compile_model(scene)
        trajectory = api.simulate(scene, model=model)
        geometry = stages.frame_geometry(stages.plan(scene, model=model), trajectory)
        with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
            corner = renderer.draw(0.0, trajectory.positions[0]).astype(int)[:60, :120]
        return int((np.abs(corner - corner[-1:, -1:]).sum(axis=2) > 150).sum())

    blank = ink("x")
    for symbol in "πωτγ≈":
        assert ink("x" + symbol) > blank + 20, symbol
