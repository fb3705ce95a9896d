"""Velocity, acceleration and force arrows: the vectors against closed forms (gravity m g, quadratic drag −c |v| v,
a resting ball's normal force), and by pixels (a force arrow points along its force, with a legend)."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from animbatch import api, stages
from animbatch.cli import cli
from animbatch.render.backend import select_backend
from animbatch.render.renderer import FrameRenderer

THROW = """
name: throw
duration: 1.0
fps: 30
solver: {method: RK45, rtol: 1.0e-10, atol: 1.0e-12}
bodies: [{name: ball, mass: 0.5, radius: 0.1, position: [0, 1, 0], velocity: [3, 4, 0], color: "#e15759"}]
fields:
  - {type: gravity}
  - {type: drag, model: quadratic, coefficient: 0.05}
render:
  arrows: {show: [velocity, acceleration, forces], length: 0.5}
"""


def geometry_of(text: str):
    scene = stages.parse_scene(text)
    model = api.compile_model(scene)
    trajectory = api.simulate(scene, model=model)
    return scene, model, trajectory, stages.frame_geometry(stages.plan(scene, model=model), trajectory)


def test_force_and_acceleration_arrows_are_the_closed_form_forces_at_each_frame():
    _, _, trajectory, geometry = geometry_of(THROW)
    arrows = geometry.arrows
    vectors = dict(zip(arrows.names, arrows.vectors))
    assert arrows.names == ("velocity", "acceleration", "gravity", "drag"), "no contact term without contacts"
    v = trajectory.velocities[:, 0]
    gravity = np.array([0.0, -9.81 * 0.5, 0.0])
    drag = -0.05 * np.linalg.norm(v, axis=1)[:, None] * v
    assert np.allclose(vectors["velocity"][:, 0], v)
    assert np.allclose(vectors["gravity"][:, 0], gravity, rtol=0, atol=1e-12)
    assert np.allclose(vectors["drag"][:, 0], drag, rtol=0, atol=1e-12)
    assert np.allclose(vectors["acceleration"][:, 0], (gravity + drag) / 0.5, rtol=0, atol=1e-12)
    units = dict(zip(arrows.names, arrows.units))
    assert units == {"velocity": "m/s", "acceleration": "m/s²", "gravity": "N", "drag": "N"}
    scales = dict(zip(arrows.names, arrows.scales))
    assert scales["gravity"] == scales["drag"], "all forces share one scale"
    typical = np.percentile(np.linalg.norm(np.concatenate([vectors["gravity"], vectors["drag"]], axis=1), axis=2), 90)
    assert scales["gravity"] == pytest.approx(0.5 / typical)


RESTING = """
name: rest
duration: 0.5
fps: 30
solver: {method: RK45}
bodies: [{name: ball, mass: 2.0, radius: 0.1, position: [0, 0.1, 0]}]
fields: [{type: gravity}]
colliders: [{type: plane}]
render:
  arrows: {show: [acceleration, forces]}
"""


def test_a_resting_ball_shows_the_normal_force_that_balances_its_weight():
    """Contacts act by impulses, not force terms: their arrow is m a − Σ F, here the normal force +m g on a ball at
    rest on the floor, and its acceleration is zero."""
    _, _, _, geometry = geometry_of(RESTING)
    vectors = dict(zip(geometry.arrows.names, geometry.arrows.vectors))
    assert np.allclose(vectors["contact"][:, 0], [0.0, 2.0 * 9.81, 0.0], atol=1e-6)
    assert np.allclose(vectors["acceleration"][:, 0], 0.0, atol=1e-6)


SIDE = """
name: side
duration: 0.1
fps: 10
bodies: [{name: ball, mass: 1, radius: 0.1, position: [0, 1, 0], color: "#e15759"}]
fields: [{type: gravity}]
render:
  resolution: [320, 240]
  background: white
  show_time: false
  camera: {position: [0, 1, 4], focal_point: [0, 1, 0]}
  arrows: {show: [forces], length: 0.6, legend: {legend}}
"""


@pytest.mark.slow
@pytest.mark.render
def test_a_force_arrow_points_along_its_force_and_the_legend_names_it():
    """Seen from the side, the gravity arrow runs straight down from the ball's centre, 0.6 m long on screen (the
    pinhole scale of the camera); with the legend on, the upper right corner shows it in the arrow's colour."""
    images = []
    for legend in ("false", "true"):
        _, _, trajectory, geometry = geometry_of(SIDE.replace("{legend}", legend))
        scene = stages.parse_scene(SIDE.replace("{legend}", legend))
        with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
            images.append(renderer.draw(0.0, trajectory.positions[0]).astype(int))
    image, with_legend = images
    purple = (image[..., 2] > image[..., 1] + 30) & (image[..., 0] > image[..., 1] + 10)  # gravity's hue
    rows, columns = np.nonzero(purple)
    assert len(rows) > 30, "no gravity arrow"
    pixels_per_metre = 240 / (2 * 4 * np.tan(np.radians(15)))
    assert abs(columns.mean() - 159.5) < 2, "straight down, under the ball"
    assert rows.min() >= 119.5 - 2 and rows.max() == pytest.approx(119.5 + 0.6 * pixels_per_metre, abs=4)
    corner = with_legend[:60, 100:]
    swatch = (corner[..., 2] > corner[..., 1] + 30) & (corner[..., 0] > corner[..., 1] + 10)
    assert swatch.sum() > 6, "the legend's purple swatch"
    text = np.nonzero(np.abs(with_legend[:60] - 255).sum(axis=2) > 60)[1]  # its letters, on the white backdrop
    assert len(text) > 40 and text.max() <= 320 - 4, "the legend's text ends inside the frame, not cut off by it"
    assert np.ptp(text) > 80, "and is wide enough to read"
    assert (np.abs(image[:60, 220:] - 255).sum(axis=2) < 10).all(), "no legend when it is off"


def test_arrows_for_an_unknown_body_or_force_are_refused_with_a_suggestion(tmp_path):
    scene = tmp_path / "throw.yaml"
    scene.write_text(THROW)
    result = CliRunner().invoke(cli, ["validate", str(scene), "--set", "render.arrows.bodies=[bal]"])
    assert result.exit_code == 1
    assert "render.arrows.bodies[0]: unknown body 'bal'; did you mean 'ball'?" in result.output
    result = CliRunner().invoke(cli, ["validate", str(scene), "--set", "render.arrows.forces=[gravty]"])
    assert result.exit_code == 1
    assert "did you mean 'gravity'?" in result.output
