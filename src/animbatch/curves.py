"""Curves that controllers keep bodies on: polylines, and parametric curves given as formulas of ``s``.

A parametric curve ``(x(s), y(s), z(s))`` is sampled into a fine polyline (``samples`` points): the distance from
a point to the polyline differs from the distance to the curve by at most the chords' sagitta, ``κ Δℓ² / 8`` for
curvature κ and chord length Δℓ (under 0.2 µm for a 0.5 m circle at 4096 samples).

Formulas are parsed with :mod:`ast` and only arithmetic, numbers, ``s``, ``pi``, ``e`` and a fixed list of numpy
functions are accepted, so a scene file cannot run code.
"""

from __future__ import annotations

import ast
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

FUNCTIONS: dict[str, Callable[..., np.ndarray]] = {
    "sin": np.sin, "cos": np.cos, "tan": np.tan, "asin": np.arcsin, "acos": np.arccos, "atan": np.arctan,
    "atan2": np.arctan2, "sinh": np.sinh, "cosh": np.cosh, "tanh": np.tanh, "exp": np.exp, "log": np.log,
    "sqrt": np.sqrt, "abs": np.abs,
}
CONSTANTS = {"pi": np.pi, "e": np.e}
_OPERATORS: dict[type, Callable[..., np.ndarray]] = {
    ast.Add: np.add, ast.Sub: np.subtract, ast.Mult: np.multiply, ast.Div: np.divide, ast.Pow: np.power,
    ast.USub: np.negative, ast.UAdd: np.positive,
}


class ExpressionError(ValueError):
    """A formula that is not valid or uses something not allowed."""


def compile_expression(text: str) -> Callable[[np.ndarray], np.ndarray]:
    """A vectorised function of ``s`` from a formula such as ``"0.5 * cos(2 * pi * s)"``."""
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as error:
        raise ExpressionError(f"not a valid formula: {text!r} ({error.msg})") from None
    _check(tree.body, text)

    def evaluate(s: np.ndarray) -> np.ndarray:
        return np.broadcast_to(_evaluate(tree.body, np.asarray(s, float)), np.shape(s)).astype(float)

    return evaluate


def _check(node: ast.AST, text: str) -> None:
    allowed = f"use s, numbers, + - * / **, {', '.join(CONSTANTS)} and {', '.join(FUNCTIONS)}"
    if isinstance(node, ast.Constant) and isinstance(node.value, int | float) and not isinstance(node.value, bool):
        return
    if isinstance(node, ast.Name):
        if node.id == "s" or node.id in CONSTANTS:
            return
        raise ExpressionError(f"unknown name {node.id!r} in {text!r}: {allowed}")
    if isinstance(node, ast.BinOp) and type(node.op) in _OPERATORS:
        _check(node.left, text)
        _check(node.right, text)
        return
    if isinstance(node, ast.UnaryOp) and type(node.op) in _OPERATORS:
        _check(node.operand, text)
        return
    if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in FUNCTIONS
            and not node.keywords):
        for argument in node.args:
            _check(argument, text)
        return
    raise ExpressionError(f"{ast.unparse(node)!r} is not allowed in {text!r}: {allowed}")


def _evaluate(node: ast.AST, s: np.ndarray) -> np.ndarray:
    if isinstance(node, ast.Constant):
        return np.asarray(float(node.value))
    if isinstance(node, ast.Name):
        return s if node.id == "s" else np.asarray(CONSTANTS[node.id])
    if isinstance(node, ast.BinOp):
        return _OPERATORS[type(node.op)](_evaluate(node.left, s), _evaluate(node.right, s))
    if isinstance(node, ast.UnaryOp):
        return _OPERATORS[type(node.op)](_evaluate(node.operand, s))
    assert isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
    return FUNCTIONS[node.func.id](*(_evaluate(argument, s) for argument in node.args))


def sample_parametric(x: str, y: str, z: str, start: float, end: float, samples: int, closed: bool) -> np.ndarray:
    """Points (samples, 3) [m] along a parametric curve; a closed curve leaves out its end (it is its start)."""
    s = np.linspace(start, end, samples, endpoint=not closed)
    points = np.stack([compile_expression(text)(s) for text in (x, y, z)], axis=1)
    if not np.isfinite(points).all():
        raise ExpressionError("the curve is not finite everywhere on its range (check divisions, log, sqrt)")
    return points


@dataclass(frozen=True, eq=False)
class Polyline:
    """Segments from ``start`` (S, 3) to ``start + direction`` (S, 3) [m]."""

    start: np.ndarray
    direction: np.ndarray

    @classmethod
    def through(cls, points: np.ndarray, closed: bool) -> Polyline:
        points = np.asarray(points, float)
        ends = np.roll(points, -1, axis=0) if closed else points[1:]
        starts = points if closed else points[:-1]
        keep = np.linalg.norm(ends - starts, axis=1) > 0
        return cls(starts[keep], (ends - starts)[keep])

    @property
    def length(self) -> float:
        return float(np.linalg.norm(self.direction, axis=1).sum())

    def closest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The closest point on the polyline to each of ``points`` (K, 3), and the unit tangent there, (K, 3) each.

        Every point is tested against every segment, in chunks so that memory stays bounded (K · S floats at a time
        at most a few million).
        """
        points = np.asarray(points, float).reshape(-1, 3)
        lengths2 = np.einsum("sj,sj->s", self.direction, self.direction)
        tangent = self.direction / np.sqrt(lengths2)[:, None]
        closest = np.empty_like(points)
        which = np.empty(len(points), np.intp)
        chunk = max(1, 2_000_000 // max(1, len(self.start)))
        for begin in range(0, len(points), chunk):
            p = points[begin:begin + chunk]
            offset = p[:, None, :] - self.start[None]  # (k, S, 3)
            fraction = np.clip(np.einsum("ksj,sj->ks", offset, self.direction) / lengths2, 0.0, 1.0)
            foot = self.start[None] + fraction[..., None] * self.direction[None]
            distance2 = np.einsum("ksj,ksj->ks", p[:, None, :] - foot, p[:, None, :] - foot)
            best = np.argmin(distance2, axis=1)
            rows = np.arange(len(p))
            closest[begin:begin + chunk] = foot[rows, best]
            which[begin:begin + chunk] = best
        return closest, tangent[which]
