"""The equations of motion of a Model, in the forms the integrators need.

State (see :mod:`animbatch.sim.model.layout`): configuration ``c = [x_particles, x_rigid, q, τ]`` and motion
``m = [v_particles, P, L]`` (τ: the proper times of the clocks bodies carry, ``dτ/dt = √(1 − v²/c²)``, only when
the scene has clocks). The lecture notes' rigid-body equations::

    dx/dt = v = P / M        dq/dt = ½ (0, ω) ⊗ q,  ω = I(t)⁻¹ L,  I(t)⁻¹ = R I_body⁻¹ Rᵀ
    dP/dt = F                dL/dt = τ

and for particles ``dx/dt = v``, ``dv/dt = F / m``. F and τ sum the model's force terms (only those the scene
declares). The quaternion's norm is conserved by these equations; integrators re-normalise it (:meth:`project`)
after each fixed step and on every output, so rounding never accumulates.

Forms offered: :meth:`Dynamics.rhs` (all of ``dy/dt``, for adaptive and Runge–Kutta methods), and for partitioned
(symplectic) methods :meth:`motion_rate` (``dm/dt``: the "kick") and :meth:`drift` (advance c with the motion held
fixed). A scene of particles only takes exactly the particle path: no rigid-body work is done.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from animbatch import quaternion
from animbatch.sim.forces import Kinematics
from animbatch.sim.forces.jacobian import ForceJacobian
from animbatch.sim.joints import STABILISATION_RATE
from animbatch.sim.joints.tree import JointTree, joint_tree
from animbatch.sim.joints.tree import advance as advance_tree
from animbatch.sim.model.model import Model, nearest_rotation, world_inverse_inertia_times

#: The fixed-step forms that step a tree of hinges and sliders in its joint coordinates (semi-implicit Euler keeps
#: maximal coordinates: see :mod:`animbatch.sim.joints.tree`).
TREE_FORMS = ("runge_kutta", "verlet")


def tree_of(model: Model) -> JointTree | str:
    """The model's joints as a joint tree (:mod:`animbatch.sim.joints.tree`), or why they are not one."""
    rigid = model.rigid
    if model.joints is None or rigid is None:
        return "it has no joints between rigid bodies"
    if model.contact_world is not None:
        return "it has contacts"
    if model.clocks is not None or model.kinematic is not None:
        return "it has clocks or bodies on keyframes"
    return joint_tree(model.joints, rigid.mass, rigid.inertia, rigid.inverse_inertia, model.rigid_count,
                      model.particle_count)


def _turning(omega: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """``[ω]× R`` for each body (B, 3, 3): ω (B, 3) crossed with each column of R, the rate of a rotation matrix."""
    return np.cross(omega[:, None, :], np.transpose(rotation, (0, 2, 1))).transpose(0, 2, 1)


class Dynamics:
    """Right-hand side for a Model. Holds its force/torque buffers, reused by every evaluation."""

    def __init__(self, model: Model) -> None:
        self.model = model
        self.terms = model.force_terms
        self.size = model.layout.size
        self.particles = model.particle_count
        self.rigid = model.rigid_count
        n, b = self.particles, self.rigid
        self.clocks = model.clocks
        self.joints = model.joints
        #: Which joint limits and ropes act, when events decide it (animbatch.sim.joints.stops); None: the state does
        self.engaged_stops: np.ndarray | None = None
        #: Baumgarte's ω [1/s] for the joints; fixed-step methods set 0, as they project after every step instead
        self.joint_stabilisation = STABILISATION_RATE
        #: Whether the run is long enough to repay loading compiled kernels (:func:`~animbatch.sim.model.compiled.
        #: dynamics_for` decides): contacts then solve their impulse sweeps compiled however few they are
        self.long_run = False
        #: orientations as rotation matrices (solver.orientation: matrix), not quaternions
        self.matrices = model.layout.matrix_orientation
        self._steps_since_renormalised = 0
        self._last_projected = float(model.frame_times[0]) if len(model.frame_times) else 0.0
        self._clock_start = 3 * n + (12 if self.matrices else 7) * b  # the clocks' proper times close the configuration
        self._config_size = self._clock_start + (self.clocks.count if self.clocks is not None else 0)
        self._inverse_mass = (1.0 / model.bodies.mass[:n])[:, None]
        self._force = np.zeros((n + b, 3))
        self._torque = np.zeros((b, 3)) if b else None
        self._patterns: dict[bool, dict] = {}  # sparsity patterns of the force Jacobians, reused between steps
        #: The joints as a tree of hinges and sliders, stepped in its joint coordinates by Runge–Kutta and Verlet
        #: (:meth:`advance`), or why they are not one.
        self.tree: JointTree | str = tree_of(model)
        if b:
            rigid = model.rigid
            assert rigid is not None
            self._rigid_inverse_mass = (1.0 / rigid.mass)[:, None]
            self._inverse_inertia = rigid.inverse_inertia
            self._x = np.empty((n + b, 3))
            self._v = np.empty((n + b, 3))

    # ------------------------------------------------------------------------------------------ state views

    def split(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Views ``(configuration, motion)`` of a flat state."""
        return y[: self._config_size], y[self._config_size:]

    def _rigid_views(self, config: np.ndarray, motion: np.ndarray) -> tuple[np.ndarray, ...]:
        n, b = self.particles, self.rigid
        width = 9 if self.matrices else 4  # rotation matrices, row by row, or quaternions
        orientation = config[3 * n + 3 * b: 3 * n + (3 + width) * b]
        return (config[3 * n: 3 * n + 3 * b].reshape(b, 3),
                orientation.reshape(b, 3, 3) if self.matrices else orientation.reshape(b, 4),
                motion[3 * n: 3 * n + 3 * b].reshape(b, 3), motion[3 * n + 3 * b:].reshape(b, 3))

    def kinematics(self, config: np.ndarray, motion: np.ndarray, *, t: float = 0.0, copy: bool = False) -> Kinematics:
        """Positions, velocities, rotations and angular velocities of all bodies at time ``t`` [s].

        The position and velocity arrays are views of the state or buffers reused by the next call, which is what
        the right-hand side wants; with ``copy`` they are the caller's own (to keep several states at once).
        """
        n = self.particles
        x = config[: 3 * n].reshape(n, 3)
        v = motion[: 3 * n].reshape(n, 3)
        if not self.rigid:
            return Kinematics(x.copy(), v.copy(), None, None, n, t) if copy else Kinematics(x, v, None, None, n, t)
        position, orientation, momentum, angular_momentum = self._rigid_views(config, motion)
        # I(t)⁻¹ = R I_body⁻¹ Rᵀ with R as integrated: with matrices, as the notes do, drift and all
        rotation = orientation.copy() if self.matrices else quaternion.to_matrix(orientation)
        omega = world_inverse_inertia_times(rotation, self._inverse_inertia, angular_momentum)
        self._x[:n], self._x[n:] = x, position
        self._v[:n] = v
        np.multiply(momentum, self._rigid_inverse_mass, out=self._v[n:])
        if copy:
            return Kinematics(self._x.copy(), self._v.copy(), rotation, omega, n, t)
        return Kinematics(self._x, self._v, rotation, omega, n, t)

    def loads(self, t: float, state: Kinematics) -> tuple[np.ndarray, np.ndarray | None]:
        """Total force [N] (P, 3) on every body and torque [N·m] (B, 3) on every rigid body (buffers, overwritten by
        the next call)."""
        force, torque = self._force, self._torque
        force.fill(0.0)
        if torque is not None:
            torque.fill(0.0)
        for term in self.terms:
            term.accumulate(t, state, force, torque)
        return force, torque

    def loads_by_term(self, t: float, y: np.ndarray) -> dict[str, np.ndarray]:
        """The force [N] (P, 3) of each kind of term on every body at state ``y``, summed by label (two gravity
        fields give one 'gravity'); new arrays, for drawing and inspection rather than stepping."""
        config, motion = self.split(y)
        state = self.kinematics(config, motion, t=t)
        by_label: dict[str, np.ndarray] = {}
        torque = np.zeros((self.rigid, 3)) if self.rigid else None
        for term in self.terms:
            force = by_label.setdefault(term.label, np.zeros_like(self._force))
            term.accumulate(t, state, force, torque)
        if self.joints is not None:  # the joints' forces answer the sum of the others
            total = np.sum(list(by_label.values()), axis=0) if by_label else np.zeros_like(self._force)
            held = np.zeros_like(self._force)
            held[self.joints.points] = self.joints.loads(state, total, torque).force
            by_label["joint"] = held
        return by_label

    def joint_reactions(self, times: np.ndarray, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What each joint's constraint does to its first body at each of the states (F, n) at ``times`` (F,) [s]:
        force [N] and torque [N·m] about the joint's point on it (F, K, 3); and the motors' efforts (F, M)
        [N·m or N], which act besides. Requires joints."""
        joints = self.joints
        assert joints is not None
        frames = len(times)
        force, torque = np.zeros((frames, joints.count, 3)), np.zeros((frames, joints.count, 3))
        efforts = np.zeros((frames, len(joints.motors.joint) if joints.motors is not None else 0))
        for frame, (t, y) in enumerate(zip(times, states)):
            config, motion = self.split(y)
            state = self.kinematics(config, motion, t=float(t))
            loads = joints.loads(state, *self.loads(float(t), state))
            force[frame], torque[frame] = joints.reactions(loads, joints.motion(state))
            efforts[frame] = loads.efforts
        return force, torque, efforts

    # ------------------------------------------------------------------------------------------ the forms

    def motion_rate(self, t: float, config: np.ndarray, motion: np.ndarray,
                    out: np.ndarray | None = None) -> np.ndarray:
        """``dm/dt = [F_particles / m, F_rigid, τ]``, flat, written to ``out`` when given."""
        return self._motion_rate(t, self.kinematics(config, motion, t=t),
                                 np.empty(len(motion)) if out is None else out)

    def _motion_rate(self, t: float, state: Kinematics, out: np.ndarray) -> np.ndarray:
        force, torque = self.loads(t, state)
        n = self.particles
        if self.joints is not None:  # the constraint forces, from the other forces (see animbatch.sim.joints)
            self.joints.add_loads(state, force, torque, self.engaged_stops, self.joint_stabilisation)
        np.multiply(force[:n], self._inverse_mass, out=out[: 3 * n].reshape(n, 3))
        if self.rigid:
            assert torque is not None  # loads gives torques whenever there are rigid bodies
            out[3 * n: 3 * n + 3 * self.rigid] = force[n:].ravel()
            out[3 * n + 3 * self.rigid:] = torque.ravel()
        return out

    def _config_rate(self, config: np.ndarray, motion: np.ndarray, state: Kinematics, out: np.ndarray) -> None:
        """``dc/dt = [v, P / M, ½ (0, ω) ⊗ q]``, flat, into ``out``."""
        n = self.particles
        out[: 3 * n] = motion[: 3 * n]
        if self.rigid:
            b = self.rigid
            assert state.omega is not None
            out[3 * n: 3 * n + 3 * b] = state.v[n:].ravel()
            if self.matrices:  # dR/dt = [ω]× R
                assert state.rotation is not None
                out[3 * n + 3 * b: 3 * n + 12 * b] = _turning(state.omega, state.rotation).ravel()
            else:
                orientation = config[3 * n + 3 * b: 3 * n + 7 * b].reshape(b, 4)
                out[3 * n + 3 * b: 3 * n + 7 * b] = quaternion.rate(orientation, state.omega).ravel()
        if self.clocks is not None:
            out[self._clock_start:] = self.clocks.rate(state.v[self.clocks.index], state.t)

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """``dy/dt`` as a new array (solve_ivp keeps references to the arrays it receives)."""
        config, motion = self.split(y)
        state = self.kinematics(config, motion, t=t)  # rotations and ω once, for both halves
        dydt = np.empty_like(y)
        self._config_rate(config, motion, state, dydt[: self._config_size])
        self._motion_rate(t, state, dydt[self._config_size:])
        return dydt

    def drift(self, config: np.ndarray, motion: np.ndarray, h: float) -> None:
        """Advance the configuration by ``h`` [s] with the motion held fixed, in place.

        Positions move by ``h v``. Orientations turn by the exact rotation ``exp(h ω)``, with ω evaluated at the
        half-turned orientation (a midpoint rule, second-order accurate, and norm-preserving).
        """
        n = self.particles
        if self.clocks is not None:  # at the motion held fixed, like the positions
            config[self._clock_start:] += h * self.clocks.rate(self.kinematics(config, motion).v[self.clocks.index])
        config[: 3 * n] += h * motion[: 3 * n]
        if self.rigid:
            position, orientation, momentum, angular_momentum = self._rigid_views(config, motion)
            position += h * momentum * self._rigid_inverse_mass
            if self.matrices:  # the notes' step R ← R + h [ω]× R: no longer a rotation, by (h ω)² a step
                omega = world_inverse_inertia_times(orientation, self._inverse_inertia, angular_momentum)
                orientation += h * _turning(omega, orientation)
                return
            omega = world_inverse_inertia_times(quaternion.to_matrix(orientation), self._inverse_inertia,
                                                angular_momentum)
            halfway = quaternion.multiply(quaternion.from_rotation_vector(0.5 * h * omega), orientation)
            omega = world_inverse_inertia_times(quaternion.to_matrix(halfway), self._inverse_inertia,
                                                angular_momentum)
            orientation[...] = quaternion.multiply(quaternion.from_rotation_vector(h * omega), orientation)

    def _renormalise_matrices(self, y: np.ndarray, t: float) -> None:
        """A fixed step's matrices back to rotations (their polar factors) at every ``model.renormalise_every``-th
        step; never with 0, and never on outputs (F, n), which must show the drift. A step is a projection at a
        later time than the last one (the projection of the start, at its own time, is none)."""
        every = self.model.renormalise_every
        if y.ndim != 1 or not every or t <= self._last_projected:
            return
        self._last_projected = t
        self._steps_since_renormalised += 1
        if self._steps_since_renormalised < every:
            return
        self._steps_since_renormalised = 0
        block = self.model.layout.block("rigid_orientation")
        held = y[block.span].reshape(self.rigid, 3, 3)
        held[...] = nearest_rotation(held)

    def advances(self, form: tuple[str, object] | None) -> bool:
        """Whether :meth:`advance` takes the steps of a scheme's form (``Scheme.compiled_form``): here, those of a
        joint tree in its joint coordinates."""
        return form is not None and form[0] in TREE_FORMS and isinstance(self.tree, JointTree)

    def advance(self, form: tuple[str, object], y: np.ndarray, t: float, h: float, steps: int) -> int:
        """``steps`` fixed steps of ``h`` [s] from ``t`` [s] of a joint tree in its joint coordinates, in place (the
        numpy reference, :func:`animbatch.sim.joints.tree.advance`; the compiled form steps every form); returns the
        right-hand sides evaluated. Only where :meth:`advances` says so."""
        assert isinstance(self.tree, JointTree)

        def forces(now: float, x: np.ndarray, v: np.ndarray, rotation: np.ndarray,
                   omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            force, torque = self.loads(now, Kinematics(x, v, rotation, omega, 0, now))
            assert torque is not None
            return force.copy(), torque.copy()

        return advance_tree(self.tree, form, y, t, h, steps, forces)

    def energy(self, t: float, config: np.ndarray, motion: np.ndarray) -> tuple[float, float]:
        """Total mechanical energy [J] (kinetic, plus the potentials of the terms that have one) at time ``t``, and
        its scale (the sum of the magnitudes of its parts), against which rounding is judged."""
        state = self.kinematics(config, motion, t=t)
        n = self.particles
        parts = [0.5 * float(np.sum(self.model.bodies.mass[:n, None] * state.v[:n] ** 2))]
        if self.rigid:
            _, _, momentum, angular_momentum = self._rigid_views(config, motion)
            parts.append(0.5 * float(np.sum(momentum * state.v[n:]) + np.sum(state.omega * angular_momentum)))
        parts += [term.potential_energy(state) for term in self.terms if term.has_potential]
        return float(sum(parts)), float(sum(abs(p) for p in parts))

    @property
    def adds_energy(self) -> bool:
        """Whether any term or joint motor can put energy in (see :attr:`Model.adds_energy`)."""
        return self.model.adds_energy

    # ------------------------------------------------------------------------------------------ derivatives

    def force_jacobian(self, t: float, config: np.ndarray, motion: np.ndarray, *, definite: bool = False,
                       compiled: bool = False) -> tuple[ForceJacobian, list[str]]:
        """``∂f/∂x`` and ``∂f/∂v`` of the forces on the particles (exact, or ``definite``: see
        :class:`ForceJacobian`; ``compiled``: its blocks and matrices by the compiled kernels, where numba is known to
        load), and the labels of the terms that give none (they are explicit in implicit steps)."""
        state = self.kinematics(config, motion, t=t)
        jacobian = ForceJacobian(self.particles, definite=definite,
                                 patterns=self._patterns.setdefault(definite, {}), compiled=compiled)
        explicit = [term.label for term in self.terms if not term.jacobian(t, state, jacobian)]
        return jacobian, explicit

    @property
    def has_jacobian(self) -> bool:
        """Whether :meth:`jacobian` can give ``∂(dy/dt)/∂y``: for models of particles only (without clocks or
        joints)."""
        return self.rigid == 0 and self.clocks is None and self.joints is None

    def jacobian(self, t: float, y: np.ndarray) -> sp.csr_matrix:
        """``∂(dy/dt)/∂y`` for a model of particles (for Radau, BDF and LSODA)::

            [[0,          I        ],
             [M⁻¹ ∂f/∂x,  M⁻¹ ∂f/∂v]]

        sparse, (6N, 6N). Terms without derivatives (aerodynamics, buoyancy, gravitation) are left out; Newton's
        method in the solver still converges, only a little slower, as long as they are not stiff.
        """
        config, motion = self.split(y)
        derivatives, _ = self.force_jacobian(t, config, motion)
        inverse_mass = sp.diags(np.repeat(self._inverse_mass[:, 0], 3))
        size = 3 * self.particles
        return sp.bmat([[None, sp.identity(size, format="csr")],
                        [inverse_mass @ derivatives.matrix("x"), inverse_mass @ derivatives.matrix("v")]],
                       format="csr")

    def project_velocities(self, state: Kinematics, v: np.ndarray, omega: np.ndarray | None) -> None:
        """Take out of velocities ``v`` (P, 3) [m/s] and ``omega`` (B, 3) [rad/s] (in place) what breaks the joints
        at ``state``'s positions (:meth:`animbatch.sim.joints.Joints.project_velocities`). Requires joints."""
        assert self.joints is not None
        self.joints.project_velocities(state, v, omega)

    def velocity_rows(self, state: Kinematics, size: int, *, dense: bool = False) -> sp.csr_matrix | np.ndarray:
        """The joint rows that hold at ``state``, as a Jacobian over a flat velocity of ``size`` bodies
        (:meth:`animbatch.sim.joints.Joints.velocity_rows`; ``dense``: as an array). Requires joints."""
        assert self.joints is not None
        return self.joints.velocity_rows(state, size, dense=dense)

    def project(self, y: np.ndarray, *, joints: bool = True, reach: float = 0.0, t: float = 0.0,
                start: np.ndarray | None = None, step: float = 0.0) -> None:
        """Re-normalise the quaternions of a state (…, n) in place, and with ``joints`` put the bodies on keyframes
        where their paths say and move a state (n,) back onto its joints: the start of every run, fixed-step
        methods after every step, adaptive ones only where a limit or rope reaches its stop (within ``reach`` [m or
        rad]); between those, adaptive methods keep to the joints by Baumgarte stabilisation, so that their outputs
        show their true drift. ``t`` [s]: the state's time (where anchors and bodies on keyframes are). ``start``:
        the configuration (the state's first part) at the start of a one-kick step of ``step`` [s] that led here,
        for a SHAKE projection (:meth:`animbatch.sim.joints.Joints.project`)."""
        if joints and self.model.kinematic is not None and y.ndim == 1:
            self.model.prescribe(y, t)  # a step integrated them as free bodies: their paths overrule it
        if joints and self.joints is not None and y.ndim == 1:
            config, motion = self.split(y)
            points = self.particles + self.rigid  # positions, and velocities then momenta, are contiguous
            rigid = (config[3 * points: 3 * points + 4 * self.rigid].reshape(-1, 4),
                     motion[3 * points:].reshape(-1, 3)) if self.rigid else (None, None)
            begun = None
            if start is not None:
                begun = (start[: 3 * points].reshape(points, 3),
                         start[3 * points: 3 * points + 4 * self.rigid].reshape(-1, 4) if self.rigid else None)
            self.joints.project(config[: 3 * points].reshape(points, 3), rigid[0],
                                motion[: 3 * points].reshape(points, 3), rigid[1], reach=reach, t=t, start=begun,
                                step=step)
        if self.rigid and self.matrices:
            self._renormalise_matrices(y, t)
        elif self.rigid:
            block = self.model.layout.block("rigid_orientation")
            q = y[..., block.span].reshape(*y.shape[:-1], self.rigid, 4)
            q /= np.linalg.norm(q, axis=-1, keepdims=True)
