"""Golden frames: one frame each of four bundled scenes, drawn at ``final`` quality (480×270), compared with the
frames kept in ``tests/golden/`` within a tolerance, so that a change to the look shows up as a failing test with
a diff image to inspect, while rounding in the rasteriser does not.

After an intended change of the look, regenerate them and look at them before committing:

    ANIMBATCH_UPDATE_GOLDEN=1 .venv/bin/python -m pytest tests/test_golden.py
"""

from __future__ import annotations

import os

import numpy as np
import pytest
from PIL import Image

from animbatch import api, stages
from animbatch.render.backend import select_backend
from animbatch.render.renderer import FrameRenderer
from support.paths import REPO

pytestmark = pytest.mark.render

GOLDEN = REPO / "tests" / "golden"
#: Each scene, the frame compared, and what it shows.
FRAMES = [
    ("projectile", 20, "a trail, the HUD with energy and speed, a faded ground"),
    ("force_arrows", 40, "velocity, acceleration and force arrows with their legend, a spring, contact shadows"),
    ("camera_moves", 60, "a following camera, a trail, a floor collider drawn as the ground"),
    ("slope_materials", 15, "the built-in materials' physically based looks, shadows on a ramp"),
]
#: Tolerance: the mean difference per channel, and the share of pixels that may differ by more than 16 per channel.
MEAN_TOLERANCE = 1.5
OUTLIER_SHARE = 0.005


def draw_frame(name: str, frame: int) -> np.ndarray:
    """Frame ``frame`` of a bundled scene at final quality, 480×270, simulated only as far as that frame."""
    loaded = stages.load_scene(REPO / "scenes" / f"{name}.yaml")
    duration = (frame + 1) / loaded.spec.fps
    scene = stages.load_scene(REPO / "scenes" / f"{name}.yaml",
                              ["render.quality=final", "render.resolution=[480, 270]", f"duration={duration!r}"])
    model = api.compile_model(scene)
    trajectory = api.simulate(scene, model=model)
    geometry = stages.frame_geometry(stages.plan(scene, model=model), trajectory)
    with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
        return renderer.draw(float(trajectory.times[frame]), trajectory.positions[frame],
                             trajectory.orientations[frame], trajectory.angular_velocities[frame],
                             (trajectory.particles, frame))


@pytest.mark.slow
@pytest.mark.parametrize("name, frame, shows", FRAMES, ids=[name for name, _, _ in FRAMES])
def test_a_frame_looks_as_it_did(name, frame, shows, tmp_path):
    image = draw_frame(name, frame)
    golden = GOLDEN / f"{name}-{frame:03d}.png"
    if os.environ.get("ANIMBATCH_UPDATE_GOLDEN"):
        GOLDEN.mkdir(exist_ok=True)
        Image.fromarray(image).save(golden)
        pytest.skip(f"wrote {golden}")
    assert golden.is_file(), f"no golden frame {golden}; make it with ANIMBATCH_UPDATE_GOLDEN=1"
    expected = np.asarray(Image.open(golden).convert("RGB")).astype(int)
    assert expected.shape == image.shape
    difference = np.abs(image.astype(int) - expected)
    mean, outliers = difference.mean(), (difference.max(axis=2) > 16).mean()
    if mean > MEAN_TOLERANCE or outliers > OUTLIER_SHARE:
        Image.fromarray(image).save(tmp_path / f"{name}-now.png")
        Image.fromarray(np.clip(difference * 4, 0, 255).astype(np.uint8)).save(tmp_path / f"{name}-diff.png")
    assert mean <= MEAN_TOLERANCE and outliers <= OUTLIER_SHARE, (
        f"{name} frame {frame} ({shows}) changed: mean difference {mean:.2f}, {outliers:.2%} of pixels differ by "
        f"more than 16; see {tmp_path}")
