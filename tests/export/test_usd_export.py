"""The USD export read back with pxr.Usd: bodies, cloth, emitted particles and the camera against the trajectory they
came from and against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner

from animbatch.cli import cli
from animbatch.trajectory import Trajectory

pxr = pytest.importorskip("pxr", reason="usd-core is not installed: bash scripts/dev.sh setup installs it")
from pxr import Gf, Usd, UsdGeom  # noqa: E402

G = 9.81
OMEGA = 2.0  # rad/s about z
FPS = 20
STEP = 0.005  # s, the cloth's backward Euler step

#: A stone thrown under gravity and a box spinning about its own z axis, far from each other, seen by a fixed camera.
BODIES = f"""
name: throw-and-spin
duration: 1.5
fps: {FPS}
solver: {{method: RK45, rtol: 1.0e-10, atol: 1.0e-12}}
bodies:
  - {{name: stone-1, radius: 0.05, position: [0, 1, 0], velocity: [2, 4, 0.5], color: "#ff0000"}}
  - {{name: box, type: rigid, shape: {{type: box, size: [0.4, 0.2, 0.1]}}, density: 500, position: [5, 5, 5],
     angular_velocity: [0, 0, {OMEGA}]}}
fields: [{{type: gravity, bodies: [stone-1]}}]
render: {{camera: {{position: [3, 2, 9], focal_point: [2, 2, 2], view_angle: 40}}}}
"""

#: Two sheets: one pinned at its top corners, one falling freely (no force stretches it: every vertex falls alike).
CLOTH = f"""
name: sheets
duration: 0.5
fps: {FPS}
solver: {{method: backward_euler, dt: {STEP}, drift_warning: 0.05}}  # BE damps a little
bodies:
  - {{name: pinned, type: cloth, grid: {{size: [0.4, 0.3], resolution: [5, 4]}}, position: [0, 1, 0], density: 0.2,
     structural: {{stiffness: 200}}, pin: [{{corners: [top-left, top-right]}}]}}
  - {{name: falling, type: cloth, grid: {{size: [0.4, 0.3], resolution: [5, 4]}}, position: [2, 1, 0], density: 0.2,
     structural: {{stiffness: 200}}}}
fields: [{{type: gravity}}]
"""

#: Drops shot out of a point in a vacuum, with no force on them: each flies straight at its own constant velocity.
EMITTER = f"""
name: spray
duration: 1.0
fps: {FPS}
seed: 3
solver: {{method: verlet, dt: 0.005}}
emitters:
  - name: nozzle
    source: {{type: point, position: [0, 0, 0]}}
    rate: 200
    lifetime: {{mean: 0.4, spread: 0.1}}
    speed: {{mean: 2.0, spread: 0.5}}
    direction: {{axis: [0, 1, 0], cone: 30}}
    radius: {{mean: 0.01, spread: 0.004}}
    color: {{mean: "#3366ff", spread: 0.1}}
"""


#: A floor and a box pushed along x at 0.8 m/s by keyframes (linear: constant velocity), beside a resting ball.
COLLIDERS = f"""
name: pusher
duration: 1
fps: {FPS}
solver: {{method: verlet, dt: 0.005}}
bodies: [{{name: ball, radius: 0.1, position: [0, 0.1, 3]}}]
colliders:
  - {{type: plane, size: 6, color: "#808080"}}
  - {{type: box, position: [0, 0.25, 0], size: [0.4, 0.5, 0.3], interpolation: linear,
     keyframes: [{{time: 0, offset: [0, 0, 0]}}, {{time: 1, offset: [0.8, 0, 0]}}]}}
  - {{type: box, position: [5, 0, 0], size: [1, 1, 1], visible: false}}
fields: [{{type: gravity}}]
"""


def export_usd(folder, text: str, name: str) -> tuple[Usd.Stage, Trajectory]:
    (folder / "scene.yaml").write_text(text)
    result = CliRunner().invoke(cli, ["export", "scene.yaml", "--format", "usd", "--no-progress"])
    assert result.exit_code == 0, result.output
    stage = Usd.Stage.Open(str(folder / "renders" / name / f"{name}.usdc"))
    trajectory = Trajectory.load(next((folder / "renders" / name / "cache").glob("*.npz")))
    return stage, trajectory


def world_transform(stage: Usd.Stage, path: str, frame: float) -> np.ndarray:
    """The prim's 4×4 local-to-world matrix at a time code, as column vectors act on it (x_world = M x)."""
    xformable = UsdGeom.Xformable(stage.GetPrimAtPath(path))
    return np.array(xformable.ComputeLocalToWorldTransform(Usd.TimeCode(frame))).T


def test_the_stage_is_in_metres_y_up_at_the_scenes_fps(tmp_cwd):
    stage, trajectory = export_usd(tmp_cwd, BODIES, "throw-and-spin")
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0 and UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert stage.GetTimeCodesPerSecond() == FPS and stage.GetFramesPerSecond() == FPS
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0, trajectory.frame_count - 1) == (0, 29)
    assert stage.GetDefaultPrim().GetPath() == "/World"


def test_bodies_move_as_the_trajectory_and_the_closed_forms_say(tmp_cwd):
    """At several frame times the stone's world position is the trajectory's to round-off and x₀ + v₀t + ½gt²; the
    box's orientation is the trajectory's quaternion and the free spin (cos ωt/2, 0, 0, sin ωt/2)."""
    stage, trajectory = export_usd(tmp_cwd, BODIES, "throw-and-spin")
    stone, box = trajectory.body_names.index("stone-1"), trajectory.body_names.index("box")
    # an invalid identifier becomes a valid prim name; the scene's name is kept on the prim
    prim = stage.GetPrimAtPath("/World/Bodies/stone_1")
    assert prim.IsValid() and prim.GetCustomDataByKey("animbatch:name") == "stone-1"
    for frame in (0, 7, 18, 29):
        t = frame / FPS
        assert trajectory.times[frame] == pytest.approx(t)
        matrix = world_transform(stage, "/World/Bodies/stone_1", frame)
        expected = np.array([0, 1, 0]) + np.array([2, 4, 0.5]) * t + 0.5 * np.array([0, -G, 0]) * t**2
        assert np.abs(matrix[:3, 3] - trajectory.positions[frame, stone]).max() < 1e-12
        assert np.allclose(matrix[:3, 3], expected, atol=1e-8)
        assert np.allclose(matrix[:3, :3], np.eye(3), atol=1e-12)

        orient = UsdGeom.Xformable(stage.GetPrimAtPath("/World/Bodies/box")).GetOrderedXformOps()[1]
        quaternion = orient.Get(Usd.TimeCode(frame))
        as_array = np.array([quaternion.GetReal(), *quaternion.GetImaginary()])
        assert np.abs(as_array - trajectory.orientations[frame, box]).max() < 1e-15
        spin = np.array([math.cos(OMEGA * t / 2), 0, 0, math.sin(OMEGA * t / 2)])
        assert min(np.abs(as_array - spin).max(), np.abs(as_array + spin).max()) < 1e-7
        rotation = world_transform(stage, "/World/Bodies/box", frame)[:3, :3]
        turn = np.array([[math.cos(OMEGA * t), -math.sin(OMEGA * t), 0], [math.sin(OMEGA * t), math.cos(OMEGA * t), 0],
                         [0, 0, 1]])
        assert np.allclose(rotation, turn, atol=1e-6)
        assert np.allclose(world_transform(stage, "/World/Bodies/box", frame)[:3, 3], [5, 5, 5], atol=1e-12)


def test_many_particles_become_one_points_prim_that_follows_the_trajectory(tmp_cwd):
    """300 particles (more than PARTICLE_PRIMS_LIMIT) in a row, each thrown up at its own speed: one Points prim
    whose ids are the particles' places in the trajectory, whose widths are their diameters, and whose points at
    each frame are y = v t − ½ g t² (float32)."""
    from animbatch.export.usd import PARTICLE_PRIMS_LIMIT

    count = 300
    assert count > PARTICLE_PRIMS_LIMIT
    bodies = "\n".join(f"  - {{name: p{k}, radius: 0.01, position: [{0.05 * k}, 0, 0], velocity: [0, {1 + k / 100}, 0]}}"
                       for k in range(count))
    stage, trajectory = export_usd(tmp_cwd, f"""
name: row
duration: 0.5
fps: {FPS}
solver: {{method: RK45, rtol: 1.0e-10, atol: 1.0e-12}}
bodies:
{bodies}
fields: [{{type: gravity}}]
""", "row")
    assert not stage.GetPrimAtPath("/World/Bodies").IsValid()
    points = UsdGeom.Points(stage.GetPrimAtPath("/World/Particles"))
    assert list(points.GetIdsAttr().Get()) == list(range(count))
    assert np.allclose(points.GetWidthsAttr().Get(), 0.02)
    speeds = 1 + np.arange(count) / 100
    for frame in (0, 4, 9):
        t = frame / FPS
        where = np.array(points.GetPointsAttr().Get(Usd.TimeCode(frame)))
        assert np.array_equal(where, trajectory.positions[frame].astype(np.float32))
        assert np.allclose(where[:, 1], speeds * t - 0.5 * G * t**2, atol=1e-6)


def test_shapes_have_the_scenes_sizes_and_colours(tmp_cwd):
    """The box's mesh spans 0.4 × 0.2 × 0.1 m around its centre of mass, with the outward normal of its face at
    each of its (split) vertices; the stone is a sphere of radius 0.05 m, red (sRGB #ff0000 is linear (1, 0, 0))."""
    stage, _ = export_usd(tmp_cwd, BODIES, "throw-and-spin")
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Bodies/box"))
    points = np.array(mesh.GetPointsAttr().Get())
    assert np.allclose(points.max(axis=0), [0.2, 0.1, 0.05], atol=1e-6)
    assert np.allclose(points.min(axis=0), [-0.2, -0.1, -0.05], atol=1e-6)
    assert set(mesh.GetFaceVertexCountsAttr().Get()) == {3}
    assert mesh.GetSubdivisionSchemeAttr().Get() == UsdGeom.Tokens.none
    # crisp faces: every vertex normal is a face normal of the box, pointing outwards
    normals = np.array(mesh.GetNormalsAttr().Get())
    assert mesh.GetNormalsInterpolation() == UsdGeom.Tokens.vertex and len(normals) == len(points)
    assert np.allclose(np.abs(normals).max(axis=1), 1, atol=1e-6)
    outward = np.sign(points) * (np.abs(normals) > 0.5)
    assert np.allclose(normals, outward, atol=1e-6)
    sphere = UsdGeom.Sphere(stage.GetPrimAtPath("/World/Bodies/stone_1"))
    assert sphere.GetRadiusAttr().Get() == pytest.approx(0.05)
    assert np.allclose(sphere.GetDisplayColorAttr().Get()[0], [1, 0, 0])


@pytest.mark.slow
def test_colliders_are_meshes_and_a_moving_one_moves_as_its_keyframes_say(tmp_cwd):
    """The floor is a 6 m square at y = 0; the box's mesh spans its size around its position; at frame k the box's
    transform moves it by the linear keyframes' offset (0.8 t, 0, 0); the invisible collider is left out."""
    stage, _ = export_usd(tmp_cwd, COLLIDERS, "pusher")
    assert [prim.GetName() for prim in stage.GetPrimAtPath("/World/Colliders").GetChildren()] == ["plane_0", "box_1"]
    floor = np.array(UsdGeom.Mesh(stage.GetPrimAtPath("/World/Colliders/plane_0")).GetPointsAttr().Get())
    assert np.allclose(floor[:, 1], 0) and np.allclose(np.ptp(floor, axis=0), [6, 0, 6], atol=1e-6)
    box = np.array(UsdGeom.Mesh(stage.GetPrimAtPath("/World/Colliders/box_1")).GetPointsAttr().Get())
    assert np.allclose(box.min(axis=0), [-0.2, 0, -0.15], atol=1e-6)
    assert np.allclose(box.max(axis=0), [0.2, 0.5, 0.15], atol=1e-6)
    assert not UsdGeom.Xformable(stage.GetPrimAtPath("/World/Colliders/plane_0")).TransformMightBeTimeVarying()
    for frame in (0, 5, 13, 19):
        matrix = world_transform(stage, "/World/Colliders/box_1", frame)
        assert np.allclose(matrix[:3, :3], np.eye(3), atol=1e-12)
        assert np.allclose(matrix[:3, 3], [0.8 * frame / FPS, 0, 0], atol=1e-12)


def test_the_camera_is_the_renders_camera(tmp_cwd):
    """Placed at the scene's camera position, looking at its focal point, with its vertical field of view."""
    stage, _ = export_usd(tmp_cwd, BODIES, "throw-and-spin")
    camera = UsdGeom.Camera(stage.GetPrimAtPath("/World/Camera")).GetCamera(Usd.TimeCode(10))
    assert camera.GetFieldOfView(Gf.Camera.FOVVertical) == pytest.approx(40, abs=1e-4)
    frustum = camera.frustum
    assert np.allclose(frustum.GetPosition(), [3, 2, 9], atol=1e-9)
    towards = np.array([2, 2, 2]) - np.array([3, 2, 9])
    assert np.allclose(frustum.ComputeViewDirection(), towards / np.linalg.norm(towards), atol=1e-9)
    lights = [prim.GetName() for prim in stage.GetPrimAtPath("/World/Lights").GetChildren()]
    assert lights == ["key", "fill", "rim", "bounce"]
    # a distant light shines along its -Z axis: the key comes from above and the camera's side, the rim from behind
    def shines_from(name: str) -> np.ndarray:
        return world_transform(stage, f"/World/Lights/{name}", 0)[:3, 2]

    to_camera = (np.array([3, 2, 9]) - np.array([2, 2, 2])) / np.linalg.norm([1, 0, 7])
    assert shines_from("key")[1] > 0.3 and shines_from("key") @ to_camera > 0
    assert shines_from("rim") @ to_camera < 0 and shines_from("rim")[1] > 0


def test_a_keyframed_camera_is_at_its_keys_at_their_times(tmp_cwd):
    """A dolly with a zoom: at each key's time (frames 0, 10, 20 at 20 fps) the stage's camera is at the key's
    position, looks at its focal point, with its view angle."""
    keys = [(0.0, [0, 1, 6], 50), (0.5, [2, 1, 4], 35), (1.0, [4, 2, 2], 20)]
    keyframes = ", ".join(f"{{t: {t}, position: {p}, focal_point: [0, 1, 0], view_angle: {a}}}" for t, p, a in keys)
    stage, _ = export_usd(tmp_cwd, BODIES.replace("render: {camera: {position: [3, 2, 9], focal_point: [2, 2, 2], "
                                                  "view_angle: 40}}",
                                                  f"render: {{camera: {{keyframes: [{keyframes}]}}}}"),
                          "throw-and-spin")
    prim = UsdGeom.Camera(stage.GetPrimAtPath("/World/Camera"))
    for t, position, angle in keys:
        camera = prim.GetCamera(Usd.TimeCode(round(t * FPS)))
        assert camera.GetFieldOfView(Gf.Camera.FOVVertical) == pytest.approx(angle, abs=1e-4)
        assert np.allclose(camera.frustum.GetPosition(), position, atol=1e-9)
        towards = np.array([0, 1, 0]) - np.array(position)
        assert np.allclose(camera.frustum.ComputeViewDirection(), towards / np.linalg.norm(towards), atol=1e-9)


def test_cloth_keeps_its_triangles_and_moves_as_simulated(tmp_cwd):
    """Each sheet is one mesh of 2·4·3 = 24 triangles, the same at every frame (not sampled over time); the pinned
    corners stay where they started; every vertex of the free sheet falls alike (no force stretches it), by backward
    Euler's fall after n steps of h, g h² n(n+1)/2 (the closed form of v_{k+1} = v_k + h g, x_{k+1} = x_k + h v_{k+1}),
    to float32 round-off."""
    stage, trajectory = export_usd(tmp_cwd, CLOTH, "sheets")
    pinned = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Deformables/pinned"))
    falling = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Deformables/falling"))
    for mesh in (pinned, falling):
        assert not mesh.GetFaceVertexIndicesAttr().ValueMightBeTimeVarying()
        assert len(mesh.GetFaceVertexCountsAttr().Get()) == 24
        assert mesh.GetPointsAttr().GetNumTimeSamples() == trajectory.frame_count
    start = np.array(falling.GetPointsAttr().Get(Usd.TimeCode(0)))
    assert start.shape == (20, 3)
    assert np.allclose(np.ptp(start, axis=0), [0.4, 0.3, 0], atol=1e-6)
    start_pinned = np.array(pinned.GetPointsAttr().Get(Usd.TimeCode(0)))
    top = np.flatnonzero(np.isclose(start_pinned[:, 1], start_pinned[:, 1].max()))
    corners = top[[np.argmin(start_pinned[top, 0]), np.argmax(start_pinned[top, 0])]]
    for frame in (3, 9):
        t = frame / FPS
        now = np.array(falling.GetPointsAttr().Get(Usd.TimeCode(frame)))
        steps = round(t / STEP)
        assert np.allclose(now, start + [0, -G * STEP**2 * steps * (steps + 1) / 2, 0], atol=2e-6)
        hanging = np.array(pinned.GetPointsAttr().Get(Usd.TimeCode(frame)))
        assert np.allclose(hanging[corners], start_pinned[corners], atol=1e-7)
        assert hanging[:, 1].min() < start_pinned[:, 1].min() - 0.01  # the rest of it sags


@pytest.mark.slow
def test_emitted_particles_keep_their_ids_and_attributes(tmp_cwd):
    """The points at each frame are the trajectory's live particles, id for serial; a particle keeps its id as it
    flies: over three frames its positions are equally spaced on a line (constant velocity), its age grows by one
    frame's time, and its width stays 2 × its radius within the emitter's bounds."""
    stage, trajectory = export_usd(tmp_cwd, EMITTER, "spray")
    points = UsdGeom.Points(stage.GetPrimAtPath("/World/Emitters/nozzle"))
    age = UsdGeom.PrimvarsAPI(points).GetPrimvar("age")
    record = trajectory.particles[0]
    tracked = 0
    for frame in range(trajectory.frame_count):
        ids = np.array(points.GetIdsAttr().Get(Usd.TimeCode(frame)))
        positions = np.array(points.GetPointsAttr().Get(Usd.TimeCode(frame)))
        live = record.serials[frame] >= 0
        assert np.array_equal(ids, record.serials[frame][live])
        assert np.array_equal(positions, record.positions[frame][live])
        widths = np.array(points.GetWidthsAttr().Get(Usd.TimeCode(frame)))
        assert np.all((widths >= 2 * 0.006 - 1e-7) & (widths <= 2 * 0.014 + 1e-7))
        if frame + 2 < trajectory.frame_count:
            later = [dict(zip(np.array(points.GetIdsAttr().Get(Usd.TimeCode(k))),
                              np.array(points.GetPointsAttr().Get(Usd.TimeCode(k))))) for k in (frame + 1, frame + 2)]
            ages = [dict(zip(np.array(points.GetIdsAttr().Get(Usd.TimeCode(k))), np.array(age.Get(Usd.TimeCode(k)))))
                    for k in (frame, frame + 1)]
            for serial, here in zip(ids, positions):
                if serial in later[0] and serial in later[1]:
                    step1, step2 = later[0][serial] - here, later[1][serial] - later[0][serial]
                    assert np.allclose(step1, step2, atol=1e-5) and np.linalg.norm(step1) > 0.05 / FPS
                    assert ages[1][serial] - ages[0][serial] == pytest.approx(1 / FPS, abs=1e-5)
                    tracked += 1
    assert tracked > 100


def test_usd_export_without_usd_core_says_what_to_install(tmp_cwd, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "pxr", None)
    (tmp_cwd / "scene.yaml").write_text(BODIES)
    result = CliRunner().invoke(cli, ["export", "scene.yaml", "--format", "usd", "--no-progress"])
    assert result.exit_code != 0
    assert result.exit_code == 5 and "usd-core" in result.output and "pip install" in result.output
    assert not list((tmp_cwd / "renders" / "throw-and-spin").glob("*.usd*"))
