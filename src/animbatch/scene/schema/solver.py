"""The ``solver`` section: the integration method and its settings."""

from __future__ import annotations

from typing import Annotated, Any, Literal, get_args

from pydantic import BeforeValidator, Field, model_validator

from animbatch.scene.schema.keys import SceneModel, key, rule_error

AdaptiveMethodName = Literal["RK23", "RK45", "DOP853", "Radau", "BDF", "LSODA"]
FixedStepMethodName = Literal["euler", "midpoint", "symplectic_euler", "verlet", "backward_euler"]
KinematicMethodName = Literal["analytic"]
ADAPTIVE_METHODS: tuple[str, ...] = get_args(AdaptiveMethodName)
FIXED_STEP_METHODS: tuple[str, ...] = get_args(FixedStepMethodName)
#: The fixed-step methods that apply contact impulses between their kick and their drift (the schemes whose
#: ``takes_constraints`` is true; a test checks the two agree), so that validate need not load the schemes.
CONTACT_METHODS = ("symplectic_euler", "verlet", "backward_euler")
#: Methods that do not integrate: the bodies move by closed forms (the lecture notes' kinematic simulation).
KINEMATIC_METHODS: tuple[str, ...] = get_args(KinematicMethodName)
METHOD_ALIASES = {
    "explicit_euler": "euler",
    "forward_euler": "euler",
    "rk2": "midpoint",
    "semi_implicit_euler": "symplectic_euler",
    "velocity_verlet": "verlet",
    "implicit_euler": "backward_euler",
}


def _canonical_method(value: Any) -> Any:
    """Method names are case-insensitive, and ``-`` may stand for ``_``; aliases map to canonical names."""
    if not isinstance(value, str):
        return value
    folded = value.strip().lower().replace("-", "_")
    for name in (*ADAPTIVE_METHODS, *FIXED_STEP_METHODS, *KINEMATIC_METHODS):
        if name.lower() == folded:
            return name
    return METHOD_ALIASES.get(folded, value)


Method = Annotated[Literal[AdaptiveMethodName, FixedStepMethodName, KinematicMethodName],
                   BeforeValidator(_canonical_method)]
FixedStepMethod = Annotated[FixedStepMethodName, BeforeValidator(_canonical_method)]


class SolverSpec(SceneModel):
    """How the equations of motion are integrated."""

    method: Method = key("RK45", "Integrator: an adaptive solve_ivp method (RK23, RK45, DOP853, Radau, BDF, LSODA) "
                                 "or a fixed-step one (euler, midpoint, symplectic_euler, verlet, backward_euler), or "
                                 "analytic (closed forms, no integration; see Kinematic mode).",
                         example="DOP853")
    rtol: float = key(1e-6, "Relative tolerance of adaptive methods (ignored by fixed-step ones).", "1",
                      gt=0, lt=1)
    atol: float = key(1e-9, "Absolute tolerance of adaptive methods, in the units of each state component "
                            "(m for positions, m/s for velocities).", "m, m/s", gt=0)
    max_step: float | None = key(None, "Largest step an adaptive method may take (default: no limit).", "s", gt=0)
    dt: float | None = key(None, "Step of fixed-step methods (default: one step per frame for backward_euler, which "
                                 "is stable at any step; 1e-3 s for the others). The step used is the largest one "
                                 "<= dt that divides the frame interval 1/fps, so that frames fall on steps (to 1e-6: "
                                 "dt 0.008333333 counts as 1/120 s).",
                           "s", gt=0)
    max_cost: float = key(3600.0, "Wall-time budget of one simulation. Before it starts, a run estimated to take "
                                  "longer is refused, naming what makes it expensive; a run that reaches it anyway "
                                  "stops with exit code 3, saying how far it got. 0 = no limit. The command line's "
                                  "--max-cost takes seconds or 30min, 2h.", "s", ge=0)
    drift_warning: float = key(0.01, "Relative drift of a conserved quantity (energy, momentum, angular momentum) "
                                     "above which a run warns, naming the quantity and what to change; 0.01 is 1 % "
                                     "of the quantity's scale in the scene (see the accuracy ledger).", "1", gt=0)
    orientation: Literal["quaternion", "matrix"] = key(
        "quaternion", "How rigid bodies' orientations are integrated: quaternion (unit by construction, so R stays a "
                      "rotation), or matrix (the notes' R itself, dR/dt = [ω]× R, which drifts away from a rotation; "
                      "the ledger reports the largest ‖RᵀR − I‖). matrix: for rigid bodies without joints, contacts "
                      "or keyframes.")
    renormalise: Literal["every step", "never"] | Annotated[int, Field(ge=1)] | None = key(
        None, "With orientation: matrix, how often a fixed-step method turns each R back into the nearest "
              "rotation: every step, never, or every N steps (default: every step; adaptive methods never can, "
              "as solve_ivp integrates on between frames).", example="never")

    @model_validator(mode="after")
    def _renormalise_with_matrices(self) -> "SolverSpec":
        if self.renormalise is not None and self.orientation != "matrix":
            raise rule_error("renormalise is for solver.orientation: matrix (quaternions are unit by construction)",
                             "renormalise")
        if self.renormalise not in (None, "never") and self.method in ADAPTIVE_METHODS:
            raise rule_error(f"{self.method} integrates on between frames, so it cannot renormalise: use never, or a "
                             "fixed-step method (verlet, symplectic_euler, …)", "renormalise")
        return self

    @property
    def renormalise_every(self) -> int:
        """Fixed steps between renormalisations of rotation matrices; 0: never."""
        if self.renormalise is None:
            return 0 if self.method in ADAPTIVE_METHODS else 1
        if self.renormalise == "every step":
            return 1
        if self.renormalise == "never":
            return 0
        return self.renormalise

    @property
    def is_adaptive(self) -> bool:
        return self.method in ADAPTIVE_METHODS
