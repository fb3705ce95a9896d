"""A USD stage of a run, for Blender, Houdini and any other tool that reads Universal Scene Description.

The stage is in metres (``metersPerUnit = 1``), with the scene's up axis (``upAxis`` Y or Z, from the camera's
``up``) and one time code per frame at the scene's fps (time code ``k`` is time ``k / fps`` s). Layout::

    /World                      Xform, the default prim
      Bodies/<name>             Mesh of a rigid body's shape around its centre of mass, or Sphere of a particle, moved
                                by translate (double) and orient (quaternion, double) sampled at every frame
      Particles                 Points (instead of Bodies/<name>, when a scene has more than 256 particles):
                                positions, widths, ids = the particles' order in the trajectory
      Colliders/<type>_<k>      Mesh of the k-th visible collider where it starts (a plane as the square drawn);
                                a moving one has a transform sampled at every frame
      Deformables/<name>        Mesh of a cloth or lattice: fixed triangles, points sampled at every frame
      Emitters/<name>           Points of an emitter's live particles at each frame: positions, ids (the particle's
                                serial, the same all its life), widths (2 × radius), primvars displayColor,
                                displayOpacity and age [s] per particle
      Camera                    Camera: the render's camera at every frame (transform, vertical field of view)
      Lights/key, fill, rim     DistantLight: the three-point rig the renderer lights the scene with

Prim names are the scene's names made valid USD identifiers (``ball-1`` becomes ``ball_1``); each prim keeps the
scene's name in its ``customData`` as ``animbatch:name``. Colours are linear RGB primvars (``displayColor``). Meshes
carry ``subdivisionScheme = none`` so that importers draw the triangles the simulation used.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from animbatch.errors import ExportError
from animbatch.export.vertices import deformable_vertices, own_particles
from animbatch.files import atomic_path
from animbatch.render.camera import CameraPath
from animbatch.render.colors import COLLIDER_COLOR, hex_to_rgb
from animbatch.render.emitted import ParticleAppearance
from animbatch.render.studio import three_point_rig
from animbatch.render.surfaces import collider_surface, shape_mesh
from animbatch.trajectory import Trajectory

#: Up to this many particles each become a prim of their own (an object to pick in Blender); more become one Points.
PARTICLE_PRIMS_LIMIT = 256
#: Triangles around a sphere's or cylinder's axis in the rigid bodies' meshes.
MESH_RESOLUTION = 32
#: Film back height of the camera in tenths of a scene unit, as USD defines lens sizes: 0.24 tenths of a metre is the
#: 24 mm of a 35 mm film back (Blender shows a 24 mm sensor and a focal length in mm). Only the ratio sets the view.
APERTURE = 0.24


def _pxr() -> Any:
    try:
        import pxr  # heavy: only when exporting USD
        from pxr import Gf, Sdf, Tf, Usd, UsdGeom, UsdLux, Vt  # noqa: F401
    except ImportError:
        raise ExportError("USD export needs the usd-core package: pip install 'animbatch[usd]' (or usd-core), or "
                          "run 'bash scripts/dev.sh setup', which installs it") from None
    return pxr


def prim_names(names: list[str] | tuple[str, ...]) -> list[str]:
    """Valid, distinct USD prim names for scene names, in order (``ball-1`` -> ``ball_1``; repeats get ``_2``…)."""
    from pxr import Tf

    taken: set[str] = set()
    result = []
    for name in names:
        base = Tf.MakeValidIdentifier(name)
        candidate, k = base, 1
        while candidate in taken:
            k += 1
            candidate = f"{base}_{k}"
        taken.add(candidate)
        result.append(candidate)
    return result


def write_usd(trajectory: Trajectory, geometry: Any, render: Any, fps: float, path: str | Path) -> Path:
    """Write the run as a USD stage at ``path`` (``.usd``, ``.usdc`` or ``.usda``; atomically) and return it.
    ``geometry``: the scene's :class:`~animbatch.render.frame_geometry.FrameGeometry`; ``render``: its render spec
    (camera, up axis, resolution); ``fps``: the scene's frames per second."""
    pxr = _pxr()
    Usd, UsdGeom = pxr.Usd, pxr.UsdGeom
    stage = Usd.Stage.CreateInMemory()
    up = np.asarray(render.active_camera.up, float)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if abs(up[2]) > max(abs(up[0]), abs(up[1]))
                           else UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetTimeCodesPerSecond(fps)
    stage.SetFramesPerSecond(fps)
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(max(trajectory.frame_count - 1, 0))
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    width, height = render.resolution
    camera = CameraPath(render.active_camera, geometry.bounds, width / height, geometry.followed)
    writer = _StageWriter(pxr, stage, trajectory, geometry)
    writer.bodies()
    writer.colliders()
    writer.deformables()
    writer.emitters()
    writer.camera(camera, width / height)
    writer.lights(camera)
    with atomic_path(path) as temporary:
        if not stage.GetRootLayer().Export(str(temporary)):
            raise ExportError(f"USD could not write {temporary}")
    return Path(path)


class _StageWriter:
    """Defines the prims of one stage and sets their samples, frame by frame."""

    def __init__(self, pxr: Any, stage: Any, trajectory: Trajectory, geometry: Any) -> None:
        self.pxr, self.stage, self.trajectory, self.geometry = pxr, stage, trajectory, geometry
        self.frames = range(trajectory.frame_count)

    def _define(self, kind: Any, path: str, name: str) -> Any:
        prim = kind.Define(self.stage, path)
        prim.GetPrim().SetCustomDataByKey("animbatch:name", name)
        return prim

    def _color(self, gprim: Any, color: str) -> None:
        gprim.CreateDisplayColorAttr([self.pxr.Gf.Vec3f(*linear_rgb(np.asarray(hex_to_rgb(color))).tolist())])

    def _solid(self, path: str, name: str, surface: Any, color: str) -> Any:
        """A Mesh of a rigid shape or collider (a PyVista surface), with normals split at edges sharper than 40°, as
        the renderer draws it: crisp boxes, smooth spheres."""
        Vt, UsdGeom = self.pxr.Vt, self.pxr.UsdGeom
        surface = surface.triangulate().compute_normals(split_vertices=True, feature_angle=40.0)
        mesh = self._mesh(path, name, np.asarray(surface.points), surface.regular_faces, color)
        mesh.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(np.asarray(surface.point_data["Normals"], np.float32)))
        mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
        return mesh

    def _mesh(self, path: str, name: str, points: np.ndarray, triangles: np.ndarray, color: str) -> Any:
        Vt, UsdGeom = self.pxr.Vt, self.pxr.UsdGeom
        mesh = self._define(UsdGeom.Mesh, path, name)
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(triangles), 3, np.int32)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(triangles, np.int32).ravel()))
        mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(points, np.float32)))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        self._color(mesh, color)
        return mesh

    def bodies(self) -> None:
        """Particles and rigid bodies: a Mesh or Sphere each, moved at every frame; or one Points for many
        particles."""
        pxr, trajectory, geometry = self.pxr, self.trajectory, self.geometry
        Gf, UsdGeom = pxr.Gf, pxr.UsdGeom
        particles = own_particles(geometry)
        rigid_first = len(geometry.particle_radius)
        rigid = range(rigid_first, rigid_first + len(geometry.rigid_shapes))
        many = len(particles) > PARTICLE_PRIMS_LIMIT
        if many:
            self._particle_points(particles)
        members = ([] if many else list(particles)) + list(rigid)
        if not members:
            return
        UsdGeom.Scope.Define(self.stage, "/World/Bodies")
        names = prim_names([trajectory.body_names[k] for k in members])
        for index, prim_name in zip(members, names):
            # the shape itself carries the motion (no Xform above it): importers name the object after the body
            path, name = f"/World/Bodies/{prim_name}", trajectory.body_names[index]
            if index >= rigid_first:
                b = index - rigid_first
                surface = shape_mesh(geometry.rigid_shapes[b], MESH_RESOLUTION)
                shape = self._solid(path, name, surface.translate(-geometry.rigid_centre[b]), geometry.colors[index])
            else:
                shape = self._define(UsdGeom.Sphere, path, name)
                shape.CreateRadiusAttr(float(geometry.particle_radius[index]))
                self._color(shape, geometry.colors[index])
            translate = shape.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble)
            orient = shape.AddOrientOp(UsdGeom.XformOp.PrecisionDouble)
            for frame in self.frames:
                translate.Set(Gf.Vec3d(*trajectory.positions[frame, index].tolist()), frame)
                w, x, y, z = trajectory.orientations[frame, index].tolist()
                orient.Set(Gf.Quatd(w, x, y, z), frame)

    def colliders(self) -> None:
        """The visible colliders as meshes where they start (planes as squares around the motion, as drawn); a
        moving one carries its pose at every frame as a transform."""
        Gf, UsdGeom = self.pxr.Gf, self.pxr.UsdGeom
        geometry = self.geometry
        colliders = geometry.colliders
        if not colliders:
            return
        UsdGeom.Scope.Define(self.stage, "/World/Colliders")
        colors = [look[0] for look in geometry.collider_looks] or [c.color or COLLIDER_COLOR for c in colliders]
        names = [f"{collider.kind}_{k}" for k, collider in enumerate(colliders)]
        for collider, name, color in zip(colliders, names, colors):
            surface = collider_surface(collider, geometry.bounds, MESH_RESOLUTION)
            mesh = self._solid(f"/World/Colliders/{name}", name, surface, color)
            if collider.track is not None:
                transform = mesh.AddTransformOp()
                for frame in self.frames:
                    matrix = np.asarray(collider.track.at(float(self.trajectory.times[frame])), float)
                    transform.Set(Gf.Matrix4d(*matrix.T.ravel().tolist()), frame)

    def _particle_points(self, particles: np.ndarray) -> None:
        Vt, UsdGeom = self.pxr.Vt, self.pxr.UsdGeom
        points = self._define(UsdGeom.Points, "/World/Particles", "particles")
        points.CreateIdsAttr(Vt.Int64Array.FromNumpy(particles.astype(np.int64)))
        points.CreateWidthsAttr(Vt.FloatArray.FromNumpy((2 * self.geometry.particle_radius[particles])
                                                        .astype(np.float32)))
        colors = linear_rgb(np.array([hex_to_rgb(self.geometry.colors[k]) for k in particles])).astype(np.float32)
        points.CreateDisplayColorPrimvar(UsdGeom.Tokens.vertex).Set(Vt.Vec3fArray.FromNumpy(colors))
        attribute = points.CreatePointsAttr()
        for frame in self.frames:
            positions = self.trajectory.positions[frame, particles].astype(np.float32)
            attribute.Set(Vt.Vec3fArray.FromNumpy(positions), frame)

    def deformables(self) -> None:
        """Each cloth and lattice: a Mesh whose triangles stay and whose points move."""
        geometry, Vt = self.geometry, self.pxr.Vt
        if geometry.surfaces is None:
            return
        self.pxr.UsdGeom.Scope.Define(self.stage, "/World/Deformables")
        bodies = geometry.surfaces.patches
        meshes = []
        for body, prim_name, (front, _back) in zip(bodies, prim_names([b.name for b in bodies]),
                                                   geometry.surface_colors):
            points = np.zeros((body.stop - body.start, 3))
            mesh = self._mesh(f"/World/Deformables/{prim_name}", body.name, points, body.triangles, front)
            mesh.CreateDoubleSidedAttr(True)
            meshes.append(mesh.GetPointsAttr())
        for frame in self.frames:
            vertices = deformable_vertices(geometry, self.trajectory, frame)
            for body, attribute in zip(bodies, meshes):
                attribute.Set(Vt.Vec3fArray.FromNumpy(vertices[body.start:body.stop].astype(np.float32)), frame)

    def emitters(self) -> None:
        """Each emitter: a Points of its live particles at every frame, with ids that follow each particle."""
        Vt, UsdGeom, Sdf = self.pxr.Vt, self.pxr.UsdGeom, self.pxr.Sdf
        records = self.trajectory.particles
        if not records:
            return
        UsdGeom.Scope.Define(self.stage, "/World/Emitters")
        for frames, emitter, prim_name in zip(records, self.geometry.emitters,
                                              prim_names([r.name for r in records])):
            points = self._define(UsdGeom.Points, f"/World/Emitters/{prim_name}", frames.name)
            api = UsdGeom.PrimvarsAPI(points)
            attributes = (points.CreatePointsAttr(), points.CreateIdsAttr(), points.CreateWidthsAttr(),
                          points.CreateDisplayColorPrimvar(UsdGeom.Tokens.vertex),
                          points.CreateDisplayOpacityPrimvar(UsdGeom.Tokens.vertex),
                          api.CreatePrimvar("age", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.vertex))
            appearance = ParticleAppearance(emitter)
            for frame in self.frames:
                serials, size, opacity, color = appearance.at(frames, frame)
                live = serials >= 0
                values = (Vt.Vec3fArray.FromNumpy(frames.positions[frame][live].astype(np.float32)),
                          Vt.Int64Array.FromNumpy(serials[live]),
                          Vt.FloatArray.FromNumpy((2 * size[live]).astype(np.float32)),
                          Vt.Vec3fArray.FromNumpy(linear_rgb(color[live]).astype(np.float32)),
                          Vt.FloatArray.FromNumpy(opacity[live].astype(np.float32)),
                          Vt.FloatArray.FromNumpy(frames.ages[frame][live].astype(np.float32)))
                for attribute, value in zip(attributes, values):
                    attribute.Set(value, frame)

    def camera(self, path: CameraPath, aspect: float) -> None:
        """The render's camera (``path``, at the frames' ``aspect``): its placement and field of view at every frame
        (once when it stands still)."""
        Gf, UsdGeom = self.pxr.Gf, self.pxr.UsdGeom
        camera = self._define(UsdGeom.Camera, "/World/Camera", "camera")
        camera.CreateVerticalApertureAttr(APERTURE)
        camera.CreateHorizontalApertureAttr(APERTURE * aspect)
        reach = max(float(np.linalg.norm(self.geometry.bounds[1] - self.geometry.bounds[0])), 1e-3)
        camera.CreateClippingRangeAttr(Gf.Vec2f(1e-3 * reach, 100 * reach))
        focal_length, transform = camera.CreateFocalLengthAttr(), camera.AddTransformOp()
        times = self.trajectory.times
        for frame in self.frames if path.moves else range(min(1, self.trajectory.frame_count)):
            placement = path.at(float(times[frame]))
            when = frame if path.moves else self.pxr.Usd.TimeCode.Default()
            focal_length.Set(APERTURE / 2 / math.tan(math.radians(placement.view_angle) / 2), when)
            matrix = _look_at(placement.position, placement.focal_point, placement.up)
            transform.Set(Gf.Matrix4d(*matrix.ravel().tolist()), when)

    def lights(self, camera: CameraPath) -> None:
        """The renderer's rig as distant lights (intensities relative: key 0.8, fill 0.4, rim 0.3, bounce 0.35),
        placed from the camera at the start, as the renderer places them."""
        Gf, UsdGeom, UsdLux = self.pxr.Gf, self.pxr.UsdGeom, self.pxr.UsdLux
        placement = camera.at(float(self.trajectory.times[0]))
        view = placement.position - placement.focal_point
        UsdGeom.Scope.Define(self.stage, "/World/Lights")
        for light in three_point_rig(placement.up, view / np.linalg.norm(view)):
            distant = self._define(UsdLux.DistantLight, f"/World/Lights/{light.name}", light.name)
            distant.CreateIntensityAttr(float(light.intensity))
            distant.CreateAngleAttr(2.0)  # a soft edge, like the renderer's shadows
            # a distant light shines along its -Z axis: point +Z at the light
            UsdGeom.Xformable(distant).AddTransformOp().Set(
                Gf.Matrix4d(*_look_at(light.toward_light, np.zeros(3), _any_up(light.toward_light)).ravel()))


def linear_rgb(srgb: np.ndarray) -> np.ndarray:
    """sRGB colours (..., 3) in 0…1, as the scene and the frames have them, in linear RGB, as USD's primvars are."""
    srgb = np.asarray(srgb, float)
    return np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)


def _look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray) -> np.ndarray:
    """The 4×4 transform (row vectors, USD's convention) of a camera or light at ``eye`` looking at ``target``: its
    -Z axis points at the target, +Y as close to ``up`` as can be."""
    back = np.asarray(eye, float) - np.asarray(target, float)
    back /= np.linalg.norm(back)
    right = np.cross(up, back)
    right /= np.linalg.norm(right)
    matrix = np.eye(4)
    matrix[0, :3], matrix[1, :3], matrix[2, :3], matrix[3, :3] = right, np.cross(back, right), back, eye
    return matrix


def _any_up(direction: np.ndarray) -> np.ndarray:
    """An axis not parallel to ``direction``, for orienting a light (which has no up of its own)."""
    axis = np.eye(3)[int(np.argmin(np.abs(direction)))]
    return axis
