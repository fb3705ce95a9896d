"""The flat tables the compiled equations of motion read: a Model's bodies, force terms, keyframe paths, joints and
the pattern of their coupling solve, packed into one float64 array, one int64 array and a layout.

Why packed: numba passes every array of a tuple to a compiled function as separate arguments, and a function taking
the ~90 arrays of a model as a tuple took a second to compile and 20 µs to call; three arrays take neither. Each
kernel takes ``(floats, integers, layout)`` and views the fields it needs by their numbers below
(:func:`animbatch.sim.kernels.rigid_motion.column`, ``table``, ``blocks``). Nothing here imports numba:
:mod:`animbatch.sim.model.compiled` fills the fields from a Model and :func:`pack` lays them out.

Each field is an array whose first axis counts its items (rows) and whose other axes are fixed: the comment after a
field gives its shape (P points: N particles then B rigid bodies, as in the Model), unit and columns. A model
without something has zero rows of it. Integer fields are int64 (flags are 0 or 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# The fields, by number (the layout's row). Plain integers, not an enum: numba compiles a kernel that takes an
# enum member several times slower.
# bodies
PARTICLE_INVERSE_MASS = 0  # (N,) [1/kg]
RIGID_INVERSE_MASS = 1  # (B,) [1/kg]
INERTIA = 2  # (B, 3, 3) [kg·m²], body axes, about the centre of mass
INVERSE_INERTIA = 3  # (B, 3, 3) [1/(kg·m²)]
# force terms
CONSTANT_FORCE = 4  # (P, 3) [N]: the forces that never change, summed (weights)
CONSTANT_TORQUE = 5  # (B, 3) [N·m]
SPRING_ENDS = 6  # int (S, 3): first point, second point or anchor, whether the second is an anchor
SPRING_OFFSETS = 7  # (S, 2, 3) [m]: attachment points, body axes from the centre of mass (0 at a centre)
SPRING_CONSTANTS = 8  # (S, 3): stiffness ks [N/m], damping kd [N·s/m], rest length [m]
ANCHOR_REST = 9  # (A, 3) [m]
ANCHOR_PATH = 10  # int (A,): the keyframe path an anchor follows, or −1
# keyframe paths: path q has the keys start … start + count − 1 of the two arrays after it
PATH_KEYS = 11  # int (Q, 2): start, count
PATH_TIMES = 12  # (T,) [s]
PATH_COEFFICIENTS = 13  # (T, 4, 3): after key i, Σ_m c[i, m] (t − tᵢ)^(3−m); the last key's row holds its value
# joints: slots are the J joined bodies, then M anchors on keyframes, then the world
JOINT_POINTS = 14  # int (J,): the model point of each joined body
SLOT_RIGID = 15  # int (J + M + 1,): the rigid index of a slot, or −1
SLOT_INVERSE_MASS = 16  # (J + M + 1,) [1/kg]: zero but for the joined bodies
SLOT_PATH = 17  # int (J + M + 1,): an anchor's path, or −1
ROW_BODIES = 18  # int (R, 2): each row's two slots
ROW_UNILATERAL = 19  # int (R,): limits and ropes (C ≥ 0)
JOINT_SCALE = 20  # (1,) [m]: the joints' size, for tolerances
KIND_ROWS = 21  # int (6,): the first row of the segment, point, axis, lock, slide and angle rows
SEGMENT_ENDS = 22  # int (S, 5): row (of the segment rows), near slot, near end, far slot, far end (−1: fixed)
SEGMENT_OFFSETS = 23  # (S, 2, 3) [m]: near and far points (a fixed far end: the world point)
SEGMENT_ROWS = 24  # (K, 2): length [m], sign (+1 rod, −1 rope)
POINT_BODIES = 25  # int (Jp, 2): ball joints (3 rows each)
POINT_OFFSETS = 26  # (Jp, 2, 3) [m]
AXIS_BODIES = 27  # int (Ja, 2): hinge axes (2 rows each)
AXIS_AXIS = 28  # (Ja, 3): the axis, second body's axes
AXIS_ACROSS = 29  # (Ja, 2, 3): two directions across it, first body's axes
LOCK_BODIES = 30  # int (Jl, 2): welds and sliders' orientation (3 rows each)
LOCK_RELATIVE = 31  # (Jl, 3, 3): R_aᵀ R_b at the start
SLIDE_BODIES = 32  # int (Ks, 2): slider rows
SLIDE_OFFSETS = 33  # (Ks, 2, 3) [m]
SLIDE_DIRECTION = 34  # (Ks, 3): second body's axes
SLIDE_BOUNDS = 35  # (Ks, 2): bound [m], sign
ANGLE_BODIES = 36  # int (Ka, 2): hinge limit rows
ANGLE_AXIS = 37  # (Ka, 3): second body's axes
ANGLE_REFERENCES = 38  # (Ka, 2, 3): reference directions, first and second body's axes
ANGLE_BOUNDS = 39  # (Ka, 2): bound [rad], sign
MOTOR_BODIES = 40  # int (Mo, 2)
MOTOR_KIND = 41  # int (Mo, 2): whether it drives a hinge (else a slider), the target's path or −1
MOTOR_AXIS = 42  # (Mo, 3): hinge axis or slider direction, second body's axes
MOTOR_REFERENCES = 43  # (Mo, 2, 3): a hinge's reference directions
MOTOR_OFFSETS = 44  # (Mo, 2, 3) [m]: a slider's points
MOTOR_GAINS = 45  # (Mo, 4): target speed, stiffness, damping, largest effort
# the coupling solve (see animbatch.sim.joints.pattern)
ORDER = 46  # int (R,): rows in elimination order
COLUMN_START = 47  # int (R + 1,): L's columns in the entries
COLUMN_ROWS = 48  # int (E,): each entry's row (elimination order), the diagonal first in its column
PAIRS = 49  # int (Q, 5): two row ends (row, end; row, end) that meet at a body, and the entry their product adds to
UPDATE_START = 50  # int (R + 1,): each column's updates
UPDATES = 51  # int (U, 3): target entry, the two entries whose product (over the pivot) it loses


# inverse-square pair laws (gravitation, Coulomb): term t acts between the points PAIR_START[t] … PAIR_START[t + 1] − 1
PAIR_TERMS = 52  # (T, 2): coupling κ (G, or −k), softening ε [m]
PAIR_START = 53  # int (T + 1,)
PAIR_POINTS = 54  # int (S,): the points of every term, one after the other
PAIR_SOURCE = 55  # (S,): each point's source strength (mass [kg], or charge [C])
# buoyancy of bodies made of spheres (a term with surface pieces has no compiled form)
BUOYANCY_TERMS = 56  # (T, 7): ρ g [N/m³], surface level [m], up (3), linear [N·s/m] and angular [N·m·s] damping
BUOYANCY_SPHERES = 57  # int (K, 3): each sphere piece's point, its rigid index or −1 (a particle), its term
BUOYANCY_SHAPES = 58  # (K, 4): its centre in body axes from the centre of mass [m] (3), its radius [m]
BUOYANCY_BODIES = 59  # int (S, 2): each selected point and its term
BUOYANCY_VOLUMES = 60  # (S,): their whole volumes [m³]
# drag (and wind): each term's points dragged at their centre of mass, then the rigid bodies dragged at a point
DRAG_TERMS = 61  # (T, 4): quadratic (1) or linear (0, Stokes' law included), the wind's velocity (3) [m/s]
DRAG_POINTS = 62  # int (D, 3): a dragged point, its rigid index where dragged at a body point (else −1), its term
DRAG_SHAPES = 63  # (D, 4): the body point in body axes from the centre of mass [m] (3), the coefficient C
# applied loads, in the order of their terms: a force (at a body point), a torque, angular drag
LOAD_POINTS = 64  # int (L, 3): the point, its rigid index (−1: a particle), the kind (FORCE_LOAD, TORQUE_LOAD, …)
LOAD_VALUES = 65  # (L, 7): the vector [N or N·m] (angular drag: c [N·m·s], 0, 0), body axes (1) or world (0),
#                   the point in body axes from the centre of mass [m] (3)
#: How many fields there are.
FIELD_COUNT = 66
#: The kinds of applied load (LOAD_POINTS' third column).
FORCE_LOAD, TORQUE_LOAD, ANGULAR_DRAG_LOAD = 0, 1, 2

#: Each field's shape after its first axis.
TRAILING: dict[int, tuple[int, ...]] = {
    PARTICLE_INVERSE_MASS: (), RIGID_INVERSE_MASS: (), INERTIA: (3, 3),
    INVERSE_INERTIA: (3, 3), CONSTANT_FORCE: (3,), CONSTANT_TORQUE: (3,), SPRING_ENDS: (3,),
    SPRING_OFFSETS: (2, 3), SPRING_CONSTANTS: (3,), ANCHOR_REST: (3,), ANCHOR_PATH: (),
    PATH_KEYS: (2,), PATH_TIMES: (), PATH_COEFFICIENTS: (4, 3), JOINT_POINTS: (),
    SLOT_RIGID: (), SLOT_INVERSE_MASS: (), SLOT_PATH: (), ROW_BODIES: (2,),
    ROW_UNILATERAL: (), JOINT_SCALE: (), KIND_ROWS: (), SEGMENT_ENDS: (5,),
    SEGMENT_OFFSETS: (2, 3), SEGMENT_ROWS: (2,), POINT_BODIES: (2,), POINT_OFFSETS: (2, 3),
    AXIS_BODIES: (2,), AXIS_AXIS: (3,), AXIS_ACROSS: (2, 3), LOCK_BODIES: (2,),
    LOCK_RELATIVE: (3, 3), SLIDE_BODIES: (2,), SLIDE_OFFSETS: (2, 3), SLIDE_DIRECTION: (3,),
    SLIDE_BOUNDS: (2,), ANGLE_BODIES: (2,), ANGLE_AXIS: (3,), ANGLE_REFERENCES: (2, 3),
    ANGLE_BOUNDS: (2,), MOTOR_BODIES: (2,), MOTOR_KIND: (2,), MOTOR_AXIS: (3,),
    MOTOR_REFERENCES: (2, 3), MOTOR_OFFSETS: (2, 3), MOTOR_GAINS: (4,), ORDER: (),
    COLUMN_START: (), COLUMN_ROWS: (), PAIRS: (5,), UPDATE_START: (), UPDATES: (3,), PAIR_TERMS: (2,),
    PAIR_START: (), PAIR_POINTS: (), PAIR_SOURCE: (), BUOYANCY_TERMS: (7,), BUOYANCY_SPHERES: (3,),
    BUOYANCY_SHAPES: (4,), BUOYANCY_BODIES: (2,), BUOYANCY_VOLUMES: (), DRAG_TERMS: (4,), DRAG_POINTS: (3,),
    DRAG_SHAPES: (4,), LOAD_POINTS: (3,), LOAD_VALUES: (7,),
}

#: The integer fields (the others are float64).
INTEGER_FIELDS = frozenset({
    SPRING_ENDS, ANCHOR_PATH, PATH_KEYS, JOINT_POINTS, SLOT_RIGID, SLOT_PATH,
    ROW_BODIES, ROW_UNILATERAL, KIND_ROWS, SEGMENT_ENDS, POINT_BODIES, AXIS_BODIES,
    LOCK_BODIES, SLIDE_BODIES, ANGLE_BODIES, MOTOR_BODIES, MOTOR_KIND, ORDER,
    COLUMN_START, COLUMN_ROWS, PAIRS, UPDATE_START, UPDATES, PAIR_START, PAIR_POINTS, BUOYANCY_SPHERES,
    BUOYANCY_BODIES, DRAG_POINTS, LOAD_POINTS,
})

#: The six row kinds in KIND_ROWS' order.
SEGMENT, POINT, AXIS, LOCK, SLIDE, ANGLE = range(6)


@dataclass(frozen=True, eq=False)
class PackedTables:
    """The fields packed: ``floats`` (float64), ``integers`` (int64) and ``layout`` (FIELD_COUNT, 2): each field's
    offset into its array and its number of rows."""

    floats: np.ndarray
    integers: np.ndarray
    layout: np.ndarray

    def __getitem__(self, field: int) -> np.ndarray:
        """A field as an array of its shape (a view)."""
        offset, rows = self.layout[field]
        source = self.integers if field in INTEGER_FIELDS else self.floats
        size = rows * int(np.prod(TRAILING[field], dtype=np.int64))
        return source[offset: offset + size].reshape(rows, *TRAILING[field])

    def rows(self, field: int) -> int:
        return int(self.layout[field, 1])


def pack(fields: dict[int, np.ndarray]) -> PackedTables:
    """Lay ``fields`` out (by number, each of its shape; missing ones have zero rows)."""
    floats: list[np.ndarray] = []
    integers: list[np.ndarray] = []
    layout = np.zeros((FIELD_COUNT, 2), np.int64)
    sizes = {False: 0, True: 0}
    for field in range(FIELD_COUNT):
        trailing = TRAILING[field]
        integer = field in INTEGER_FIELDS
        value = np.asarray(fields.get(field, np.zeros((0, *trailing))), np.int64 if integer else np.float64)
        if value.shape[1:] != trailing:
            raise ValueError(f"table field {field} has shape {value.shape}, not (rows, {trailing})")
        layout[field] = sizes[integer], len(value)
        (integers if integer else floats).append(value.ravel())
        sizes[integer] += value.size
    return PackedTables(np.concatenate(floats), np.concatenate(integers), layout)
