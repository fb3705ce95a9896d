"""Contact shadows: each body's own mesh, flattened onto the ground along the key light (a planar projected shadow).

A shadow lands on the first surface under its body along the light: the ground, or an upward face of a fixed box
collider (a ramp, a table, a step), flattened onto that face's plane and clipped to its edges, so that a block on a
ramp shades the ramp instead of the ground beneath it. A rigid body's shadow switches face as the body moves
(:meth:`GroundShadows.place`); particle spheres draw one shadow set per face (:mod:`animbatch.render.spheres`).

VTK's shadow-map pass (``enable_shadows``) was tried first: under Mesa's software rasteriser it shadowed whole
regions of the ground black at the edges of its light frustum and speckled lit spheres with acne, and it doubled the
time per frame. A projected shadow costs one more actor per body, sharing the body's transform through one more
4×4 matrix, and is exact for a flat ground: the shadow of a point ``p`` along the light's direction ``d`` on the
plane ``n · p = c`` is ``p − ((n · p − c) / (n · d)) d``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from animbatch.render.frame_geometry import DrawnCollider

#: Shadow colour and opacity: a translucent dark grey keeps the ground's grid and colour readable through it.
SHADOW_COLOR = "#1e1e24"
SHADOW_OPACITY = 0.38
#: The key light's tilt from straight down, towards the camera's right and away from it [rad each].
KEY_LIGHT_TILT = (0.55, 0.45)


def key_light_direction(up: np.ndarray, camera_direction: np.ndarray) -> np.ndarray:
    """The direction light travels from the key light (unit): downwards, tilted to the right of the view and away
    from the camera, so that shadows fall beside the bodies, where the camera sees them."""
    up = up / np.linalg.norm(up)
    away = -(camera_direction - np.dot(camera_direction, up) * up)  # from the camera into the scene, level
    away = away / np.linalg.norm(away) if np.linalg.norm(away) > 1e-9 else np.zeros(3)
    right = np.cross(away, up) if np.any(away) else np.zeros(3)
    direction = -up + np.tan(KEY_LIGHT_TILT[0]) * right + np.tan(KEY_LIGHT_TILT[1]) * away
    return direction / np.linalg.norm(direction)


def planar_projection(normal: np.ndarray, level: float, direction: np.ndarray) -> np.ndarray:
    """The 4×4 matrix taking a point to its shadow on the plane ``normal · p = level`` along ``direction``."""
    n = normal / np.linalg.norm(normal)
    along = float(np.dot(n, direction))
    matrix = np.eye(4)
    matrix[:3, :3] -= np.outer(direction, n) / along
    matrix[:3, 3] = direction * level / along
    return matrix


#: A face catches shadows when its outward normal is within 60° of straight up (this cosine): ramps, not walls.
FACING_UP = 0.5


@dataclass(frozen=True, eq=False)
class Receiver:
    """A flat face that catches shadows: the points p with ``normal · p = level`` and ``edges[k, :3] · p ≥
    edges[k, 3]`` for each of its bounding planes (K, 4), the edge planes' normals pointing inward."""

    normal: np.ndarray
    level: float
    edges: np.ndarray


def shadow_receivers(colliders: tuple[DrawnCollider, ...], up: np.ndarray) -> list[Receiver]:
    """The upward faces of the fixed box colliders, as receivers of shadows."""
    up = up / np.linalg.norm(up)
    receivers = []
    for collider in colliders:
        solid = collider.solid
        if solid is None or solid.kind != "box" or collider.track is not None:
            continue
        rotation, centre = collider.pose[:3, :3], collider.pose[:3, 3]
        half = np.asarray(solid.size, float) / 2
        for axis in range(3):
            for sign in (1.0, -1.0):
                normal = sign * rotation[:, axis]
                if normal @ up < FACING_UP:
                    continue
                others = [j for j in range(3) if j != axis]
                edges = np.array([[*(side * rotation[:, j]), side * rotation[:, j] @ centre - half[j]]
                                  for j in others for side in (1.0, -1.0)])
                receivers.append(Receiver(normal, float(normal @ centre + half[axis]), edges))
    return receivers


@dataclass
class Shadow:
    """One body's shadow: the 4×4 matrix that places it and its actor's mapper (clipped to a face it lands on)."""

    matrix: Any
    mapper: Any
    receiver: int = -1  # the ground


class GroundShadows:
    """The contact shadows of a scene's bodies on its ground and on the faces of its fixed boxes; :meth:`place`
    moves one with its body."""

    def __init__(self, pv: Any, plotter: Any, matrix_class: Any, up: np.ndarray, level: float,
                 camera_direction: np.ndarray, lift: float, receivers: list[Receiver] | None = None) -> None:
        """``lift`` [m]: how far above the ground (or a face) the shadows lie, so that they win the depth test
        against it; ``receivers``: the faces besides the ground that catch shadows."""
        self.pv, self.plotter, self.matrix_class = pv, plotter, matrix_class
        self.direction = key_light_direction(up, camera_direction)
        self.projection = planar_projection(up, level + lift, self.direction)
        self.up, self.level = up / np.linalg.norm(up), level
        self.receivers = receivers or []
        self._on_face = [planar_projection(face.normal, face.level + lift, self.direction) for face in self.receivers]
        self._clips = [self._clipping_planes(face) for face in self.receivers]

    def _clipping_planes(self, face: Receiver) -> Any:
        from vtkmodules.vtkCommonDataModel import vtkPlane, vtkPlaneCollection  # heavy (VTK): only when drawing

        planes = vtkPlaneCollection()
        for edge in face.edges:
            plane = vtkPlane()
            plane.SetNormal(*edge[:3])  # VTK keeps the side the normal points to
            plane.SetOrigin(*(edge[:3] * edge[3]))
            planes.AddItem(plane)
        return planes

    #: How a shadow is drawn (add_mesh keywords): translucent dark grey, unlit.
    LOOK: dict[str, Any] = {"color": SHADOW_COLOR, "opacity": SHADOW_OPACITY, "lighting": False,
                            "smooth_shading": False}

    def add(self, mesh: Any) -> Shadow:
        """A shadow actor for ``mesh`` (in its body's frame), to be placed by :meth:`place`."""
        actor = self.plotter.add_mesh(mesh, **self.LOOK)
        actor.prop.backface_culling = False
        matrix = self.matrix_class()
        actor.SetUserMatrix(matrix)
        return Shadow(matrix, actor.mapper)

    def receivers_of(self, points: np.ndarray) -> np.ndarray:
        """Which face catches the shadow of each point (K, 3) [m]: the index of the first receiver met along the light
        from it, -1 for the ground (K,)."""
        which = np.full(len(points), -1)
        nearest = np.full(len(points), np.inf)
        for k, face in enumerate(self.receivers):
            along = float(face.normal @ self.direction)
            if along >= -1e-9:  # the light runs along it or comes from under it
                continue
            distance = (face.level - points @ face.normal) / along
            met = points + distance[:, None] * self.direction
            inside = np.all(met @ face.edges[:, :3].T >= face.edges[:, 3] - 1e-9, axis=1)
            closer = inside & (distance > 0) & (distance < nearest)
            which[closer], nearest[closer] = k, distance[closer]
        return which

    def projection_onto(self, receiver: int) -> np.ndarray:
        """The flattening matrix (4, 4) onto receiver ``receiver`` (-1: the ground)."""
        return self.projection if receiver < 0 else self._on_face[receiver]

    def clip(self, mapper: Any, receiver: int) -> None:
        """Clip what ``mapper`` draws to the edges of receiver ``receiver`` (the ground: nothing clipped)."""
        mapper.RemoveAllClippingPlanes()
        if receiver >= 0:
            mapper.SetClippingPlanes(self._clips[receiver])

    def place(self, shadow: Shadow, rotation: np.ndarray | None, position: np.ndarray) -> None:
        """Put a shadow under its body at ``position`` [m] turned by ``rotation`` (3, 3) (None: unturned): on the
        first face along the light from the body's centre, else on the ground."""
        body = np.eye(4)
        if rotation is not None:
            body[:3, :3] = rotation
        body[:3, 3] = position
        receiver = int(self.receivers_of(np.asarray(position, float)[None])[0])
        if receiver != shadow.receiver:
            self.clip(shadow.mapper, receiver)
            shadow.receiver = receiver
        shadow.matrix.DeepCopy((self.projection_onto(receiver) @ body).ravel())
        shadow.matrix.Modified()
