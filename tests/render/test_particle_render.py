"""Emitted particles on screen: one point cloud per emitter, ramps over life, and frames that do not depend on
which frames were drawn before them (checked by pixels)."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import api
from animbatch.render.backend import select_backend
from animbatch.render.renderer import FrameRenderer
from support.scenes import scene

pytestmark = pytest.mark.render

FOUNTAIN = """
name: fountain
duration: 0.7
fps: 30
seed: 3
solver: {method: verlet, dt: 0.005}
emitters:
  - name: jet
    source: {type: disc, radius: 0.05}
    rate: 800
    lifetime: {mean: 0.5, spread: 0.2}
    speed: {mean: 3, spread: 0.5}
    direction: {cone: 15}
    radius: {mean: 0.02, spread: 0.01}
    color: {mean: orange, spread: 0.2}
    look: {style: sprite, size: [1, 0.3], opacity: [1, 0.2], color: ["#ffffff", "#ff4000"], trail: 3}
fields: [{type: gravity}]
colliders: [{type: plane}]
render:
  resolution: [160, 96]
  background: black
  show_time: false
  camera: {position: [0, 0.4, 2.5], focal_point: [0, 0.4, 0]}
"""

STILL = """
name: still
duration: {duration}
fps: 10
solver: {{method: verlet, dt: 0.01}}
emitters:
  - {{name: dots, bursts: [{{time: 0, count: 40}}], source: {{type: box, size: [1.2, 0.6, 0.01]}}, speed: 0,
     lifetime: 1.0, radius: 0.03, color: white, look: {{style: {style}, size: {size}, opacity: {opacity}}}}}
render:
  resolution: [160, 96]
  background: black
  show_time: false
  camera: {{position: [0, 0, 2.5], focal_point: [0, 0, 0]}}
"""


def draw(loaded, frames: list[int]) -> list[np.ndarray]:
    """Images of the given frames, drawn by one new renderer in that order."""
    model = api.compile_model(loaded)
    trajectory = api.simulate(loaded, model=model)
    geometry = api.frame_geometry(api.plan(loaded, model=model), trajectory)
    with FrameRenderer(loaded.spec.render, geometry, select_backend("auto")) as renderer:
        return [renderer.draw(float(trajectory.times[k]), trajectory.positions[k], trajectory.orientations[k],
                              trajectory.angular_velocities[k], (trajectory.particles, k)) for k in frames]


@pytest.mark.slow
def test_frames_drawn_in_chunks_have_the_same_pixels_as_one_pass():
    """Frames 12–20 drawn after frames 0–11 by one renderer, or by a fresh renderer as a chunk of their own, are
    pixel-identical (trails come from the trajectory, attributes from the serials, not from the renderer's past)."""
    loaded = scene(FOUNTAIN)
    whole = draw(loaded, list(range(21)))
    chunk = draw(loaded, list(range(12, 21)))
    for one, other in zip(whole[12:], chunk):
        assert np.array_equal(one, other)
    assert (whole[20].sum(axis=2) > 100).sum() > 100  # the fountain is on screen


def brightness(image: np.ndarray) -> float:
    return float(image.astype(float).sum())


def test_opacity_fades_over_life_and_dead_particles_vanish():
    """With opacity ramping from 1 to 0 over a 1 s life, particles at age 0.9 s give under 20 % of the light they
    gave at birth, and once dead nothing is drawn."""
    loaded = scene(STILL.format(duration=1.2, style="sprite", size="[1]", opacity="[1, 0]"))
    young, old, dead = draw(loaded, [0, 9, 11])
    assert brightness(young) > 1000 * 255
    assert brightness(old) < 0.2 * brightness(young)
    assert brightness(dead) == 0


@pytest.mark.parametrize("style", ["sprite", "sphere"])
def test_size_ramp_grows_the_particles_on_screen(style):
    """A size ramp from 1 to 3 makes every particle cover several times more pixels late in life."""
    loaded = scene(STILL.format(duration=1.0, style=style, size="[1, 3]", opacity="[1]").replace("count: 40",
                                                                                                  "count: 6"))
    young, old = draw(loaded, [0, 9])
    covered = [(image.sum(axis=2) > 60).sum() for image in (young, old)]
    assert covered[0] > 20 and covered[1] > 4 * covered[0]  # 2.8² = 7.8 times the area at age 0.9 s


@pytest.mark.slow
def test_many_particles_make_no_mesh_per_particle(polydata_built):
    """10 000 live particles are drawn with as many PolyData objects as 10 (one cloud per emitter)."""
    built = polydata_built
    counts = []
    for count in (10, 10000):
        built.clear()
        loaded = scene(STILL.format(duration=0.2, style="sprite", size="[1]", opacity="[1]").replace(
            "count: 40", f"count: {count}"))
        draw(loaded, [0, 1])
        counts.append(len(built))
    assert counts[0] == counts[1]


@pytest.mark.slow
def test_glowing_sprites_add_their_light_where_they_overlap():
    """Sprites are emitted light: four dim particles in one spot are several times as bright as one (additive
    blending), where ordinary alpha blending would leave a stack of opaque dim particles as dim as one."""
    one_spot = STILL.replace("source: {{type: box, size: [1.2, 0.6, 0.01]}}", "source: {{type: point}}")
    centres = []
    for count in (1, 4):
        text = one_spot.format(duration=0.1, style="sprite", size="[1]", opacity="[1]")
        loaded = scene(text.replace("count: 40", f"count: {count}").replace("color: white", 'color: "#303030"'))
        (image,) = draw(loaded, [0])
        centres.append(float(image.astype(float).sum(axis=2).max()))
    assert centres[0] > 20
    assert centres[1] > 2.5 * centres[0], centres
