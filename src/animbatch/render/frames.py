"""Draw frames off-screen with PyVista: one plotter for the whole run, arrays updated in place per frame.

Measured on a 2-core machine with Mesa llvmpipe at 1280×720 (see ``benchmarks/``): a reused plotter renders a
simple scene at well over 100 fps without anti-aliasing, while re-creating it per frame drops to about 10 fps; so
every actor is created once here and a frame only moves things. Particles are sphere meshes (one actor each, moved by
its transform) up to ``SPRITE_THRESHOLD`` particles, and point sprites (one actor, shaded as spheres of their radius)
beyond, since meshes cost 10–30× more per particle.

Anti-aliasing uses VTK's FXAA pass directly (``renderer.SetUseFXAA``): PyVista's ``enable_anti_aliasing('fxaa')``
silently switches to SSAA on OSMesa/EGL builds, which is several times slower.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from animbatch.errors import RenderError
from animbatch.model.model import Model
from animbatch.render.backend import Backend, activate
from animbatch.render.camera import CameraPlacement, nice_spacing, place_camera, plane_axes
from animbatch.scene.schema import RenderSpec, SceneSpec

#: Above this many particles, ``particles: auto`` draws point sprites instead of sphere meshes.
SPRITE_THRESHOLD = 200

#: Body colours by index when the scene gives none (Tableau 10).
PALETTE = ("#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f", "#edc948", "#b07aa1", "#ff9da7", "#9c755f",
           "#bab0ac")
ANCHOR_COLOR = "#333333"
SPRING_COLOR = "#808080"


def hex_to_rgb(color: str) -> tuple[float, float, float]:
    """``'#rrggbb'`` -> (r, g, b) in 0…1."""
    value = color.lstrip("#")
    return tuple(int(value[i:i + 2], 16) / 255 for i in (0, 2, 4))  # type: ignore[return-value]


def body_colors(spec: SceneSpec) -> list[str]:
    return [body.color or PALETTE[i % len(PALETTE)] for i, body in enumerate(spec.bodies)]


@dataclass(frozen=True)
class FrameGeometry:
    """What the renderer draws, independent of the scene file: topology, sizes, colours, bounds."""

    radius: np.ndarray  # (N,) [m]
    colors: list[str]  # (N,) '#rrggbb'
    anchor_positions: np.ndarray  # (A, 3) [m]
    spring_ends: np.ndarray  # (S, 2) indices into concat(particles, anchors)
    spring_colors: list[str]
    bounds: np.ndarray  # (2, 3) [m], whole motion

    @classmethod
    def from_scene(cls, spec: SceneSpec, model: Model, bounds: np.ndarray) -> FrameGeometry:
        n = model.particle_count
        springs = model.springs
        if springs is None:
            ends = np.zeros((0, 2), dtype=np.intp)
        else:
            second = np.where(springs.second_is_anchor, springs.second + n, springs.second)
            ends = np.stack([springs.first, second], axis=1)
        spring_colors = [s.color or SPRING_COLOR for s in spec.springs]
        return cls(np.asarray(model.particles.radius), body_colors(spec), np.asarray(model.anchor_position),
                   ends, spring_colors, bounds)


class FrameRenderer:
    """Renders frames of one scene. Create once, call :meth:`draw` per frame, then :meth:`close`."""

    def __init__(self, render: RenderSpec, geometry: FrameGeometry, backend: Backend) -> None:
        activate(backend)
        try:
            import pyvista as pv
        except ImportError as error:  # pragma: no cover - dependency missing
            raise RenderError(f"pyvista is not installed ({error}); run 'bash scripts/dev.sh setup'") from None
        self.pv = pv
        self.render_spec = render
        self.geometry = geometry
        self.backend = backend
        self.width, self.height = render.resolution
        self.plotter = pv.Plotter(off_screen=True, window_size=[self.width, self.height], lighting="light kit")
        created = self.plotter.ren_win.GetClassName()
        if created != backend.vtk_window_class:  # e.g. a VTK build without runtime window selection
            self.plotter.close()
            raise RenderError(f"VTK created a {created} instead of {backend.vtk_window_class} for the {backend.name} "
                              "backend; install VTK >= 9.4 ('bash scripts/dev.sh setup') or try another --backend")
        self._configure_quality()
        self.plotter.set_background(render.background)
        self.camera = place_camera(render.camera, geometry.bounds, self.width / self.height)
        self._add_ground()
        self._add_particles()
        self._add_springs()
        self._add_anchors()
        self._add_time_label()
        self._apply_camera(self.camera)
        self._pixels = None

    # ------------------------------------------------------------------ setup

    def _configure_quality(self) -> None:
        window = self.plotter.ren_win
        mode = self.render_spec.anti_aliasing
        window.SetMultiSamples(self.render_spec.msaa_samples if mode == "msaa" else 0)
        if mode == "fxaa":
            self.plotter.renderer.SetUseFXAA(True)

    def _add_particles(self) -> None:
        geometry, spec = self.geometry, self.render_spec
        count = len(geometry.radius)
        self.use_sprites = spec.particles == "sprite" or (spec.particles == "auto" and count > SPRITE_THRESHOLD)
        self._particle_actors = []
        if self.use_sprites:
            cloud = self.pv.PolyData(np.zeros((count, 3)))
            cloud.point_data["radius"] = geometry.radius
            cloud.point_data["rgb"] = (np.array([hex_to_rgb(c) for c in geometry.colors]) * 255).astype(np.uint8)
            actor = self.plotter.add_mesh(cloud, style="points_gaussian", render_points_as_spheres=True,
                                          emissive=False, scalars="rgb", rgb=True, show_scalar_bar=False)
            actor.mapper.SetScaleArray("radius")
            actor.mapper.SetScaleFactor(1.0)
            self._cloud = cloud
        else:
            resolution = spec.sphere_resolution
            for radius, color in zip(geometry.radius, geometry.colors):
                sphere = self.pv.Sphere(radius=float(radius), theta_resolution=resolution, phi_resolution=resolution)
                self._particle_actors.append(self.plotter.add_mesh(sphere, color=color, smooth_shading=True,
                                                                   specular=0.3, specular_power=20))

    def _add_springs(self) -> None:
        geometry = self.geometry
        self._spring_mesh = None
        if self.render_spec.springs == "hidden" or len(geometry.spring_ends) == 0:
            return
        count = len(geometry.radius)
        points = np.zeros((count + len(geometry.anchor_positions), 3))
        points[count:] = geometry.anchor_positions
        cells = np.hstack([np.full((len(geometry.spring_ends), 1), 2), geometry.spring_ends]).ravel()
        mesh = self.pv.PolyData(points, lines=cells)
        colors = np.array([hex_to_rgb(c) for c in geometry.spring_colors]) * 255
        mesh.cell_data["rgb"] = colors.astype(np.uint8)
        self.plotter.add_mesh(mesh, scalars="rgb", rgb=True, show_scalar_bar=False,
                              line_width=self.render_spec.spring_width,
                              render_lines_as_tubes=self.render_spec.springs == "tube")
        self._spring_mesh = mesh

    def _add_anchors(self) -> None:
        anchors = self.geometry.anchor_positions
        if not self.render_spec.show_anchors or len(anchors) == 0:
            return
        size = 0.8 * float(np.median(self.geometry.radius)) if len(self.geometry.radius) else 0.05
        for position in anchors:
            cube = self.pv.Cube(center=position, x_length=size, y_length=size, z_length=size)
            self.plotter.add_mesh(cube, color=ANCHOR_COLOR)

    def _add_ground(self) -> None:
        ground = self.render_spec.ground
        if ground is None:
            return
        up = self.camera.up
        bounds = self.geometry.bounds
        centre = bounds.mean(axis=0)
        first, second = plane_axes(up)
        corners = np.array([[bounds[i][0], bounds[j][1], bounds[k][2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
        extent = max(np.ptp(corners @ first), np.ptp(corners @ second))
        size = ground.size or max(1.4 * extent, 1.0)
        origin = centre - np.dot(centre, up) * up + ground.level * up  # centre projected onto the ground plane
        plane = self.pv.Plane(center=origin, direction=up, i_size=size, j_size=size)
        self.plotter.add_mesh(plane, color=ground.color, ambient=0.2)
        if ground.grid:
            spacing = nice_spacing(size, 12)
            ticks = np.arange(-size / 2, size / 2 + 1e-9, spacing)
            lift = up * 1e-3 * size  # just above the plane, so the lines win the depth test
            segments = []
            for offset in ticks:
                for along, across in ((first, second), (second, first)):
                    start = origin + lift + along * offset - across * size / 2
                    segments.append((start, start + across * size))
            points = np.array(segments).reshape(-1, 3)
            cells = np.hstack([np.full((len(segments), 1), 2), np.arange(len(points)).reshape(-1, 2)]).ravel()
            self.plotter.add_mesh(self.pv.PolyData(points, lines=cells), color="#a0a0a0", line_width=1)

    def _add_time_label(self) -> None:
        self._label = None
        if not self.render_spec.show_time:
            return
        red, green, blue = hex_to_rgb(self.render_spec.background)
        text_color = "black" if 0.299 * red + 0.587 * green + 0.114 * blue > 0.5 else "white"
        size = max(8, self.height // 36)
        self._label = self.plotter.add_text(self.render_spec.time_label.format(t=0.0),
                                            position=(size, self.height - size), font_size=size, color=text_color)
        self._label.GetTextProperty().SetVerticalJustificationToTop()  # anchor the label by its top edge

    def _apply_camera(self, placement: CameraPlacement) -> None:
        camera = self.plotter.camera
        camera.position = tuple(placement.position)
        camera.focal_point = tuple(placement.focal_point)
        camera.up = tuple(placement.up)
        camera.view_angle = placement.view_angle
        camera.clipping_range = placement.clipping_range

    # ------------------------------------------------------------------ per frame

    def draw(self, t: float, positions: np.ndarray) -> np.ndarray:
        """Render the bodies at ``positions`` (N, 3) [m] at time ``t`` [s]; return an RGB image (H, W, 3) uint8."""
        if self.use_sprites:
            self._cloud.points[:] = positions
            self._cloud.GetPoints().Modified()
        else:
            for actor, position in zip(self._particle_actors, positions):
                actor.SetPosition(*position)
        if self._spring_mesh is not None:
            self._spring_mesh.points[: len(positions)] = positions
            self._spring_mesh.GetPoints().Modified()
        if self._label is not None:
            self._label.SetInput(self.render_spec.time_label.format(t=t))
        # The window itself, not plotter.render(): PyVista skips rendering until the plotter was first shown.
        self.plotter.ren_win.Render()
        return self._read_pixels()

    def _read_pixels(self) -> np.ndarray:
        from vtkmodules.util.numpy_support import vtk_to_numpy
        from vtkmodules.vtkCommonCore import vtkUnsignedCharArray

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
