"""From joints as a model builder receives them (world points and axes at the start) to the row kinds of a
:class:`~animbatch.sim.joints.Joints`."""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from animbatch.sim.joints import Joints
from animbatch.sim.joints.kinds import AngleRows, AxisRows, LockRows, PointRows, RowKind, SegmentRows, SlideRows
from animbatch.sim.joints.motors import Motors, MotorTarget
from animbatch.sim.motion import KeyframePath

WORLD = -1
#: Joint ends at anchors on keyframes: ``MOVING_ANCHOR − m`` for the m-th (see :func:`assemble`).
MOVING_ANCHOR = -2
#: The joint types, and which of them hold orientations (so need rigid bodies).
TYPES = ("distance", "rope", "pulley", "ball", "hinge", "slider", "fixed")
TURNING = ("hinge", "slider", "fixed")


@dataclass(frozen=True)
class MotorSetting:
    """A joint motor: ``target`` q*(t) (None: a speed servo), target ``speed`` [rad/s or m/s], ``stiffness``
    [N·m/rad or N/m], ``damping`` [N·m·s/rad or N·s/m], ``max_effort`` [N·m or N]."""

    target: MotorTarget
    stiffness: float
    damping: float
    max_effort: float = np.inf


@dataclass(frozen=True)
class JointSetting:
    """One joint between model points ``first`` and ``second`` (``WORLD``: the world).

    ``first_offset``/``second_offset`` (3,): the joint's points on each body in body axes from the centre of mass
    (on the world: the world point). For ball, hinge, slider and fixed joints they are the same world point at the
    start; for distance joints and ropes the two ends; for pulleys the ropes' ends, with ``over`` (2, 3) the
    pulleys [m]. ``axis`` (3,): hinge or slider axis, world axes at the start. ``length`` [m] (None: at the start),
    ``limits`` (lower, upper) [rad or m], ``motor``; ``name`` for messages."""

    type: str
    first: int
    second: int
    first_offset: np.ndarray
    second_offset: np.ndarray
    name: str
    axis: np.ndarray | None = None
    length: float | None = None
    limits: tuple[float, float] | None = None
    motor: MotorSetting | None = None
    over: np.ndarray | None = None


@dataclass
class _Collected:
    """Row data of one kind, gathered joint by joint."""

    bodies: list = field(default_factory=list)
    joint: list = field(default_factory=list)
    columns: dict = field(default_factory=lambda: defaultdict(list))

    def add(self, bodies: tuple[int, int], joint: int, rows: int = 1, **columns: object) -> None:
        self.bodies += [bodies] * rows
        self.joint += [joint] * rows
        for name, value in columns.items():
            self.columns[name].append(value)

    def arrays(self, stacked: tuple[str, ...] = ()) -> dict:
        return {name: (np.concatenate if name in stacked else np.array)(values)
                for name, values in self.columns.items()}


def _across(axis: np.ndarray) -> np.ndarray:
    """Two unit vectors (2, 3) across ``axis`` (3,), the three right-handed."""
    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    first = np.cross(axis, helper)
    first /= np.linalg.norm(first)
    return np.array([first, np.cross(axis, first)])


def assemble(settings: list[JointSetting], x0: np.ndarray, rotation0: np.ndarray, mass: np.ndarray,
             inertia: np.ndarray, first_rigid: int, anchor_paths: tuple[KeyframePath, ...] = (),
             anchor_starts: np.ndarray | None = None) -> Joints:
    """The :class:`Joints` of ``settings`` for bodies at ``x0`` (P, 3) [m] with rotations ``rotation0`` (P, 3, 3)
    (identity for particles), masses (P,) [kg] and body-axes inertia (P, 3, 3) [kg·m²] (zero for particles).
    Ends ``MOVING_ANCHOR − m`` are held by the m-th of ``anchor_paths``, which starts at ``anchor_starts[m]``
    (their offsets are from there)."""
    ends = np.array([[s.first, s.second] for s in settings], np.intp)
    points = np.unique(ends[ends >= 0])
    world = len(points) + len(anchor_paths)
    compact = {int(point): k for k, point in enumerate(points)}
    compact.update({MOVING_ANCHOR - m: len(points) + m for m in range(len(anchor_paths))})
    compact[WORLD] = world
    turn = lambda point: rotation0[point] if point >= 0 else np.eye(3)  # noqa: E731
    starts = np.zeros((0, 3)) if anchor_starts is None else anchor_starts

    segments, balls, axes, locks = _Collected(), _Collected(), _Collected(), _Collected()
    slides, angles = _Collected(), _Collected()
    motors: list[tuple[int, bool, JointSetting]] = []
    descriptions = []
    for k, s in enumerate(settings):
        pair = (compact[s.first], compact[s.second])
        turn_a, turn_b = turn(s.first), turn(s.second)
        if s.type in ("distance", "rope", "pulley"):
            start = _segment_start(s, x0, turn_a, turn_b, starts)
            length = float(np.sum(start)) if s.length is None else float(s.length)
            if length <= 0:
                raise ValueError(f"joint {s.name!r} has length {length:g} m: it needs a positive length")
            sign = -1.0 if s.type == "rope" else 1.0
            row = len(segments.bodies)
            if s.type == "pulley":
                assert s.over is not None
                segments.add(pair, k, length=length, sign=sign, unilateral=False)
                for slot, (body, offset, pulley) in enumerate(((pair[0], s.first_offset, s.over[0]),
                                                               (pair[1], s.second_offset, s.over[1]))):
                    segments.columns["segment"].append((row, body, offset, slot, world, pulley, -1))
                descriptions.append(f"pulley rope {length:g} m")
            else:
                segments.add(pair, k, length=length, sign=sign, unilateral=s.type == "rope")
                segments.columns["segment"].append((row, pair[0], s.first_offset, 0, pair[1], s.second_offset,
                                                    1 if pair[1] != world else -1))
                descriptions.append(f"{'rope ≤' if s.type == 'rope' else 'rod'} {length:g} m")
            continue
        balls_too = s.type in ("ball", "hinge", "fixed")
        if balls_too:
            balls.add(pair, k, 3, first_offset=s.first_offset, second_offset=s.second_offset)
        if s.type in ("fixed", "slider"):
            locks.add(pair, k, 3, relative=turn_a.T @ turn_b)
        text = {"ball": "ball", "fixed": "fixed (welded)"}.get(s.type, "")
        if s.type in ("hinge", "slider"):
            assert s.axis is not None
            axis = s.axis / np.linalg.norm(s.axis)
            across = _across(axis)
            hinge = s.type == "hinge"
            if hinge:
                axes.add(pair, k, 2, axis=turn_b.T @ axis, across=across @ turn_a)
                angle: dict[str, Any] = dict(axis=turn_b.T @ axis, first_reference=turn_a.T @ across[0],
                             second_reference=turn_b.T @ across[0])
                for bound, sign in zip(s.limits or (), (1.0, -1.0)):
                    angles.add(pair, k, bound=bound, sign=sign, **angle)
            else:
                slide: dict[str, Any] = dict(first_offset=s.first_offset, second_offset=s.second_offset)
                for direction in across:
                    slides.add(pair, k, direction=turn_b.T @ direction, bound=0.0, sign=1.0, unilateral=False,
                               **slide)
                for bound, sign in zip(s.limits or (), (1.0, -1.0)):
                    slides.add(pair, k, direction=turn_b.T @ axis, bound=bound, sign=sign, unilateral=True, **slide)
            text = f"{s.type} {'about' if hinge else 'along'} ({', '.join(f'{c:.3g}' for c in axis)})"
            if s.limits is not None:
                text += f", limits [{s.limits[0]:g}, {s.limits[1]:g}] {'rad' if hinge else 'm'}"
            if s.motor is not None:
                motors.append((k, hinge, s))
                text += ", motor"
        descriptions.append(text)

    kinds: list[RowKind] = []
    if segments.bodies:
        kinds.append(_segment_rows(segments))
    for collected, kind, unit in ((balls, PointRows, "m"), (axes, AxisRows, "rad"), (locks, LockRows, "rad")):
        if collected.bodies:
            step = 2 if kind is AxisRows else 3
            columns = {name: np.array(values) for name, values in collected.columns.items()}
            kinds.append(kind(np.array(collected.bodies), np.array(collected.joint),
                              np.zeros(len(collected.bodies), bool), unit, **columns))
            assert len(collected.bodies) == step * len(next(iter(columns.values())))
    if slides.bodies:
        columns = slides.arrays()
        kinds.append(SlideRows(np.array(slides.bodies), np.array(slides.joint), columns.pop("unilateral"), "m",
                               **columns))
    if angles.bodies:
        kinds.append(AngleRows(np.array(angles.bodies), np.array(angles.joint), np.ones(len(angles.bodies), bool),
                               "rad", **angles.arrays()))
    inverse_mass = 1.0 / mass[points]
    inverse_inertia = np.zeros((len(points), 3, 3))
    rigid = points >= first_rigid
    inverse_inertia[rigid] = np.linalg.inv(inertia[points[rigid]])
    distances = [np.linalg.norm(x0[p]) for p in points] + [1.0]
    return Joints(tuple(s.name for s in settings), tuple(s.type for s in settings), tuple(descriptions), points,
                  first_rigid, inverse_mass, np.array(inertia[points]), inverse_inertia, tuple(kinds),
                  np.array([compact[s.first] for s in settings]), np.array([s.first_offset for s in settings]),
                  _motors(motors, compact, rotation0), scale=float(max(distances)), anchor_paths=anchor_paths,
                  anchor_starts=starts)


def _segment_start(s: JointSetting, x0: np.ndarray, turn_a: np.ndarray, turn_b: np.ndarray,
                   anchor_starts: np.ndarray) -> np.ndarray:
    """The lengths (segments,) [m] of a rod's, rope's or pulley's segments at the start."""
    start_a = x0[s.first] + turn_a @ s.first_offset
    if s.type == "pulley":
        assert s.over is not None
        start_b = x0[s.second] + turn_b @ s.second_offset
        return np.array([np.linalg.norm(start_a - s.over[0]), np.linalg.norm(start_b - s.over[1])])
    if s.second == WORLD:
        start_b = s.second_offset
    elif s.second < 0:  # a moving anchor: its offset is from where it starts
        start_b = anchor_starts[MOVING_ANCHOR - s.second] + s.second_offset
    else:
        start_b = x0[s.second] + turn_b @ s.second_offset
    return np.array([np.linalg.norm(start_a - start_b)])


def _segment_rows(collected: _Collected) -> SegmentRows:
    row, near, near_offset, near_slot, far, far_offset, far_slot = zip(*collected.columns.pop("segment"))
    columns = collected.arrays()
    return SegmentRows(np.array(collected.bodies), np.array(collected.joint), columns.pop("unilateral"), "m",
                       np.array(row), np.array(near), np.array(near_offset), np.array(near_slot), np.array(far),
                       np.array(far_offset), np.array(far_slot), columns["length"], columns["sign"])


def _motors(motors: list[tuple[int, bool, JointSetting]], compact: dict[int, int],
            rotation0: np.ndarray) -> Motors | None:
    if not motors:
        return None
    hinge = np.array([is_hinge for _, is_hinge, _ in motors])
    angles, travels = _Collected(), _Collected()
    for k, is_hinge, s in motors:
        assert s.axis is not None
        pair = (compact[s.first], compact[s.second])
        turn_a = rotation0[s.first]
        turn_b = rotation0[s.second] if s.second >= 0 else np.eye(3)
        axis = s.axis / np.linalg.norm(s.axis)
        if is_hinge:
            across = _across(axis)
            angles.add(pair, k, axis=turn_b.T @ axis, first_reference=turn_a.T @ across[0],
                       second_reference=turn_b.T @ across[0], bound=0.0, sign=1.0)
        else:
            travels.add(pair, k, first_offset=s.first_offset, second_offset=s.second_offset,
                        direction=turn_b.T @ axis, bound=0.0, sign=1.0)
    settings = [s.motor for _, _, s in motors]

    angle_rows = (AngleRows(np.array(angles.bodies), np.array(angles.joint), np.zeros(len(angles.bodies), bool),
                            "rad", **angles.arrays()) if angles.bodies else None)
    slide_rows = (SlideRows(np.array(travels.bodies), np.array(travels.joint), np.zeros(len(travels.bodies), bool),
                            "m", **travels.arrays()) if travels.bodies else None)
    chosen = [setting for setting in settings if setting is not None]
    return Motors(np.array([k for k, _, _ in motors]), hinge, angle_rows, slide_rows,
                  tuple(m.target for m in chosen), np.array([m.stiffness for m in chosen]),
                  np.array([m.damping for m in chosen]), np.array([m.max_effort for m in chosen]))
