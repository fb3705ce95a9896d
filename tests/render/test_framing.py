"""The fitted camera frames everything drawn and keeps it out of the overlays' corners.

Checked by pixels: each frame is drawn twice by the same renderer, once whole and once with only what the camera
frames (the ground, the label and the legend hidden); every pixel of the second that is not the backdrop belongs to
a body, an arrow, a trail, a spring or an anchor. None may lie in the strips reserved for the label and the legend,
nor touch the frame's edge (something cut by the edge runs off the frame). The geometry of the fit itself is
checked against the pinhole projection of the box it fits.
"""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import stages
from animbatch.render.backend import select_backend
from animbatch.render.camera import Reserved, place_camera
from animbatch.render.renderer import FrameRenderer
from animbatch.scene.schema import CameraSpec
from support.paths import REPO
from support.rendering import CHASE, ready_to_draw
from support.scenarios import on_screen_extent

#: A scene, the frames sampled, and why it is here.
SCENES = [
    ("twin_clocks", "a three-line label over a circling body's orbit and its trail"),
    ("force_arrows", "arrows up to twice their typical length, under a six-line legend"),
    ("charged_particles", "trails seven seconds long and velocity arrows under a label"),
]
#: A pixel further than this from the backdrop's colour (per channel, of 255) is something drawn.
DRAWN = 12


def corners(bounds: np.ndarray) -> np.ndarray:
    return np.array([[bounds[i][0], bounds[j][1], bounds[k][2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])


@pytest.mark.parametrize("reserved", [Reserved(0.3, 0.0), Reserved(0.0, 0.25), Reserved(0.2, 0.15)],
                         ids=["top", "bottom", "both"])
@pytest.mark.parametrize("direction", [[0.4, 0.35, 1.0], [0.0, 0.0, 1.0], [0.2, 1.5, 0.3]])
def test_a_fitted_box_stays_between_the_reserved_strips_centred_in_the_room_between_them(reserved, direction):
    bounds = np.array([[-3.0, 0.0, -1.0], [2.0, 1.5, 0.5]])
    spec = CameraSpec(direction=direction, fit_margin=1.0)
    placement = place_camera(spec, bounds, 16 / 9, reserved=reserved)
    points = corners(bounds)
    forward = placement.focal_point - placement.position
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, placement.up)
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    tangent = np.tan(np.radians(placement.view_angle) / 2)
    relative = np.vstack([points, bounds.mean(axis=0)]) - placement.position
    depth = relative @ forward
    height = relative @ up / (depth * tangent)  # −1 at the frame's bottom edge, 1 at the top
    across = np.abs(relative @ right) / (depth * tangent * 16 / 9)
    low, high = reserved.limits
    assert height.min() >= low - 1e-9 and height.max() <= high + 1e-9 and across.max() <= 1 + 1e-9
    # the box's centre midway between the strips, and tight: one limit is touched (it could not come nearer)
    assert abs(height[-1] - (low + high) / 2) < 1e-9
    assert min(high - height.max(), height.min() - low, 1 - across.max()) < 1e-9


def test_with_nothing_reserved_the_camera_aims_at_the_centre_of_the_box():
    bounds = np.array([[-3.0, 0.0, -1.0], [2.0, 1.5, 0.5]])
    placement = place_camera(CameraSpec(fit_margin=1.0), bounds)
    assert np.allclose(placement.focal_point, bounds.mean(axis=0))
    extent = on_screen_extent(placement, 16 / 9, corners(bounds), np.zeros(8))
    assert extent.max() <= 1 + 1e-9 and extent.max() > 0.99  # the symmetric fit touches the frame


def draw_pairs(name: str, samples: int
               ) -> tuple[FrameRenderer, np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
    """A bundled scene at 480×270 without shadows: the renderer, its empty frame (the backdrop alone), and (whole
    frame, what is framed alone) at ``samples`` frames."""
    scene = stages.load_scene(REPO / "scenes" / f"{name}.yaml",
                              ["render.resolution=[480, 270]", "render.shadows=false",
                               "render.ambient_occlusion=false"])
    trajectory, geometry = ready_to_draw(scene)
    pairs = []
    renderer = FrameRenderer(scene.spec.render, geometry, select_backend())
    with renderer:
        for k in np.linspace(0, len(trajectory.times) - 1, samples).round().astype(int):
            arguments = (float(trajectory.times[k]), trajectory.positions[k], trajectory.orientations[k],
                         trajectory.angular_velocities[k], (trajectory.particles, k))
            for actor in renderer.scenery + renderer.overlays:
                actor.SetVisibility(True)
            whole = renderer.draw(*arguments)
            for actor in renderer.scenery + renderer.overlays:
                actor.SetVisibility(False)
            pairs.append((whole, renderer.draw(*arguments)))
        for actor in renderer.plotter.renderer.actors.values():
            actor.SetVisibility(False)
        empty = renderer.draw(*arguments)
    return renderer, empty, pairs


@pytest.mark.slow
@pytest.mark.parametrize("name, shows", SCENES, ids=[name for name, _ in SCENES])
def test_nothing_drawn_enters_the_label_or_legend_or_leaves_the_frame(name, shows):
    renderer, empty, pairs = draw_pairs(name, 6)
    height = renderer.height
    top = int(np.ceil(renderer.reserved.top * height))
    bottom = height - int(np.ceil(renderer.reserved.bottom * height))
    assert top > 0.05 * height, f"{name}: no strip reserved for its label ({shows})"
    for whole, framed in pairs:
        drawn = np.abs(framed.astype(int) - empty.astype(int)).max(axis=2) > DRAWN
        assert drawn.sum() > 100, f"{name}: nothing drawn"
        rows = np.flatnonzero(drawn.any(axis=1))
        assert rows.min() >= top, f"{name}: something drawn {top - rows.min()} px into the top strip ({shows})"
        assert rows.max() < bottom, f"{name}: something drawn into the bottom strip ({shows})"
        columns = np.flatnonzero(drawn.any(axis=0))
        assert columns.min() > 0 and columns.max() < renderer.width - 1, f"{name}: something runs off the frame"
        # and the overlays are drawn where they were reserved: the label's letters in its strip
        letters = np.abs(whole.astype(int) - framed.astype(int)).max(axis=2) > DRAWN
        assert letters[:top].sum() > 50


FOLLOWED = CHASE + """  time_label: "t = {t:.2f} s\\nsecond line\\nthird line"
  camera: {follow: ball, follow_lag: 0}
"""


@pytest.mark.slow
def test_a_following_camera_keeps_the_body_centred_between_the_strips():
    """The ball stays at the middle of the frame's width and of the room under the label, at every frame."""
    scene = stages.parse_scene(FOLLOWED)
    trajectory, geometry = ready_to_draw(scene)
    with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
        top = renderer.reserved.top * renderer.height
        assert top > 0.2 * renderer.height  # three lines
        for k in (0, 6, 11):
            image = renderer.draw(float(trajectory.times[k]), trajectory.positions[k]).astype(int)
            rows, columns = np.nonzero((image[..., 0] > 60) & (image[..., 0] > 2 * image[..., 1] + 20))
            assert len(rows) > 30
            assert abs(columns.mean() - 159.5) < 3 and abs(rows.mean() - (top + renderer.height) / 2) < 3, k


@pytest.mark.slow
def test_a_label_line_too_long_for_the_frame_is_drawn_smaller_until_it_fits():
    long_line = "t = {t:.2f} s   " + "a line far too long for a frame this narrow " * 2
    scene = stages.parse_scene(FOLLOWED.replace('"t = {t:.2f} s\\nsecond line\\nthird line"', repr(long_line)))
    trajectory, geometry = ready_to_draw(scene)
    with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
        whole = renderer.draw(0.0, trajectory.positions[0]).astype(int)
        renderer.overlays[0].SetVisibility(False)
        bare = renderer.draw(0.0, trajectory.positions[0]).astype(int)
    fit = renderer._label_fit
    assert fit is not None and fit.margin < round(scene.spec.render.label_size * 180)  # shrunk
    columns = np.flatnonzero((np.abs(whole - bare).max(axis=2) > DRAWN).any(axis=0))
    assert columns.min() >= fit.margin - 1 and columns.max() <= renderer.width - fit.margin // 2, columns.max()
