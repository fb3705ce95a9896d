"""Draw frames off-screen with PyVista: one plotter for the whole run, arrays updated in place per frame.

Measured on a 2-core machine with Mesa llvmpipe at 1280×720 (see ``benchmarks/``): a reused plotter renders a
simple scene at well over 100 fps without anti-aliasing, while re-creating it per frame drops to about 10 fps; so
every actor is created once here and a frame only moves things:

* particles are sphere meshes up to ``SPRITE_THRESHOLD`` particles (instanced: one actor per look, see
  :mod:`animbatch.render.spheres`), and point sprites (one actor, shaded as spheres of their radius) beyond;
* each rigid body is its own mesh, built once in its centre-of-mass frame; a frame only rewrites the 4×4 transform
  ``[R | x]`` that its actor (and its axes) share;
* springs are one line set whose end points are rewritten.

Anti-aliasing uses VTK's FXAA pass directly (``renderer.SetUseFXAA``): PyVista's ``enable_anti_aliasing('fxaa')``
silently switches to SSAA on OSMesa/EGL builds, which is several times slower.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from animbatch import quaternion
from animbatch.errors import RenderError
from animbatch.render.arrows import LEGEND_MARGIN, ArrowLayer, legend_box
from animbatch.render.backend import Backend, activate
from animbatch.render.camera import CameraPath, CameraPlacement, Reserved
from animbatch.render.colors import (
    ANCHOR_COLOR,
    AXIS_COLORS,
    COLLIDER_COLOR,
    TARGET_COLOR,
    hex_to_rgb,
    linear_rgb,
)
from animbatch.render.emitted import EmitterLayer
from animbatch.render.frame_geometry import Finish, FrameGeometry, FrameSeries
from animbatch.render.occlusion import GroundOcclusion
from animbatch.render.overlay import LabelFit, fit_label, reserved_strips, use_overlay_font
from animbatch.render.settings import Ground, GroundSettings, RenderSettings
from animbatch.render.shadows import GroundShadows, Shadow, shadow_receivers
from animbatch.render.spheres import SphereGroup, group_by_finish, sphere_segments
from animbatch.render.studio import (
    GROUND_REACH,
    StudioGround,
    add_lights,
    backdrop_color,
    environment_faces,
    three_point_rig,
    use_environment,
)
from animbatch.render.surfaces import (
    arrow_basis,
    collider_surface,
    plane_square,
    shape_mesh,
    vertex_normals,
)
from animbatch.render.trails import TrailLayer

#: The share of a cloth's or lattice's colour it shows unlit (``ambient``), whichever way it faces the lights.
SURFACE_AMBIENT = 0.3
#: Above this many particles, ``particles: auto`` draws point sprites instead of sphere meshes.
SPRITE_THRESHOLD = 200

class FrameRenderer:
    """Renders frames of one scene. Create once, call :meth:`draw` per frame, then :meth:`close`."""

    def __init__(self, render: RenderSettings, geometry: FrameGeometry, backend: Backend) -> None:
        activate(backend)
        try:
            import pyvista as pv  # heavy (VTK): only when drawing
            from vtkmodules.vtkCommonMath import vtkMatrix4x4  # heavy (VTK): only when drawing
        except ImportError as error:  # pragma: no cover - dependency missing
            raise RenderError(f"pyvista is not installed ({error}); run 'bash scripts/dev.sh setup'") from None
        self.pv = pv
        self._matrix_class = vtkMatrix4x4
        self.render_spec = render
        self.geometry = geometry
        self.backend = backend
        self.width, self.height = render.resolution
        self._panel = None
        if geometry.panel is not None:
            from animbatch.render.panel import EnergyPanel

            panel_height = 2 * round(geometry.panel.height * self.height / 2)  # even, as the frame is
            self._panel = EnergyPanel(geometry.panel, self.width, panel_height)
            self.height -= panel_height
        # PyVista's objects are taken as they come (Any): its stubs leave the window and arrays optional
        plotter: Any = pv.Plotter
        self.plotter: Any = plotter(off_screen=True, window_size=[self.width, self.height],
                                    lighting="light kit" if render.lights == "light_kit" else "none")
        created = self.plotter.ren_win.GetClassName()
        if created != backend.vtk_window_class:  # e.g. a VTK build without runtime window selection
            self.plotter.close()
            raise RenderError(f"VTK created a {created} instead of {backend.vtk_window_class} for the {backend.name} "
                              "backend; install VTK >= 9.4 ('bash scripts/dev.sh setup') or try another --backend")
        self._configure_quality()
        self._drawing_seconds = self._last_frame_seconds = 0.0
        self.reserved = self._reserve_overlays()
        self._ground = self._find_ground()
        self.camera_path = CameraPath(render.active_camera, self._framed_bounds(), self.width / self.height,
                                      geometry.followed, self.reserved)
        self.camera = self.camera_path.at(float(geometry.label.times[0]) if geometry.label is not None
                                          and len(geometry.label.times) else 0.0)
        self._backdrop = (np.asarray(hex_to_rgb(render.background)),
                          np.asarray(hex_to_rgb(render.background_top)) if render.background_top else None)
        self.plotter.set_background(render.background, top=render.background_top)
        if render.lights == "three_point":
            view = self.camera.position - self.camera.focal_point
            add_lights(self.pv, self.plotter, three_point_rig(self.camera.up, view / np.linalg.norm(view)),
                       self.camera.focal_point, float(np.linalg.norm(view)))
        self._environment = False  # set up when the first physically based surface needs it
        #: Actors drawn to the horizon (the ground, fluids' surfaces, plane colliders), which the camera does not
        #: frame; and the overlays (the time label, the legend), which it keeps clear of (``reserved``).
        self.scenery: list[Any] = []
        self.overlays: list[Any] = []
        self._as_scenery(self._add_ground)
        self._shadows = self._make_shadows()
        self._add_colliders()
        self._as_scenery(self._add_fluids)
        self._add_particles()
        self._occlusion = self._make_occlusion()  # after the particles: it needs how they are drawn
        self._add_emitted()
        self._trails = TrailLayer(self.pv, self.plotter, geometry.trails) if geometry.trails is not None else None
        self._arrows = ArrowLayer(self.pv, self.plotter, geometry.arrows) if geometry.arrows else None
        self._add_surfaces()
        self._add_rigid_bodies()
        self._add_springs()
        self._add_anchors()
        self._add_targets()
        self._add_time_label()
        legend = self._arrows.legend if self._arrows is not None else None
        self.overlays += [actor for actor in (self._label, legend) if actor is not None]
        self._apply_camera(self.camera)
        self._pixels: Any = None

    def _as_scenery(self, add: Any) -> None:
        """Call ``add`` and count the actors it adds as scenery."""
        before = set(map(id, self.plotter.renderer.actors.values()))
        add()
        self.scenery += [actor for actor in self.plotter.renderer.actors.values() if id(actor) not in before]

    # ------------------------------------------------------------------ setup

    def _make_shadows(self) -> GroundShadows | None:
        """Contact shadows on the ground, when asked for and there is a ground to fall on."""
        ground = self._ground
        if not self.render_spec.shadows or ground is None:
            return None
        _, _, size = self._plane_square(ground.level, self.camera.up, ground.size)
        view = self.camera.position - self.camera.focal_point
        return GroundShadows(self.pv, self.plotter, self._matrix_class, self.camera.up, ground.level,
                             view / np.linalg.norm(view), lift=3e-3 * size,  # clear of depth-test ties
                             receivers=shadow_receivers(self.geometry.colliders, self.camera.up))

    def _make_occlusion(self) -> GroundOcclusion | None:
        """Ambient occlusion of the ground around the motion, when asked for and there is a ground. The occluders'
        radii are fixed: particles drawn as spheres, and each rigid body as the sphere of its volume (its reach
        would overstate a rod)."""
        ground = self._ground
        if not self.render_spec.ambient_occlusion or ground is None:
            return None
        geometry = self.geometry
        rigid = (geometry.rigid_volume_radius if geometry.rigid_volume_radius is not None
                 else geometry.rigid_extent)
        self._occluder_radius = np.concatenate([
            np.zeros(0) if self.use_sprites else geometry.particle_radius[self._drawn],
            np.minimum(rigid, geometry.rigid_extent)])
        _, origin, side = self._plane_square(ground.level, self.camera.up, ground.size)
        return GroundOcclusion(self.pv, self.plotter, origin=origin, up=self.camera.up, side=side,
                               lift=1.5e-3 * side)  # under the shadows, over the grid

    def _find_ground(self) -> GroundSettings | None:
        """The ground drawn: ``render.ground``, or else the first plane collider facing up (drawn as a ground in its
        own colour, since it is the floor bodies land on)."""
        if self.render_spec.ground is not None:
            return self.render_spec.ground
        up = np.asarray(self.render_spec.active_camera.up, float)
        up /= np.linalg.norm(up)
        for collider in self.geometry.colliders:
            if collider.normal is not None and collider.track is None:  # a moving plane is no ground
                if float(np.dot(collider.normal, up)) > 1 - 1e-9:
                    return Ground(level=collider.level, size=collider.size,
                                  color=collider.color or Ground.color)
        return None

    def _framed_bounds(self) -> np.ndarray:
        """What the fitted camera frames (2, 3) [m]: everything drawn (the geometry's bounds), except what lies
        under an opaque ground seen from above (an arrow of a body resting on the floor points into it)."""
        bounds = np.array(self.geometry.bounds, float)
        spec = self.render_spec.active_camera
        up = np.asarray(spec.up, float) / np.linalg.norm(spec.up)
        axis = int(np.argmax(np.abs(up)))
        if self._ground is not None and abs(up[axis]) == 1.0 and float(np.dot(spec.direction, up)) > 0:
            level = self._ground.level * up[axis]  # the ground's coordinate along that axis
            if up[axis] > 0:
                bounds[0, axis] = min(max(bounds[0, axis], level), bounds[1, axis])
            else:
                bounds[1, axis] = max(min(bounds[1, axis], level), bounds[0, axis])
        return bounds

    def _finish(self, body: int | np.integer) -> Finish | None:
        finishes = self.geometry.finishes
        return finishes[body] if finishes else None

    def _shading(self, finish: Finish | None, color: str) -> dict[str, Any]:
        """How add_mesh shades a surface of ``color``: physically based with a finish (lit by the studio's
        environment too; the colour in linear RGB), else plain Phong shading with a small highlight."""
        if finish is None:
            return {"color": color, "smooth_shading": True, "specular": 0.3, "specular_power": 20}
        if not self._environment:
            ground = self._ground.color if self._ground is not None else self.render_spec.background
            use_environment(self.pv, self.plotter, environment_faces(self.camera.up, self._backdrop,
                                                                     np.asarray(hex_to_rgb(ground))))
            self._environment = True
        metallic, roughness = finish
        return {"color": linear_rgb(color), "smooth_shading": True, "pbr": True, "metallic": metallic,
                "roughness": roughness}

    def _configure_quality(self) -> None:
        window = self.plotter.ren_win
        mode = self.render_spec.anti_aliasing
        window.SetMultiSamples(self.render_spec.msaa_samples if mode == "msaa" else 0)
        if mode == "fxaa":
            self.plotter.renderer.SetUseFXAA(True)

    def _add_particles(self) -> None:
        geometry, spec = self.geometry, self.render_spec
        total = len(geometry.particle_radius)
        self._drawn = (np.flatnonzero(geometry.drawn_particles) if geometry.drawn_particles is not None
                       else np.arange(total))
        count = len(self._drawn)
        colors = [geometry.colors[k] for k in self._drawn]
        self.use_sprites = spec.particles == "sprite" or (spec.particles == "auto" and count > SPRITE_THRESHOLD)
        self._sphere_groups: list[tuple[np.ndarray, SphereGroup]] = []
        if count and self.use_sprites:
            cloud = self.pv.PolyData(np.zeros((count, 3)))
            cloud.point_data["radius"] = geometry.particle_radius[self._drawn]
            cloud.point_data["rgb"] = (np.array([hex_to_rgb(c) for c in colors]) * 255).astype(np.uint8)
            actor = self.plotter.add_mesh(cloud, style="points_gaussian", render_points_as_spheres=True,
                                          emissive=False, scalars="rgb", rgb=True, show_scalar_bar=False)
            actor.mapper.SetScaleArray("radius")
            actor.mapper.SetScaleFactor(1.0)
            self._cloud: Any = cloud
        elif count:
            radius = geometry.particle_radius[self._drawn]
            distance = float(np.linalg.norm(geometry.bounds.mean(axis=0) - self.camera.position))
            segments = sphere_segments(spec.sphere_resolution, float(np.median(radius)), distance,
                                       self.camera.view_angle, self.height)
            for finish, members in group_by_finish([self._finish(k) for k in self._drawn]).items():
                group = SphereGroup(self.pv, self.plotter, radius[members], [colors[k] for k in members], segments,
                                    self._shading(finish, colors[members[0]]), self._shadows)
                self._sphere_groups.append((members, group))

    def _add_emitted(self) -> None:
        """One point cloud per emitter (see :mod:`animbatch.render.emitted`)."""

        self._emitter_layers = [EmitterLayer(self.pv, self.plotter, look) for look in self.geometry.emitters]

    def _add_surfaces(self) -> None:
        """One smooth, two-sided surface per cloth or lattice; a frame rewrites its points and normals in place."""
        geometry = self.geometry
        self._surfaces: list[tuple[slice, np.ndarray, Any]] = []  # (vertices, triangles (T, 3), mesh)
        if geometry.surfaces is None:
            return
        finishes = geometry.surface_finishes or (None,) * len(geometry.surface_colors)
        for patch, (front, back), finish in zip(geometry.surfaces.patches, geometry.surface_colors, finishes):
            triangles = patch.triangles
            points = np.zeros((patch.stop - patch.start, 3))
            faces = np.hstack([np.full((len(triangles), 1), 3), triangles]).ravel()
            mesh = self.pv.PolyData(points, faces)
            mesh.point_data["Normals"] = np.zeros_like(points)
            mesh.point_data.active_normals_name = "Normals"
            # a thin sheet: more of its light is ambient (light through the cloth and from around it), so that the
            # side turned away from the key reads as cloth, not as a hole
            shading = (self._shading(finish, front) if finish is not None
                       else {"color": front, "specular": 0.15, "ambient": SURFACE_AMBIENT, "diffuse": 0.7})
            actor = self.plotter.add_mesh(mesh, opacity=self.render_spec.surface_opacity,
                                          **{**shading, "smooth_shading": False})
            if finish is None:
                actor.prop.interpolation = "gouraud"  # shade with our normals, smoothly
            back_side = actor.prop.copy()
            back_side.color = back
            actor.SetBackfaceProperty(back_side)
            self._surfaces.append((slice(patch.start, patch.stop), triangles, mesh))

    def _add_rigid_bodies(self) -> None:
        """One mesh per rigid body in its centre-of-mass frame; its actors share one transform matrix."""
        geometry, spec = self.geometry, self.render_spec
        first = len(geometry.particle_radius)
        self._rigid_matrices = []
        self._rigid_shadows: list[Shadow] = []
        self._vector_actors = []
        for b, shape in enumerate(geometry.rigid_shapes):
            mesh = shape_mesh(shape, spec.sphere_resolution).translate(-geometry.rigid_centre[b])
            # split vertices at sharp edges so boxes stay crisp while spheres and cylinders look smooth
            mesh = mesh.compute_normals(split_vertices=True, feature_angle=40.0)
            matrix = self._matrix_class()
            actor = self.plotter.add_mesh(mesh, **self._shading(self._finish(first + b), geometry.colors[first + b]))
            actor.SetUserMatrix(matrix)
            if spec.show_axes:
                length = 1.3 * float(geometry.rigid_extent[b])
                for axis, color in enumerate(AXIS_COLORS):
                    direction = np.eye(3)[axis]
                    arrow = self.pv.Arrow(start=(0, 0, 0), direction=direction, scale=length, tip_length=0.15,
                                          tip_radius=0.04, shaft_radius=0.015)
                    self.plotter.add_mesh(arrow, color=color).SetUserMatrix(matrix)
            if spec.show_vectors != "none":
                arrow = self.pv.Arrow(start=(0, 0, 0), direction=(1, 0, 0), scale=1.0, tip_length=0.2,
                                      tip_radius=0.05, shaft_radius=0.02)
                vector_matrix = self._matrix_class()
                self.plotter.add_mesh(arrow, color="#ffbf00").SetUserMatrix(vector_matrix)
                self._vector_actors.append(vector_matrix)
            self._rigid_matrices.append(matrix)
            if self._shadows is not None:
                self._rigid_shadows.append(self._shadows.add(mesh))

    def _add_springs(self) -> None:
        geometry = self.geometry
        self._spring_mesh: Any = None
        count = len(geometry.spring_first)
        if self.render_spec.springs == "hidden" or count == 0:
            return
        points = np.zeros((2 * count, 3))
        cells = np.hstack([np.full((count, 1), 2), np.arange(2 * count).reshape(-1, 2)]).ravel()
        mesh = self.pv.PolyData(points, lines=cells)
        colors = np.array([hex_to_rgb(c) for c in geometry.spring_colors]) * 255
        mesh.cell_data["rgb"] = colors.astype(np.uint8)
        self.plotter.add_mesh(mesh, scalars="rgb", rgb=True, show_scalar_bar=False,
                              line_width=self.render_spec.spring_width,
                              render_lines_as_tubes=self.render_spec.springs == "tube")
        self._spring_mesh = mesh

    def _add_anchors(self) -> None:
        geometry = self.geometry
        anchors = geometry.anchor_positions
        self._anchor_actors: list[tuple[int, Any]] = []
        visible = geometry.anchor_visible if geometry.anchor_visible is not None else np.ones(len(anchors), bool)
        if not self.render_spec.show_anchors or not visible.any():
            return
        sizes = np.concatenate([geometry.particle_radius, 0.3 * geometry.rigid_extent])
        size = 0.8 * float(np.median(sizes)) if len(sizes) else 0.05
        for index in np.flatnonzero(visible):
            cube = self.pv.Cube(center=(0, 0, 0), x_length=size, y_length=size, z_length=size)
            actor = self.plotter.add_mesh(cube, color=ANCHOR_COLOR)
            actor.SetPosition(*anchors[index])
            self._anchor_actors.append((int(index), actor))

    def _add_targets(self) -> None:
        """The curves controllers keep bodies on, as thin lines; their point targets as small spheres."""
        geometry = self.geometry
        self._target_actors: list[Any] = []
        if not self.render_spec.show_targets:
            return
        segments = geometry.target_segments
        if segments is not None:
            points = segments.reshape(-1, 3)
            cells = np.hstack([np.full((len(segments), 1), 2), np.arange(len(points)).reshape(-1, 2)]).ravel()
            self.plotter.add_mesh(self.pv.PolyData(points, lines=cells), color=TARGET_COLOR,
                                  line_width=max(1.0, 0.5 * self.render_spec.spring_width))
        radius = 0.4 * float(np.median(geometry.particle_radius)) if len(geometry.particle_radius) else 0.02
        track = geometry.target_track
        for position in track.values[0] if track is not None else ():
            marker = self.pv.Sphere(radius=radius, theta_resolution=12, phi_resolution=12)
            actor = self.plotter.add_mesh(marker, color=TARGET_COLOR)
            actor.SetPosition(*position)
            self._target_actors.append(actor)

    def _plane_square(self, level: float, up: np.ndarray, size: float | None) -> tuple[Any, np.ndarray, float]:
        """A square plane at height ``level`` along ``up`` under the motion, its centre and side length."""
        return plane_square(self.geometry.bounds, level, up, size)

    def _add_ground(self) -> None:
        ground = self._ground
        if ground is None:
            return
        _, origin, side = self._plane_square(ground.level, self.camera.up, ground.size)
        reach = side
        if ground.fade:  # far enough to fade out, and to run under the camera to the frame's bottom edge
            to_camera = self.camera.position - origin
            level = to_camera - np.dot(to_camera, self.camera.up) * self.camera.up
            reach = max(GROUND_REACH * side, 2.5 * float(np.linalg.norm(level)))
        StudioGround(self.pv, self.plotter, origin=origin, up=self.camera.up, side=side, reach=reach,
                     color=ground.color, grid=ground.grid, fade=ground.fade, camera=self.camera,
                     backdrop=self._backdrop)

    def _add_colliders(self) -> None:
        """Fixed colliders, built once: planes as squares around the motion, boxes, spheres and meshes."""

        colliders = self.geometry.colliders
        looks = self.geometry.collider_looks or tuple((c.color or COLLIDER_COLOR, None) for c in colliders)
        self._moving_colliders: list[tuple[Any, FrameSeries]] = []  # (actor, track): placed at every frame
        for collider, (color, finish) in zip(colliders, looks):
            if (collider.normal is not None and collider.track is None
                    and self._is_ground(collider.normal, collider.level)):
                continue  # the ground draws it: two squares in one plane would fight over every pixel
            mesh = collider_surface(collider, self.geometry.bounds, self.render_spec.sphere_resolution)
            mesh = mesh.compute_normals(split_vertices=True, feature_angle=40.0)
            shading = (self._shading(finish, color) if finish is not None
                       else {"color": color, "smooth_shading": True, "ambient": 0.15})
            actor = self.plotter.add_mesh(mesh, **shading)
            if collider.track is not None:
                self._moving_colliders.append((actor, collider.track))
            if collider.normal is not None:
                self.scenery.append(actor)

    def _is_ground(self, normal: np.ndarray, level: float) -> bool:
        """Whether the plane ``normal · p = level`` is the drawn ground's."""
        ground = self._ground
        up = self.camera.up / np.linalg.norm(self.camera.up)
        return (ground is not None and float(np.dot(normal, up)) > 1 - 1e-9
                and abs(level - ground.level) <= 1e-9 * max(1.0, abs(level)))

    def _add_fluids(self) -> None:
        for level, up in self.geometry.fluids:
            plane, _, _ = self._plane_square(level, np.asarray(up, float), None)
            self.plotter.add_mesh(plane, color=self.render_spec.fluid_color, opacity=0.35, ambient=0.3)

    def _reserve_overlays(self) -> Reserved:
        """The strips the fitted camera keeps clear for the time label and the arrows' legend; sizes the label."""
        spec, geometry = self.render_spec, self.geometry
        self._label_fit: LabelFit | None = None
        if spec.show_time:
            times = geometry.label.times if geometry.label is not None and len(geometry.label.times) else [0.0]
            samples = np.unique(np.linspace(0, len(times) - 1, min(len(times), 9)).round().astype(int))
            texts = [self._label_text(float(times[k])) for k in samples]  # its numbers change width
            self._label_fit = fit_label(texts, max(8, round(spec.label_size * self.height)), self.width)
        legend = legend_box(geometry.arrows, self.width, self.height) if geometry.arrows else None
        return reserved_strips(self.height, self._label_fit, spec.label_corner,
                               legend[0][1] if legend is not None else None, LEGEND_MARGIN)

    def _add_time_label(self) -> None:
        self._label = None
        if self._label_fit is None:
            return
        spec = self.render_spec
        size = self._label_fit.margin  # letters scale with the frame, shrunk if a line would run off it
        right, lower = spec.label_corner.endswith("right"), spec.label_corner.startswith("lower")
        red, green, blue = backdrop_color(*self._backdrop, np.array(0.05 if lower else 0.95))
        text_color = "black" if 0.299 * red + 0.587 * green + 0.114 * blue > 0.5 else "white"
        self._label = self.plotter.add_text(self._label_text(0.0), font_size=size, color=text_color,
                                            position=(self.width - size if right else size,
                                                      size if lower else self.height - size))
        text = self._label.GetTextProperty()
        use_overlay_font(text, self._label_fit.font)
        text.SetVerticalJustificationToBottom() if lower else text.SetVerticalJustificationToTop()
        text.SetJustificationToRight() if right else text.SetJustificationToLeft()

    def _label_text(self, t: float) -> str:
        """The overlay at time ``t`` [s], with the numbers of its frame, and the wall-clock seconds this renderer
        has spent drawing (so far, and on the frame before)."""
        values = self.geometry.label.at(t) if self.geometry.label is not None else {"t": t}
        return self.render_spec.time_label.format(**values, wall_render=self._drawing_seconds,
                                                  wall_frame=self._last_frame_seconds)

    def _apply_camera(self, placement: CameraPlacement) -> None:
        camera = self.plotter.camera
        camera.position = tuple(placement.position)
        camera.focal_point = tuple(placement.focal_point)
        camera.up = tuple(placement.up)
        camera.view_angle = placement.view_angle
        # Near and far around all that is drawn and everywhere the run's motion goes: a camera that stands still
        # keeps them for the whole run, and around the first frame's props alone a ball tossed up toward a camera
        # looking down left them and vanished for the top of its arc. (Computed once: every frame costs 15 %.)
        drawn = np.array(self.plotter.renderer.ComputeVisiblePropBounds(), float).reshape(3, 2)
        low, high = np.asarray(self.geometry.bounds, float)
        pad = 0.25 * float(np.max(high - low))
        box = np.stack([np.minimum(drawn[:, 0], low - pad), np.maximum(drawn[:, 1], high + pad)], axis=1)
        self.plotter.renderer.ResetCameraClippingRange(*box.ravel())

    # ------------------------------------------------------------------ per frame

    def _set_matrix(self, matrix: Any, rotation: np.ndarray, position: np.ndarray) -> None:
        values = np.eye(4)
        values[:3, :3] = rotation
        values[:3, 3] = position
        matrix.DeepCopy(values.ravel())
        matrix.Modified()

    def draw(self, t: float, positions: np.ndarray, orientations: np.ndarray | None = None,
             angular_velocities: np.ndarray | None = None, emitted: tuple[Any, int] | None = None) -> np.ndarray:
        """Render the bodies at time ``t`` [s]: centre-of-mass ``positions`` (P, 3) [m], ``orientations`` (P, 4)
        quaternions and ``angular_velocities`` (P, 3) [rad/s]; ``emitted``: the trajectory's particle frames (one
        :class:`~animbatch.trajectory.ParticleFrames` per emitter) and the index of this frame. Returns an
        RGB image (H, W, 3) uint8."""
        started = time.perf_counter()
        geometry = self.geometry
        if emitted is not None:
            records, frame = emitted
            for layer, frames in zip(self._emitter_layers, records):
                layer.update(frames, frame)
        n = len(geometry.particle_radius)
        drawn = positions[self._drawn]
        if self.use_sprites and len(drawn):
            self._cloud.points[:] = drawn
            self._cloud.GetPoints().Modified()
        else:
            for members, group in self._sphere_groups:
                group.update(drawn[members])
        anchor_positions = geometry.anchors_at(t)
        if geometry.anchor_track is not None:
            for index, actor in self._anchor_actors:
                actor.SetPosition(*anchor_positions[index])
        for actor, track in self._moving_colliders:
            actor.user_matrix = track.at(t)
        rotation = None
        if orientations is not None and len(self._rigid_matrices):
            rotation = quaternion.to_matrix(orientations[n:])
            for b, matrix in enumerate(self._rigid_matrices):
                self._set_matrix(matrix, rotation[b], positions[n + b])
            shadows = self._shadows
            for b, shadow in enumerate(self._rigid_shadows):  # (none without shadows)
                assert shadows is not None
                shadows.place(shadow, rotation[b], positions[n + b])
            if self._vector_actors and angular_velocities is not None:
                vectors = angular_velocities[n:]
                if self.render_spec.show_vectors == "angular_momentum":
                    vectors = np.einsum("bij,bjk,blk,bl->bi", rotation, geometry.rigid_inertia, rotation, vectors)
                bases = arrow_basis(vectors) * (geometry.vector_scale * np.linalg.norm(vectors, axis=1))[:, None, None]
                for b, matrix in enumerate(self._vector_actors):
                    self._set_matrix(matrix, bases[b], positions[n + b])
        if self._surfaces:
            rigid_rotation = (rotation if rotation is not None or orientations is None
                              else quaternion.to_matrix(orientations[n:]))
            assert geometry.surfaces is not None
            vertices = geometry.surfaces.placement.place(positions, rigid_rotation, anchor_positions)
            for vertex_range, triangles, mesh in self._surfaces:
                points = vertices[vertex_range]
                mesh.points[:] = points
                mesh.point_data["Normals"][:] = vertex_normals(points, triangles)
                mesh.GetPoints().Modified()
                mesh.GetPointData().GetNormals().Modified()
        if self._target_actors:
            assert geometry.target_track is not None
            for actor, position in zip(self._target_actors, geometry.target_track.at(t)):
                actor.SetPosition(*position)  # keyframed targets move
        if self._spring_mesh is not None:
            self._spring_mesh.points[:] = self._spring_ends(positions, rotation, anchor_positions)
            self._spring_mesh.GetPoints().Modified()
        if self._occlusion is not None:
            spheres = np.empty((0, 3)) if self.use_sprites else drawn
            self._occlusion.update(np.concatenate([spheres, positions[n:n + len(geometry.rigid_shapes)]]),
                                   self._occluder_radius)
        if self._trails is not None:
            self._trails.update(t)
        if self._arrows is not None:
            self._arrows.update(t, positions)
        if self._label is not None:
            self._label.SetInput(self._label_text(t))
        if self.camera_path.moves:
            self._apply_camera(self.camera_path.at(t))
        # The window itself, not plotter.render(): PyVista skips rendering until the plotter was first shown.
        self.plotter.ren_win.Render()
        pixels = self._read_pixels()
        if self._panel is not None:
            pixels = np.concatenate([pixels, self._panel.draw(t)], axis=0)
        self._last_frame_seconds = time.perf_counter() - started
        self._drawing_seconds += self._last_frame_seconds
        return pixels

    def _spring_ends(self, positions: np.ndarray, rigid_rotation: np.ndarray | None,
                     anchor_positions: np.ndarray) -> np.ndarray:
        """World positions of both ends of every spring, interleaved (2S, 3)."""
        g = self.geometry
        n = len(g.particle_radius)

        def attached(points: np.ndarray, offset: np.ndarray) -> np.ndarray:
            result = positions[points].copy()
            rigid = points >= n
            if rigid_rotation is not None and rigid.any():
                result[rigid] += np.einsum("kij,kj->ki", rigid_rotation[points[rigid] - n], offset[rigid])
            return result

        ends = np.empty((len(g.spring_first), 2, 3))
        ends[:, 0] = attached(g.spring_first, g.spring_first_offset)
        to_body = ~g.spring_to_anchor
        ends[g.spring_to_anchor, 1] = anchor_positions[g.spring_second[g.spring_to_anchor]]
        ends[to_body, 1] = attached(g.spring_second[to_body], g.spring_second_offset[to_body])
        return ends.reshape(-1, 3)

    def _read_pixels(self) -> np.ndarray:
        from vtkmodules.util.numpy_support import vtk_to_numpy  # heavy (VTK): only when drawing
        from vtkmodules.vtkCommonCore import vtkUnsignedCharArray  # heavy (VTK): only when drawing

        if self._pixels is None:
            self._pixels = vtkUnsignedCharArray()
        window = self.plotter.ren_win
        window.GetPixelData(0, 0, self.width - 1, self.height - 1, 0, self._pixels, 0)
        image = vtk_to_numpy(self._pixels).reshape(self.height, self.width, -1)[:, :, :3]
        return np.ascontiguousarray(image[::-1])  # OpenGL rows run bottom-up

    def close(self) -> None:
        self.plotter.close()

    def __enter__(self) -> FrameRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
