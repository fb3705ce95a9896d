"""Contact shadows: each body's own mesh, flattened onto the ground along the key light (a planar projected shadow).

VTK's shadow-map pass (``enable_shadows``) was tried first: under Mesa's software rasteriser it shadowed whole
regions of the ground black at the edges of its light frustum and speckled lit spheres with acne, and it doubled the
time per frame. A projected shadow costs one more actor per body, sharing the body's transform through one more
4×4 matrix, and is exact for a flat ground: the shadow of a point ``p`` along the light's direction ``d`` on the
plane ``n · p = c`` is ``p − ((n · p − c) / (n · d)) d``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

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


class GroundShadows:
    """The contact shadows of a scene's bodies on its ground; :meth:`place` moves one with its body."""

    def __init__(self, pv: Any, plotter: Any, matrix_class: Any, up: np.ndarray, level: float,
                 camera_direction: np.ndarray, lift: float) -> None:
        """``lift`` [m]: how far above the ground the shadows lie, so that they win the depth test against it."""
        self.pv, self.plotter, self.matrix_class = pv, plotter, matrix_class
        self.direction = key_light_direction(up, camera_direction)
        self.projection = planar_projection(up, level + lift, self.direction)
        self.up, self.level = up / np.linalg.norm(up), level

    #: How a shadow is drawn (add_mesh keywords): translucent dark grey, unlit.
    LOOK: dict[str, Any] = {"color": SHADOW_COLOR, "opacity": SHADOW_OPACITY, "lighting": False,
                            "smooth_shading": False}

    def add(self, mesh: Any) -> Any:
        """A shadow actor for ``mesh`` (in its body's frame); returns the 4×4 matrix that places it."""
        actor = self.plotter.add_mesh(mesh, **self.LOOK)
        actor.prop.backface_culling = False
        matrix = self.matrix_class()
        actor.SetUserMatrix(matrix)
        return matrix

    def place(self, matrix: Any, rotation: np.ndarray | None, position: np.ndarray) -> None:
        """Put a shadow under its body at ``position`` [m] turned by ``rotation`` (3, 3) (None: unturned)."""
        body = np.eye(4)
        if rotation is not None:
            body[:3, :3] = rotation
        body[:3, 3] = position
        matrix.DeepCopy((self.projection @ body).ravel())
        matrix.Modified()
