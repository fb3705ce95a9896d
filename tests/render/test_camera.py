"""The camera directs: keyframes, following a body, orbiting, and named cameras rendered into separate videos.

The geometry is checked against closed forms (a follower's lag at constant velocity, a spline through its
keyframes, a circle of an orbit); the renderer's use of it by pixels and by the videos written.
"""

from __future__ import annotations

import math

import imageio_ffmpeg
import numpy as np
import pytest
from click.testing import CliRunner

from animbatch import api, stages
from animbatch.cli import cli
from animbatch.render.backend import select_backend
from animbatch.render.camera import CameraPath, follower
from animbatch.render.frame_geometry import BodyPath
from animbatch.render.renderer import FrameRenderer
from animbatch.scene.schema import CameraSpec
from support.rendering import CHASE
from support.scenarios import on_screen_extent

pytestmark = pytest.mark.render

BOUNDS = np.array([[-1.0, 0.0, -1.0], [1.0, 2.0, 1.0]])


def test_a_follower_trails_a_body_at_constant_velocity_by_exactly_its_lag():
    """A body moving at constant velocity from t = 0, the follower starting on it: two first-order lags of time
    constant τ = lag/2 in series give x(t) = v (t − lag + (lag + t) e^(−t/τ)), matched to round-off at every frame;
    so the follower never passes the body and, settled, sits where the body was ``lag`` seconds before."""
    times = np.linspace(0.0, 4.0, 121)
    velocity = np.array([3.0, 0.0, -1.0])
    positions = times[:, None] * velocity
    lag = 0.4
    track = follower(BodyPath(positions, times, 0.1), lag)
    exact = (times - lag + (lag + times) * np.exp(-2 * times / lag))[:, None] * velocity
    assert np.allclose(track, exact, rtol=0, atol=1e-12)
    assert ((positions - track) @ velocity >= -1e-12).all(), "a critically damped follower does not overshoot"
    assert np.array_equal(follower(BodyPath(positions, times, 0.1), 0.0), positions), "lag 0 locks on"


def test_a_followed_body_is_at_the_focal_point_and_the_camera_keeps_its_offset():
    times = np.linspace(0.0, 2.0, 61)
    positions = np.stack([2 * times, 1 + 0 * times, -times], axis=1)
    spec = CameraSpec(position=[0, 3, 8], focal_point=[0, 1, 0], follow="ball", follow_lag=0)
    path = CameraPath(spec, BOUNDS, followed=BodyPath(positions, times, 0.1))
    for k in (0, 17, 60):
        placement = path.at(float(times[k]))
        assert np.allclose(placement.focal_point, positions[k])
        assert np.allclose(placement.position - placement.focal_point, [0, 2, 8])
    assert path.moves


def test_keyframes_pass_through_their_values_start_and_end_at_rest_and_hold_outside():
    spec = CameraSpec(keyframes=[{"t": 1.0, "position": [0, 2, 10], "focal_point": [0, 1, 0]},
                                 {"t": 3.0, "position": [8, 4, 6], "view_angle": 20}])
    path = CameraPath(spec, BOUNDS)
    start, end = path.at(1.0), path.at(3.0)
    assert np.allclose(start.position, [0, 2, 10]) and np.allclose(end.position, [8, 4, 6])
    assert np.allclose(path.at(0.0).position, [0, 2, 10]) and np.allclose(path.at(9.0).position, [8, 4, 6])
    assert np.allclose(path.at(2.0).position, [4, 3, 8]), "two clamped keyframes: symmetric ease, midpoint halfway"
    h = 1e-4
    for t in (1.0 + h, 3.0 - h):  # at rest at both keyframes: the motion there is second order in time
        moved = np.linalg.norm(path.at(t).position - path.at(t - math.copysign(h, t - 2)).position)
        assert moved < 1e-6
    assert np.allclose(path.at(2.0).focal_point, [0, 1, 0]), "one keyframe with a focal point holds it"
    assert end.view_angle == pytest.approx(20.0) and path.at(1.0).view_angle == pytest.approx(20.0)


def test_an_orbit_turns_the_camera_about_the_vertical_axis_keeping_height_and_distance():
    spec = CameraSpec(position=[0, 3, 5], focal_point=[0, 1, 0], orbit={"period": 8.0})
    path = CameraPath(spec, BOUNDS)
    quarter = path.at(2.0)
    assert np.allclose(quarter.position, [5, 3, 0], atol=1e-12), "a quarter turn (counter-clockwise seen from above)"
    assert np.allclose(quarter.focal_point, [0, 1, 0])
    assert np.allclose(path.at(8.0).position, [0, 3, 5])
    back = CameraPath(CameraSpec(position=[0, 3, 5], focal_point=[0, 1, 0], orbit={"period": -8.0}), BOUNDS)
    assert np.allclose(back.at(2.0).position, [-5, 3, 0], atol=1e-12), "a negative period turns the other way"


def test_a_fitted_orbiting_camera_sees_the_whole_motion_from_every_side():
    bounds = np.array([[-3.0, 0.0, -0.2], [3.0, 1.0, 0.2]])  # long and thin: the worst case for turning
    path = CameraPath(CameraSpec(orbit={"period": 4.0}), bounds)
    corners = np.array([[bounds[i][0], bounds[j][1], bounds[k][2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    for t in np.linspace(0, 4, 33):
        extent = on_screen_extent(path.at(float(t)), 16 / 9, corners, np.zeros(8))
        assert extent.max() <= 1.0, f"a corner leaves the frame at t = {t:.3f} s"


FOLLOW = CHASE + """  show_time: false
  camera: {follow: ball, follow_lag: 0}
"""


@pytest.mark.slow
def test_a_following_camera_keeps_the_body_at_the_centre_of_every_frame():
    """A ball crossing 6 m at 5 m/s stays at the image centre (its red pixels' centroid within 3 px, within 1 px of
    where it was at the first frame) at every frame, where the camera fitted to the whole motion sees it cross."""
    scene = stages.parse_scene(FOLLOW)
    model = api.compile_model(scene)
    trajectory = api.simulate(scene, model=model)
    geometry = stages.frame_geometry(stages.plan(scene, model=model), trajectory)
    with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
        centres = []
        for k in (0, 6, 11):
            image = renderer.draw(float(trajectory.times[k]), trajectory.positions[k]).astype(int)
            rows, columns = np.nonzero((image[..., 0] > 60) & (image[..., 0] > 2 * image[..., 1] + 20))
            assert len(rows) > 50
            centres.append((columns.mean(), rows.mean()))
    assert abs(centres[0][0] - 159.5) < 3 and abs(centres[0][1] - 89.5) < 3, centres  # (lit from above)
    assert np.ptp(np.array(centres), axis=0).max() < 1.0, centres


CAMERAS = FOLLOW.replace("  camera: {follow: ball, follow_lag: 0}\n", """  formats: [mp4]
  cameras:
    side: {position: [2, 1, 8], focal_point: [2, 1, 0]}
    spin: {orbit: {period: 1}}
""")


@pytest.mark.slow
def test_camera_all_renders_every_camera_into_its_own_video_from_one_bake(tmp_path):
    scene = tmp_path / "chase.yaml"
    scene.write_text(CAMERAS)
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["render", str(scene), "--camera", "all", "--out", str(out), "--no-progress",
                                      "--jobs", "1"])
    assert result.exit_code == 0, result.output
    for stem in ("chase", "chase-side", "chase-spin"):
        reader = imageio_ffmpeg.read_frames(str(out / "chase" / f"{stem}.mp4"))
        assert next(reader)["size"] == (320, 180), stem
        reader.close()
        assert imageio_ffmpeg.count_frames_and_secs(str(out / "chase" / f"{stem}.mp4"))[0] == 12, stem
    assert result.output.count("simulate") == 1 and result.output.count("load_cache") == 2, "one bake, reused"
    side = CliRunner().invoke(cli, ["render", str(scene), "--camera", "sied", "--out", str(out), "--no-progress"])
    assert side.exit_code != 0
    assert "render.use_camera: no camera 'sied' in render.cameras; did you mean 'side'? Cameras: side, spin" \
        in side.output


def test_a_followed_body_must_exist_and_be_one_point(tmp_path):
    scene = tmp_path / "chase.yaml"
    scene.write_text(FOLLOW.replace("follow: ball", "follow: bal"))
    result = CliRunner().invoke(cli, ["validate", str(scene)])
    assert result.exit_code == 1
    assert "render.camera.follow: unknown body 'bal'; did you mean 'ball'?" in result.output
    keyframes = FOLLOW.replace("camera: {follow: ball, follow_lag: 0}",
                               "camera: {keyframes: [{t: 1, view_angle: 20}, {t: 0.5, view_angle: 30}]}")
    scene.write_text(keyframes)
    result = CliRunner().invoke(cli, ["validate", str(scene)])
    assert "render.camera.keyframes[1]: keyframe times must increase (t = 0.5 after t = 1)" in result.output
