"""Every example scene in scenes/ renders, and the ones with closed forms behave as their comments say."""

from __future__ import annotations

from pathlib import Path

import imageio_ffmpeg
import numpy as np
import pytest

from animbatch import api
from animbatch.compile.model import compile_scene
from animbatch.sim.invariants import angular_momentum, total_energy
from animbatch.stages import load_scene
from support.paths import REPO

SCENES = sorted((REPO / "scenes").glob("*.yaml"))  # (the templates are validated and graded in test_teaching)


@pytest.mark.slow
@pytest.mark.render
@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_example_scene_renders(path, tmp_path):
    """Each scene renders to an MP4 with the scene's frame count (its first 0.2 s, small, at 15 fps: the physics of
    each scene is tested on its own)."""
    overrides = ["render.resolution=[128, 72]", "fps=15", "duration=0.2"]
    report = api.run(path, out_dir=tmp_path, overrides=overrides)
    video = Path(report.outputs[0])
    frames, _ = imageio_ffmpeg.count_frames_and_secs(str(video))
    assert frames == report.frame_count == load_scene(path, overrides).spec.frame_count == 3
    assert (video.parent / "report.json").is_file()
    # the ledger finds no body inside another (placed so, or a collision missed) in any bundled scene
    assert report.ledger.get("contacts") in (None, {"starts_inside": None, "missed": None})


def test_projectile_scene_lands_when_its_comment_says():
    """The projectile's ball returns to its launch height after 2 v_y / g = 1.427 s."""
    scene = load_scene(REPO / "scenes" / "projectile.yaml", ["fps=240"])
    trajectory = api.simulate(scene)
    height = trajectory.positions[:, 0, 1]
    crossing = trajectory.times[np.argmax((trajectory.times > 0.1) & (height < 0.11))]
    assert crossing == pytest.approx(2 * 7.0 / 9.81, abs=1 / 240)


def test_orbit_scene_conserves_energy_and_angular_momentum():
    """The bundled orbit keeps energy and angular momentum to 1e-8, as its comment promises."""
    scene = load_scene(REPO / "scenes" / "two_body_orbit.yaml")
    model = compile_scene(scene.spec)
    trajectory = api.simulate(scene, model=model)
    y = model.states_from(trajectory.positions, trajectory.velocities, trajectory.orientations,
                          trajectory.angular_velocities)
    energy = total_energy(model, y)
    momentum = angular_momentum(model, y)
    assert np.abs(energy / energy[0] - 1).max() < 1e-8
    assert np.abs(momentum - momentum[0]).max() < 1e-8 * np.linalg.norm(momentum[0])


def test_damped_oscillator_scene_dampings_are_the_stated_ratios():
    """The three springs have damping ratios 0.1, 1 and 2 (ζ = kd / (2 sqrt(ks m)))."""
    spec = load_scene(REPO / "scenes" / "damped_oscillator.yaml").spec
    ratios = [s.damping / (2 * np.sqrt(s.stiffness * 1.0)) for s in spec.springs]
    assert ratios == pytest.approx([0.1, 1.0, 2.0], rel=1e-4)
