"""The overlay's text (the time label, the HUD) and the room it and the arrows' legend take on the frame.

The camera is fitted before anything is drawn, so what the overlays will cover is worked out first, from the text
itself: the label is measured with the font it is drawn in, at several frames (its numbers change), shrunk when its
widest line would run off the frame, and its corner's strip of the frame, with the legend's, is kept clear of
what the camera frames (:class:`animbatch.render.camera.Reserved`).
"""

from __future__ import annotations

import importlib.util
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

from animbatch.render.camera import MOST_RESERVED, Reserved

#: vtkTextProperty's font family that reads a font file (VTK_FONT_FILE in vtkSystemIncludes.h).
VTK_FONT_FILE = 4
#: The smallest the label's letters are shrunk to [px] to keep a long line in the frame.
SMALLEST_LETTERS = 6
#: Room left between the label and what the camera frames, as a fraction of its font size.
CLEARANCE = 0.5


def overlay_font() -> Path | None:
    """DejaVu Sans, which matplotlib (a dependency) ships, found without importing matplotlib; None if absent."""
    spec = importlib.util.find_spec("matplotlib")
    for folder in (spec.submodule_search_locations or []) if spec is not None else []:
        path = Path(folder) / "mpl-data" / "fonts" / "ttf" / "DejaVuSans.ttf"
        if path.is_file():
            return path
    return None


@cache
def _text_renderer() -> Any:
    # Plain text, always: VTK's default backend hands any label with '|' (as in '|v|') to matplotlib's MathText,
    # which draws it in another font and drops the bars
    from vtkmodules.vtkRenderingCore import vtkTextRenderer  # heavy (VTK): only when drawing
    from vtkmodules.vtkRenderingFreeType import vtkFreeTypeTools  # noqa: F401  (registers the text renderer)

    renderer = vtkTextRenderer.GetInstance()
    renderer.SetDefaultBackend(vtkTextRenderer.FreeType)
    return renderer


def use_overlay_font(text_property: Any, size: int) -> None:
    """Set a vtkTextProperty to the overlay's font at ``size`` [px]: DejaVu Sans when found (VTK's own fonts have
    no π, ω, τ, γ, ≈: the notes' symbols need a fuller one)."""
    _text_renderer()
    text_property.SetFontSize(size)
    font = overlay_font()
    if font is not None:
        text_property.SetFontFamily(VTK_FONT_FILE)
        text_property.SetFontFile(str(font))


def measure_text(texts: Iterable[str], size: int) -> tuple[int, int]:
    """The largest width and height [px] of ``texts`` drawn in the overlay's font at ``size`` [px]."""
    from vtkmodules.vtkRenderingCore import vtkTextProperty  # heavy (VTK): only when drawing

    text_property = vtkTextProperty()
    use_overlay_font(text_property, size)
    width = height = 0
    for text in texts:
        box = [0, 0, 0, 0]
        if text and _text_renderer().GetBoundingBox(text_property, text, box, 72):  # the window's 72 dpi
            width, height = max(width, box[1] - box[0] + 1), max(height, box[3] - box[2] + 1)
    return width, height


#: The label's font size [px] per pixel of its margin from the frame's edges (``render.label_size``).
FONT_PER_MARGIN = 2


@dataclass(frozen=True)
class LabelFit:
    """The time label as it will be drawn: its ``margin`` [px] from the frame's edges, its ``font`` size [px]
    (FONT_PER_MARGIN times the margin) and the ``width`` and ``height`` [px] of its largest text."""

    margin: int
    width: int
    height: int

    @property
    def font(self) -> int:
        return FONT_PER_MARGIN * self.margin


def fit_label(texts: list[str], margin: int, frame_width: int) -> LabelFit:
    """The label's size: its ``margin`` [px] (and font), or smaller so that the widest of ``texts`` fits the frame's
    width with the margin on both sides (a line that would run off the frame shrinks)."""
    width, height = measure_text(texts, FONT_PER_MARGIN * margin)
    while width > frame_width - 2 * margin and FONT_PER_MARGIN * margin > SMALLEST_LETTERS:
        margin = max(SMALLEST_LETTERS // FONT_PER_MARGIN,
                     min(margin - 1, int(margin * (frame_width - 2 * margin) / width)))
        width, height = measure_text(texts, FONT_PER_MARGIN * margin)
    return LabelFit(margin, width, height)


def reserved_strips(frame_height: int, label: LabelFit | None, label_corner: str,
                    legend_height: float | None, legend_margin: float) -> Reserved:
    """The strips of the frame the camera keeps clear: the label's (its margin, its text and some clearance, along
    the edge of its corner) and the legend's (upper right: ``legend_height`` and ``legend_margin`` as fractions of
    the frame's height, and the same clearance); None for an overlay not drawn. Together they take at most
    MOST_RESERVED of the frame, shared in proportion."""
    top = bottom = 0.0
    if label is not None:
        strip = (label.margin + label.height + CLEARANCE * label.font) / frame_height
        if label_corner.startswith("lower"):
            bottom = strip
        else:
            top = strip
    if legend_height is not None:
        top = max(top, 2 * legend_margin + legend_height)  # its gap from the edge, and as much under it
    if top + bottom > MOST_RESERVED:
        scale = MOST_RESERVED / (top + bottom)
        top, bottom = top * scale, bottom * scale
    return Reserved(top, bottom)
