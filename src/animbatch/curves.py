"""Curves that controllers keep bodies on: polylines, and parametric curves given as formulas of ``s``.

The closest point on a curve is what a PD controller pulls towards (a bead on a wire).

* A polyline's closest point is exact (a k-d tree of segment midpoints narrows the search); its tangent turns
  abruptly at each vertex, as the wire does.
* A parametric curve ``c(s) = (x(s), y(s), z(s))`` is sampled into a fine polyline only to *seed* the search; the
  closest point is then refined by Newton's method on ``g(s) = (c(s) - p)·c'(s) = 0`` with the exact derivatives
  ``c'`` and ``c''`` of the formulas (differentiated symbolically). So the pull is a smooth function of the body's
  position: an adaptive integrator does not stumble over the sampling's kinks (there are thousands).

Formulas are parsed with :mod:`ast` and only arithmetic, numbers, ``s``, ``pi``, ``e`` and a fixed list of numpy
functions are accepted, so a scene file cannot run code; only such checked trees (and their derivatives, built
from the same parts) are ever compiled.
"""

from __future__ import annotations

import ast
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

FUNCTIONS: dict[str, Callable[..., np.ndarray]] = {
    "sin": np.sin, "cos": np.cos, "tan": np.tan, "asin": np.arcsin, "acos": np.arccos, "atan": np.arctan,
    "atan2": np.arctan2, "sinh": np.sinh, "cosh": np.cosh, "tanh": np.tanh, "exp": np.exp, "log": np.log,
    "sqrt": np.sqrt, "abs": np.abs,
}
CONSTANTS = {"pi": np.pi, "e": np.e}
_OPERATORS = (ast.Add, ast.Sub, ast.Mult, ast.Div, ast.Pow, ast.USub, ast.UAdd)
#: Functions that derivatives use but formulas may not name.
_HIDDEN_FUNCTIONS: dict[str, Callable[..., np.ndarray]] = {"sign": np.sign}


class ExpressionError(ValueError):
    """A formula that is not valid or uses something not allowed."""


def parse_expression(text: str, variable: str = "s") -> ast.expr:
    """The checked syntax tree of a formula of ``variable`` (``s`` for curves, ``t`` for closed forms of time)."""
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as error:
        raise ExpressionError(f"not a valid formula: {text!r} ({error.msg})") from None
    _check(tree.body, text, variable)
    return tree.body


def compile_expression(text: str, variable: str = "s") -> Callable[[np.ndarray], np.ndarray]:
    """A vectorised function of ``variable`` from a formula such as ``"0.5 * cos(2 * pi * s)"``."""
    return compile_tree(parse_expression(text, variable), variable)


def compile_tree(node: ast.expr, variable: str = "s") -> Callable[[np.ndarray], np.ndarray]:
    """A function of ``variable`` from a checked tree (or a derivative built from one: never an unchecked tree)."""
    evaluate_all = _compile_all([node], variable)
    return lambda s: evaluate_all(s)[..., 0]


def _compile_all(nodes: list[ast.expr], variable: str = "s") -> Callable[[np.ndarray], np.ndarray]:
    """One function of ``variable`` giving all the trees' values at once, shape s.shape + (len(nodes),)."""
    tree = ast.Expression(ast.Tuple(list(nodes), ast.Load()))
    code = compile(ast.fix_missing_locations(tree), "<formula>", "eval")
    namespace = {"__builtins__": {}, **FUNCTIONS, **_HIDDEN_FUNCTIONS, **CONSTANTS}

    def evaluate(s: np.ndarray) -> np.ndarray:
        s = np.asarray(s, float)
        out = np.empty(s.shape + (len(nodes),))
        for index, value in enumerate(eval(code, namespace, {variable: s})):  # noqa: S307 (a checked tree)
            out[..., index] = value  # constants broadcast
        return out

    return evaluate


def _check(node: ast.AST, text: str, variable: str = "s") -> None:
    allowed = f"use {variable}, numbers, + - * / **, {', '.join(CONSTANTS)} and {', '.join(FUNCTIONS)}"
    if isinstance(node, ast.Constant) and isinstance(node.value, int | float) and not isinstance(node.value, bool):
        return
    if isinstance(node, ast.Name):
        if node.id == variable or node.id in CONSTANTS:
            return
        raise ExpressionError(f"unknown name {node.id!r} in {text!r}: {allowed}")
    if isinstance(node, ast.BinOp) and isinstance(node.op, _OPERATORS):
        _check(node.left, text, variable)
        _check(node.right, text, variable)
        return
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, _OPERATORS):
        _check(node.operand, text, variable)
        return
    if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in FUNCTIONS
            and not node.keywords and len(node.args) == (2 if node.func.id == "atan2" else 1)):
        for argument in node.args:
            _check(argument, text, variable)
        return
    raise ExpressionError(f"{ast.unparse(node)!r} is not allowed in {text!r}: {allowed}")


# ------------------------------------------------------------------------------------------ differentiation


def _number(value: float) -> ast.expr:
    return ast.Constant(float(value))


def _call(name: str, *arguments: ast.expr) -> ast.expr:
    return ast.Call(ast.Name(name, ast.Load()), list(arguments), [])


def _binary(left: ast.expr, operator: ast.operator, right: ast.expr) -> ast.expr:
    return ast.BinOp(left, operator, right)


def _depends_on_s(node: ast.AST) -> bool:
    return any(isinstance(child, ast.Name) and child.id == "s" for child in ast.walk(node))


def differentiate(node: ast.expr) -> ast.expr:
    """The tree of ``d/ds`` of a checked tree (no simplification beyond dropping constant factors' derivatives)."""
    if not _depends_on_s(node):
        return _number(0.0)
    if isinstance(node, ast.Name):  # it is s
        return _number(1.0)
    if isinstance(node, ast.UnaryOp):
        inner = differentiate(node.operand)
        return ast.UnaryOp(ast.USub(), inner) if isinstance(node.op, ast.USub) else inner
    if isinstance(node, ast.BinOp):
        u, w = node.left, node.right
        du, dw = differentiate(u), differentiate(w)
        if isinstance(node.op, ast.Add | ast.Sub):
            return _binary(du, node.op, dw)
        if isinstance(node.op, ast.Mult):  # (u w)' = u' w + u w'
            return _binary(_binary(du, ast.Mult(), w), ast.Add(), _binary(u, ast.Mult(), dw))
        if isinstance(node.op, ast.Div):  # (u / w)' = (u' w - u w') / w²
            return _binary(_binary(_binary(du, ast.Mult(), w), ast.Sub(), _binary(u, ast.Mult(), dw)), ast.Div(),
                           _binary(w, ast.Pow(), _number(2)))
        assert isinstance(node.op, ast.Pow)
        if not _depends_on_s(w):  # (u^w)' = w u^(w-1) u'
            return _binary(_binary(w, ast.Mult(), _binary(u, ast.Pow(), _binary(w, ast.Sub(), _number(1)))),
                           ast.Mult(), du)
        # (u^w)' = u^w (w' log u + w u' / u)
        return _binary(node, ast.Mult(), _binary(_binary(dw, ast.Mult(), _call("log", u)), ast.Add(),
                                                 _binary(_binary(w, ast.Mult(), du), ast.Div(), u)))
    assert isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
    name, arguments = node.func.id, node.args
    if name == "atan2":  # d atan2(y, x) = (x y' - y x') / (x² + y²)
        y, x = arguments
        numerator = _binary(_binary(x, ast.Mult(), differentiate(y)), ast.Sub(),
                            _binary(y, ast.Mult(), differentiate(x)))
        return _binary(numerator, ast.Div(), _binary(_binary(x, ast.Pow(), _number(2)), ast.Add(),
                                                     _binary(y, ast.Pow(), _number(2))))
    u = arguments[0]
    outer = {  # f'(u) for each function
        "sin": lambda: _call("cos", u),
        "cos": lambda: ast.UnaryOp(ast.USub(), _call("sin", u)),
        "tan": lambda: _binary(_number(1), ast.Div(), _binary(_call("cos", u), ast.Pow(), _number(2))),
        "asin": lambda: _binary(_number(1), ast.Div(), _call("sqrt", _binary(_number(1), ast.Sub(),
                                                                          _binary(u, ast.Pow(), _number(2))))),
        "acos": lambda: _binary(_number(-1), ast.Div(), _call("sqrt", _binary(_number(1), ast.Sub(),
                                                                           _binary(u, ast.Pow(), _number(2))))),
        "atan": lambda: _binary(_number(1), ast.Div(), _binary(_number(1), ast.Add(),
                                                               _binary(u, ast.Pow(), _number(2)))),
        "sinh": lambda: _call("cosh", u),
        "cosh": lambda: _call("sinh", u),
        "tanh": lambda: _binary(_number(1), ast.Div(), _binary(_call("cosh", u), ast.Pow(), _number(2))),
        "exp": lambda: _call("exp", u),
        "log": lambda: _binary(_number(1), ast.Div(), u),
        "sqrt": lambda: _binary(_number(0.5), ast.Div(), _call("sqrt", u)),
        "abs": lambda: _call("sign", u),
        "sign": lambda: _number(0.0),
    }[name]()
    return _binary(outer, ast.Mult(), differentiate(u))


#: Segments whose midpoints are looked up per point before the exactness check (see :meth:`Polyline.closest`).
NEAREST_CANDIDATES = 8
#: Newton iterations at most when refining a closest point on a parametric curve (3 or 4 are typical).
NEWTON_ITERATIONS = 12


@dataclass(frozen=True, eq=False)
class CurvePoint:
    """The closest points on a curve to K query points ``p``, and how they move with ``p``.

    ``position`` (K, 3) [m]; ``tangent`` (K, 3) unit tangents there; ``position_gradient`` (K, 3, 3) = ∂c/∂p
    (``t tᵀ`` on a straight piece; zero where the closest point sits at a corner or an end); ``tangent_gradient``
    (K, 3, 3) = ∂t/∂p (zero on a straight piece); ``segment`` (K,) the polyline segment it lies on (or seeded from).
    """

    position: np.ndarray
    tangent: np.ndarray
    position_gradient: np.ndarray
    tangent_gradient: np.ndarray
    segment: np.ndarray
    fraction: np.ndarray


@dataclass(frozen=True, eq=False)
class Polyline:
    """Segments from ``start`` (S, 3) to ``start + direction`` (S, 3) [m], none of zero length."""

    start: np.ndarray
    direction: np.ndarray

    def __post_init__(self) -> None:
        lengths2 = np.einsum("sj,sj->s", self.direction, self.direction)
        # A k-d tree of segment midpoints finds the few segments worth testing for each point (see closest).
        object.__setattr__(self, "_lengths2", lengths2)
        from scipy.spatial import cKDTree  # here, not at import: the command line starts without SciPy's spatial

        object.__setattr__(self, "_tree", cKDTree(self.start + 0.5 * self.direction))
        object.__setattr__(self, "_reach", 0.5 * float(np.sqrt(lengths2.max())) if len(lengths2) else 0.0)

    @staticmethod
    def segments(points: np.ndarray, closed: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Starts and directions of the segments through ``points`` (closing the loop if asked), and the indices
        of the points they start at (segments of zero length are left out)."""
        points = np.asarray(points, float)
        ends = np.roll(points, -1, axis=0) if closed else points[1:]
        starts = points if closed else points[:-1]
        keep = np.flatnonzero(np.linalg.norm(ends - starts, axis=1) > 0)
        return starts[keep], (ends - starts)[keep], keep

    @classmethod
    def through(cls, points: np.ndarray, closed: bool) -> Polyline:
        starts, directions, _ = cls.segments(points, closed)
        return cls(starts, directions)

    @property
    def length(self) -> float:
        return float(np.linalg.norm(self.direction, axis=1).sum())

    def _feet(self, points: np.ndarray, segments: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Closest points on ``segments`` (K, C) to ``points`` (K, 3): feet (K, C, 3), squared distances and the
        fractions along each segment (K, C)."""
        start, direction = self.start[segments], self.direction[segments]
        offset = points[:, None, :] - start
        fraction = np.clip(np.einsum("kcj,kcj->kc", offset, direction) / self._lengths2[segments], 0.0, 1.0)
        foot = start + fraction[..., None] * direction
        gap = points[:, None, :] - foot
        return foot, np.einsum("kcj,kcj->kc", gap, gap), fraction

    def closest(self, points: np.ndarray) -> CurvePoint:
        """The closest point on the polyline to each of ``points`` (K, 3).

        Exact, in O(log S) per point: the segments with the nearest midpoints are tested first. A segment whose
        midpoint is at distance D has no point nearer than ``D - reach`` (reach: the longest half segment), so when
        the best distance found is below the farthest candidate's ``D - reach``, no other segment can be nearer;
        the rare points where that is not proven are tested against every segment.
        """
        points = np.asarray(points, float).reshape(-1, 3)
        count = len(self.start)
        candidates_count = min(NEAREST_CANDIDATES, count)
        midpoint_distance, candidates = self._tree.query(points, k=candidates_count)
        midpoint_distance = midpoint_distance.reshape(len(points), candidates_count)
        candidates = candidates.reshape(len(points), candidates_count)
        foot, distance2, fraction = self._feet(points, candidates)
        best = np.argmin(distance2, axis=1)
        rows = np.arange(len(points))
        closest, which, along = foot[rows, best], candidates[rows, best], fraction[rows, best]
        if candidates_count < count:
            unproven = np.flatnonzero(np.sqrt(distance2[rows, best]) > midpoint_distance[:, -1] - self._reach)
            chunk_size = max(1, 2_000_000 // count)  # bounded memory: K·S floats at a time
            for begin in range(0, len(unproven), chunk_size):
                chunk = unproven[begin:begin + chunk_size]
                everything = np.broadcast_to(np.arange(count)[None], (len(chunk), count))
                foot_all, distance2_all, fraction_all = self._feet(points[chunk], everything)
                nearest = np.argmin(distance2_all, axis=1)
                closest[chunk] = foot_all[np.arange(len(chunk)), nearest]
                which[chunk] = nearest
                along[chunk] = fraction_all[np.arange(len(chunk)), nearest]
        tangent = self.direction[which] / np.sqrt(self._lengths2[which])[:, None]
        inside = (along > 0.0) & (along < 1.0)  # at a vertex the closest point stays put as p moves a little
        gradient = np.einsum("ki,kj->kij", tangent, tangent) * inside[:, None, None]
        return CurvePoint(closest, tangent, gradient, np.zeros_like(gradient), which, along)


@dataclass(frozen=True, eq=False)
class ParametricCurve:
    """The curve ``c(s) = (x(s), y(s), z(s))`` for s in [``start``, ``end``], from formulas (strings) of s.

    ``samples`` points along it seed the closest-point search; Newton's method then finds the exact parameter (see
    the module's docstring). A ``closed`` curve ends where it starts; its parameter wraps around.
    """

    formulas: tuple[str, str, str]
    start: float
    end: float
    closed: bool = False
    samples: int = 4096
    #: the samples joined into segments (set in __post_init__): the drawn curve and the search's seeds
    polyline: Polyline = field(init=False, repr=False)

    def __post_init__(self) -> None:
        trees = [parse_expression(text) for text in self.formulas]
        first = [differentiate(tree) for tree in trees]
        second = [differentiate(tree) for tree in first]
        object.__setattr__(self, "_position", _compile_all(trees))
        object.__setattr__(self, "_derivatives", _compile_all(trees + first + second))
        parameters = np.linspace(self.start, self.end, self.samples, endpoint=not self.closed)
        points = self.position(parameters)
        if not np.isfinite(points).all():
            raise ExpressionError("the curve is not finite everywhere on its range (check divisions, log, sqrt)")
        starts, directions, first_points = Polyline.segments(points, self.closed)
        spacing = (self.end - self.start) / (self.samples if self.closed else self.samples - 1)
        object.__setattr__(self, "polyline", Polyline(starts, directions))
        object.__setattr__(self, "_segment_parameter", parameters[first_points])
        object.__setattr__(self, "_spacing", spacing)

    def position(self, s: np.ndarray) -> np.ndarray:
        """``c(s)`` [m], shape s.shape + (3,)."""
        return self._position(s)

    def derivatives(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``c(s)``, ``c'(s)`` and ``c''(s)``, (K, 3) each, for parameters s (K,)."""
        values = self._derivatives(s)
        return values[:, 0:3], values[:, 3:6], values[:, 6:9]

    @property
    def length(self) -> float:
        return self.polyline.length

    def _wrap(self, s: np.ndarray) -> np.ndarray:
        if self.closed:
            return self.start + np.mod(s - self.start, self.end - self.start)
        return np.clip(s, self.start, self.end)

    def closest(self, points: np.ndarray) -> CurvePoint:
        """The closest point on the curve to each of ``points`` (K, 3): the sampled polyline's closest point,
        refined by Newton's method on ``g(s) = (c(s) - p)·c'(s)``, ``g' = |c'|² + (c - p)·c''``."""
        points = np.asarray(points, float).reshape(-1, 3)
        seed = self.polyline.closest(points)
        s = self._segment_parameter[seed.segment] + seed.fraction * self._spacing
        for iteration in range(NEWTON_ITERATIONS + 1):
            c, d1, d2 = self.derivatives(s)
            gap = c - points
            slope = np.einsum("kj,kj->k", d1, d1) + np.einsum("kj,kj->k", gap, d2)
            # where g' ≤ 0 the seed is not near a minimum (a cusp, or the middle of a circle): keep it
            change = np.where(slope > 0, np.einsum("kj,kj->k", gap, d1) / np.where(slope > 0, slope, 1.0), 0.0)
            if iteration == NEWTON_ITERATIONS or np.all(np.abs(change) <= 1e-14 * (self.end - self.start)):
                break  # converged: c, c', c'' are those at s
            s = self._wrap(s - change)
        speed = np.linalg.norm(d1, axis=1)
        tangent = d1 / np.where(speed > 0, speed, 1.0)[:, None]
        # ∂s/∂p = c'ᵀ / g' (from g(s(p), p) = 0), zero at a clamped end of an open curve
        at_end = ~self.closed & ((s <= self.start) | (s >= self.end))
        parameter_gradient = np.where((slope > 0) & ~at_end, 1.0 / np.where(slope > 0, slope, 1.0), 0.0)[:, None] * d1
        position_gradient = np.einsum("ki,kj->kij", d1, parameter_gradient)
        # ∂t/∂s = (I - t tᵀ) c'' / |c'|
        turn = (d2 - np.einsum("kj,kj->k", tangent, d2)[:, None] * tangent) / np.where(speed > 0, speed, 1.0)[:, None]
        tangent_gradient = np.einsum("ki,kj->kij", turn, parameter_gradient)
        return CurvePoint(c, tangent, position_gradient, tangent_gradient, seed.segment, seed.fraction)
