"""Prescribed motion: anchors that stay put or follow keyframes, and solids that follow posed keyframes or a
closed-form motion (moving colliders and kinematic rigid bodies: :class:`PosePath`, :class:`ClosedFormPath`, and
:class:`KinematicBodies`).

An anchor is a point the simulation does not move; springs and cloth pins attach to it. With keyframes it follows a
path: ``linear`` interpolation (constant velocity between keys) or ``cubic`` (a C² cubic spline through the keys,
starting and ending at rest). Before the first key and after the last the anchor holds its position. Velocities are
the exact derivatives of the interpolant, so dampers see the anchor's true speed.
"""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from animbatch import quaternion
from animbatch.sim.memo import remembered

if TYPE_CHECKING:  # SciPy's interpolation and rotations load when a path is built, not with the package
    from scipy.spatial.transform import Rotation


class PiecewiseCubic:
    """A SciPy piecewise cubic (``CubicSpline``, ``CubicHermiteSpline``, a ``RotationSpline``'s interpolator) read
    at one instant at a time: the same pieces and the same rule for which piece holds a time (the first and last
    extend beyond the breaks), evaluated by Horner's rule without SciPy's per-call overhead (some 30 µs, which a
    moving collider paid several times a step)."""

    def __init__(self, spline: Any) -> None:
        self._breaks = [float(x) for x in spline.x]
        self._coefficients = np.asarray(spline.c)  # (4, pieces, …): c[m] multiplies (t − t_k)^(3 − m)
        if self._coefficients.shape[0] != 4:
            raise ValueError(f"not a cubic: {self._coefficients.shape[0] - 1} is the degree")

    @property
    def coefficients(self) -> np.ndarray:
        """The pieces' coefficients (4, pieces, …), highest power first (SciPy's ``c``)."""
        return self._coefficients

    def __call__(self, t: float, derivative: int = 0) -> Any:
        """The value (…) at time ``t`` [s], or its first or second ``derivative``."""
        k = min(max(bisect_right(self._breaks, t) - 1, 0), len(self._breaks) - 2)
        s = t - self._breaks[k]
        c0, c1, c2, c3 = self._coefficients[:, k]
        if derivative == 0:
            return ((c0 * s + c1) * s + c2) * s + c3
        if derivative == 1:
            return (3.0 * c0 * s + 2.0 * c1) * s + c2
        return 6.0 * c0 * s + 2.0 * c1


@dataclass(frozen=True, eq=False)
class KeyframePath:
    """A path through ``positions`` (K, 3) [m] at increasing ``times`` (K,) [s]."""

    times: np.ndarray
    positions: np.ndarray
    interpolation: str = "linear"
    # derived in __post_init__: the key times as floats, and the cubic spline through the keys (cubic only)
    _breaks: list[float] = field(init=False, repr=False)
    _spline: PiecewiseCubic = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_breaks", [float(x) for x in self.times])
        if self.interpolation == "cubic" and len(self.times) > 1:
            from scipy.interpolate import CubicSpline

            spline = CubicSpline(self.times, self.positions, bc_type="clamped")
            object.__setattr__(self, "_spline", PiecewiseCubic(spline))

    def _clamped(self, t: float) -> float:
        return min(max(float(t), float(self.times[0])), float(self.times[-1]))

    def position(self, t: float) -> np.ndarray:
        """Position (3,) [m] at time ``t`` [s]."""
        if len(self.times) == 1:
            return self.positions[0]
        if self.interpolation == "cubic":
            return self._spline(self._clamped(t))
        t = self._clamped(t)
        breaks = self._breaks
        k = min(max(bisect_right(breaks, t) - 1, 0), len(breaks) - 2)
        along = (t - breaks[k]) / (breaks[k + 1] - breaks[k])
        return self.positions[k] + along * (self.positions[k + 1] - self.positions[k])

    def acceleration(self, t: float) -> np.ndarray:
        """Acceleration (3,) [m/s²] at time ``t`` [s]: the spline's second derivative between cubic keys, zero on
        linear segments (their kinks are impulses no step can take) and outside the keys."""
        if self.interpolation != "cubic" or len(self.times) == 1 or t < self.times[0] or t > self.times[-1]:
            return np.zeros(3)
        return self._spline(t, 2)

    def velocity(self, t: float) -> np.ndarray:
        """Velocity (3,) [m/s] at time ``t`` [s] (zero outside the keys)."""
        if len(self.times) == 1 or t < self.times[0] or t > self.times[-1]:
            return np.zeros(3)
        if self.interpolation == "cubic":
            return self._spline(t, 1)
        segment = int(np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 2))
        span = self.times[segment + 1] - self.times[segment]
        return (self.positions[segment + 1] - self.positions[segment]) / span


@dataclass(frozen=True, eq=False)
class AnchorMotion:
    """Where the A anchors are at any time: ``rest`` (A, 3) [m] for the fixed ones, and keyframe paths for the
    moving ones (``paths``: anchor index -> path)."""

    rest: np.ndarray
    paths: dict[int, KeyframePath]

    @property
    def count(self) -> int:
        return len(self.rest)

    @property
    def moving(self) -> bool:
        return bool(self.paths)

    def only(self, used: np.ndarray) -> AnchorMotion:
        """The same anchors, with keyframes kept only for the ``used`` (indices): what one force term needs, so
        that a moving anchor nothing is attached to costs no evaluation."""
        wanted = {int(i) for i in np.asarray(used).ravel()}
        return AnchorMotion(self.rest, {i: path for i, path in self.paths.items() if i in wanted})

    def positions(self, t: float) -> np.ndarray:
        """Anchor positions (A, 3) [m] at time ``t`` [s] (the fixed array itself when nothing moves)."""
        if not self.paths:
            return self.rest
        result = self.rest.copy()
        for index, path in self.paths.items():
            result[index] = path.position(t)
        return result

    def velocities(self, t: float) -> np.ndarray:
        """Anchor velocities (A, 3) [m/s] at time ``t`` [s]."""
        result = np.zeros_like(self.rest)
        for index, path in self.paths.items():
            result[index] = path.velocity(t)
        return result


@dataclass(frozen=True, eq=False)
class PosePath:
    """How a kinematic solid (a moving collider, a rigid body on keyframes) moves: its rest centre ``centre`` (3,)
    [m], displaced by ``offsets`` (a path of (3,) offsets [m]) and turned about the centre by ``turns`` (Rotations at
    ``times`` (K,) [s]), ``interpolation`` 'linear' or 'cubic'."""

    centre: np.ndarray
    times: np.ndarray
    offsets: KeyframePath
    turns: Rotation
    interpolation: str
    # built from the keys in __post_init__ (two or more keys): the keys' turns (K, 3, 3); slerp's turns between
    # keys (K − 1, 3); the cubic's rotation vector r(s) and the easing s(t) (SciPy piecewise polynomials)
    _keys: np.ndarray = field(init=False, repr=False)
    _steps: np.ndarray = field(init=False, repr=False)
    _rotation_vector: Any = field(init=False, repr=False)
    _ease: Any = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if len(self.times) < 2:
            return
        # Both interpolants turn key k's rotation R_k by exp(r) for a rotation vector r that depends on the time:
        # slerp (as SciPy's Slerp) by r = α φ_k, φ_k the turn from key k to k + 1 in key k's axes; the cubic (SciPy's
        # RotationSpline) by a cubic polynomial r(t) per interval. They are evaluated here from those pieces: a step
        # reads the turn and its rate at a few instants, and SciPy's rotation objects cost more than the arithmetic.
        object.__setattr__(self, "_keys", self.turns.as_matrix())
        if self.interpolation != "cubic":
            object.__setattr__(self, "_steps", (self.turns[:-1].inv() * self.turns[1:]).as_rotvec())
            return
        from scipy.interpolate import CubicHermiteSpline
        from scipy.spatial.transform import RotationSpline

        rotation_vector = RotationSpline(self.times, self.turns).interpolator
        object.__setattr__(self, "_rotation_vector", PiecewiseCubic(rotation_vector))
        # A rotation spline through two keys turns at a constant rate, and through more it starts and ends turning:
        # a jolt at the first and last keys. Eased, it is read at a warped time that passes every key at its own
        # time with rate 1, and the first and last at rate 0 (a monotone Hermite cubic: Fritsch–Carlson), so a
        # cubic turn starts and ends at rest like the offsets' clamped spline.
        slopes = np.ones(len(self.times))
        slopes[[0, -1]] = 0.0
        object.__setattr__(self, "_ease", PiecewiseCubic(CubicHermiteSpline(self.times, self.times, slopes)))

    def _segment(self, t: float) -> tuple[int, float]:
        """The key interval (index k) holding time t [s], clamped to the keys, and how far along it t is (0 … 1)."""
        clamped = min(max(t, float(self.times[0])), float(self.times[-1]))
        k = min(max(int(np.searchsorted(self.times, clamped, side="right")) - 1, 0), len(self.times) - 2)
        return k, (clamped - float(self.times[k])) / float(self.times[k + 1] - self.times[k])

    def turn(self, t: float) -> np.ndarray:
        """The turn (3, 3) at time t [s], held before the first key and after the last."""
        if len(self.times) == 1:
            return self.turns[0].as_matrix()
        return remembered(self, "turn", t, lambda: self._turn(t))

    def _turn(self, t: float) -> np.ndarray:
        """:meth:`turn`, computed (for a path of two keys or more)."""
        if self.interpolation != "cubic":
            k, along = self._segment(t)
            turned = along * self._steps[k]
        else:
            eased = float(self._ease(float(np.clip(t, self.times[0], self.times[-1]))))
            k, _ = self._segment(eased)
            turned = self._rotation_vector(eased)
        return self._keys[k] @ quaternion.to_matrix(quaternion.from_rotation_vector(turned))

    def pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Centre (3,) [m] and turn (3, 3) at time t: a rest point p goes to ``turn (p − c₀) + c₀ + offset``."""
        return remembered(self, "centre", t, lambda: self.centre + self.offsets.position(t)), self.turn(t)

    def velocity(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Velocity of the centre (3,) [m/s] and angular velocity (3,) [rad/s], world axes, at time t."""
        return remembered(self, "velocity", t, lambda: (self.offsets.velocity(t), self._angular_velocity(t)))

    def _angular_velocity(self, t: float) -> np.ndarray:
        """The turn's rate (3,) [rad/s], world axes, at time t [s]: the exact derivative of the interpolant."""
        if len(self.times) == 1 or t < self.times[0] or t > self.times[-1]:
            return np.zeros(3)
        if self.interpolation != "cubic":  # slerp: the key's turn φ_k over the interval, in world axes
            k, _ = self._segment(t)
            return self._keys[k] @ self._steps[k] / float(self.times[k + 1] - self.times[k])
        # R = R_k exp(r(s)) at the eased time s: the rate in the turned body's axes is ṙ − k₁ r × ṙ + k₂ r × (r × ṙ)
        # (the rotation vector's derivative mapped to an angular rate, as SciPy's RotationSpline), scaled by the
        # easing's slope and turned into world axes
        eased = float(self._ease(t))
        r = self._rotation_vector(eased)
        r_dot = self._rotation_vector(eased, 1)
        angle = float(np.sqrt(r @ r))
        if angle > 1e-4:
            k1, k2 = (1 - np.cos(angle)) / angle**2, (angle - np.sin(angle)) / angle**3
        else:  # their series, as SciPy's
            k1, k2 = 0.5 - angle**2 / 24, 1 / 6 - angle**2 / 120
        across = quaternion.cross(r, r_dot)
        body_rate = r_dot - k1 * across + k2 * quaternion.cross(r, across)
        return float(self._ease(t, 1)) * (self.turn(t) @ body_rate)

    def matrix(self, t: float) -> np.ndarray:
        """The 4 × 4 transform from the rest pose to the pose at time t (for drawing)."""
        return pose_matrix(self.centre, *self.pose(t))


@dataclass(frozen=True, eq=False)
class ClosedFormPath:
    """How a kinematic solid moves in closed form (the kinematic mode's motions, for solids): its pivot, at rest at
    ``centre`` (3,) [m], moves by ``drift t + amplitude e^(−γ t) sin(2π f t + φ)`` ((3,) [m/s], (3,) [m],
    ``frequency`` f [Hz], ``phase`` φ [rad], ``damping`` γ [1/s]), and the solid turns about it by the rotation
    vector ``angular_velocity t`` ((3,) [rad/s], world axes). From t = 0; held at its t = 0 pose before."""

    centre: np.ndarray
    drift: np.ndarray
    angular_velocity: np.ndarray
    amplitude: np.ndarray
    frequency: float = 0.0
    phase: float = 0.0
    damping: float = 0.0

    def turn(self, t: float) -> np.ndarray:
        """The turn (3, 3) at time t [s]."""
        from scipy.spatial.transform import Rotation

        return Rotation.from_rotvec(self.angular_velocity * max(t, 0.0)).as_matrix()

    def pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Pivot (3,) [m] and turn (3, 3) at time t: a rest point p goes to ``turn (p − c₀) + pivot``."""
        t = max(t, 0.0)
        swing = np.exp(-self.damping * t) * np.sin(2 * np.pi * self.frequency * t + self.phase)
        return self.centre + self.drift * t + self.amplitude * swing, self.turn(t)

    def velocity(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Velocity of the pivot (3,) [m/s] and angular velocity (3,) [rad/s] at time t: the exact derivatives."""
        if t < 0:
            return np.zeros(3), np.zeros(3)
        rate = 2 * np.pi * self.frequency
        decay = np.exp(-self.damping * t)
        swing = decay * (rate * np.cos(rate * t + self.phase) - self.damping * np.sin(rate * t + self.phase))
        return self.drift + self.amplitude * swing, self.angular_velocity

    def matrix(self, t: float) -> np.ndarray:
        """The 4 × 4 transform from the rest pose to the pose at time t (for drawing)."""
        return pose_matrix(self.centre, *self.pose(t))


def pose_matrix(rest_centre: np.ndarray, centre: np.ndarray, turn: np.ndarray) -> np.ndarray:
    """The 4 × 4 transform that turns a solid by ``turn`` about its pivot and moves the pivot from ``rest_centre``
    to ``centre``."""
    transform = np.eye(4)
    transform[:3, :3] = turn
    transform[:3, 3] = centre - turn @ rest_centre
    return transform


#: Either kind of prescribed pose.
SolidPath = PosePath | ClosedFormPath


@dataclass(frozen=True, eq=False)
class KinematicBodies:
    """Rigid bodies on keyframes (kinematic bodies): ``rigid`` (K,) their indices among the rigid bodies, each
    moving along ``paths[k]`` (K,) about its position (the shape's origin), with ``rest`` (K, 3, 3) its orientation
    at rest and ``lever`` (K, 3) [m] its centre of mass from its position at rest, world axes.

    At time t a body on its path has ``R(t) = turn(t) R₀``, centre of mass ``o(t) + turn(t) lever``, velocity
    ``o'(t) + ω × turn(t) lever`` and angular velocity ``ω(t)``, the path's own."""

    rigid: np.ndarray
    paths: tuple[SolidPath, ...]
    rest: np.ndarray
    lever: np.ndarray

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Centres of mass (K, 3) [m], rotations (K, 3, 3), velocities (K, 3) [m/s] and angular velocities (K, 3)
        [rad/s] at time t [s]."""
        count = len(self.paths)
        x, rotation = np.zeros((count, 3)), np.zeros((count, 3, 3))
        v, omega = np.zeros((count, 3)), np.zeros((count, 3))
        for k, path in enumerate(self.paths):
            origin, turn = path.pose(t)
            velocity, spin = path.velocity(t)
            arm = turn @ self.lever[k]
            x[k], rotation[k] = origin + arm, turn @ self.rest[k]
            v[k], omega[k] = velocity + np.cross(spin, arm), spin
        return x, rotation, v, omega
