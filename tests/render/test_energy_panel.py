"""The energy panel under the 3D view: the frame keeps its size, the panel shows the plot, and its cursor moves
with time, linearly from the plot's left edge at t = 0 to its right edge at the end."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import api, stages
from animbatch.render.backend import select_backend
from animbatch.render.panel import CURSOR
from animbatch.render.renderer import FrameRenderer

pytestmark = pytest.mark.render

SCENE = """
name: panel
duration: 2
fps: 10
anchors: [{name: hook, position: [0, 2, 0]}]
bodies: [{name: bob, mass: 0.5, position: [0, 0.8, 0]}]
springs: [{between: [hook, bob], stiffness: 20, damping: 0.5, rest_length: 1}]
fields: [{type: gravity}]
render:
  resolution: [320, 240]
  show_time: false
  energy_panel: {height: 0.4, quantities: [energy, momentum]}
"""


@pytest.mark.slow
def test_the_panel_sits_under_the_view_and_its_cursor_follows_time():
    scene = stages.parse_scene(SCENE)
    model = api.compile_model(scene)
    trajectory = api.simulate(scene, model=model)
    geometry = stages.frame_geometry(stages.plan(scene, model=model), trajectory)
    assert set(geometry.panel.series) == {"kinetic [J]", "potential [J]", "total [J]", "|p| [kg·m/s]"}
    columns = []
    with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
        for k in (0, 10, 19):
            image = renderer.draw(float(trajectory.times[k]), trajectory.positions[k])
            assert image.shape == (240, 320, 3), "the frame keeps the scene's resolution"
            panel = image[240 - 96:]  # 0.4 × 240 px
            cursor = np.all(panel == CURSOR, axis=2)
            assert cursor.sum() > 20, "the cursor is drawn in the panel"
            assert not np.all(image[:240 - 96] == CURSOR, axis=2).any(), "and only there"
            columns.append(np.nonzero(cursor.any(axis=0))[0].mean())
            white = np.all(panel > 240, axis=2).mean()
            assert white > 0.5, "a plot on white"
    times = trajectory.times[[0, 10, 19]]
    slope = (columns[2] - columns[0]) / (times[2] - times[0])
    assert slope > 50, "moves right as time runs"
    assert columns[1] == pytest.approx(columns[0] + slope * (times[1] - times[0]), abs=1.5), "linearly"


def test_scenes_without_a_panel_have_none():
    scene = stages.parse_scene(SCENE.replace("  energy_panel: {height: 0.4, quantities: [energy, momentum]}\n", ""))
    model = api.compile_model(scene)
    trajectory = api.simulate(scene, model=model)
    assert stages.frame_geometry(stages.plan(scene, model=model), trajectory).panel is None
