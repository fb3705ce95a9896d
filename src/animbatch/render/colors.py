"""The renderer's colours: the palette bodies take when the scene gives none, and the colours of the rest."""

from __future__ import annotations

import numpy as np

#: Body colours by index when the scene gives none (Tableau 10).
PALETTE = ("#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f", "#edc948", "#b07aa1", "#ff9da7", "#9c755f",
           "#bab0ac")
ANCHOR_COLOR = "#333333"
COLLIDER_COLOR = "#c8c8c8"
SPRING_COLOR = "#808080"
MESH_SPRING_COLOR = "#505050"
ROD_COLOR = "#3d4451"  # distance joints: rigid rods, darker than springs
TARGET_COLOR = "#6b6b6b"
AXIS_COLORS = ("#d62728", "#2ca02c", "#1f77b4")


def hex_to_rgb(color: str) -> tuple[float, float, float]:
    """``'#rrggbb'`` -> (r, g, b) in 0…1."""
    value = color.lstrip("#")
    return int(value[0:2], 16) / 255, int(value[2:4], 16) / 255, int(value[4:6], 16) / 255


def darker(color: str, factor: float = 0.7) -> str:
    """The same hue, darker (for the back of a cloth)."""
    return "#{:02x}{:02x}{:02x}".format(*(round(255 * factor * c) for c in hex_to_rgb(color)))


def srgb_to_linear(rgb: np.ndarray) -> np.ndarray:
    """sRGB channel values (…) in 0…1 (as colours are written) -> linear ones, what VTK's physically based shading
    takes: it lights in linear space and gamma-encodes its output, so an sRGB colour passed as is comes out pale."""
    rgb = np.asarray(rgb, float)
    return np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)


def linear_rgb(color: str) -> tuple[float, float, float]:
    """``'#rrggbb'`` -> linear (r, g, b) in 0…1 (see :func:`srgb_to_linear`)."""
    red, green, blue = srgb_to_linear(np.array(hex_to_rgb(color)))
    return float(red), float(green), float(blue)
