"""Assignments: what a student must change in a scene, and the checks ``animbatch grade`` scores it by."""

from __future__ import annotations

from typing import Literal

from pydantic import field_validator, model_validator

from animbatch.curves import ExpressionError, compile_expression
from animbatch.scene.overrides import parse_key_path
from animbatch.scene.schema.keys import Name, SceneModel, key, rule_error
from animbatch.scene.schema.solver import Method

Quantity = Literal["position", "velocity", "speed", "stopwatch", "energy_drift", "momentum_drift",
                   "angular_momentum_drift", "method", "field"]
#: The quantities compared with a value at times (the others are judged once per run).
SAMPLED = ("position", "velocity", "speed")


class CheckSpec(SceneModel):
    """One graded check. ``position``, ``velocity`` and ``speed`` of a ``body`` are compared at the times ``at``
    with ``expected`` (default: the reference run's); ``stopwatch`` compares a stopwatch's interval;
    ``energy_drift`` (``momentum_drift``, ``angular_momentum_drift``) asks that the run's relative drift of that
    conserved quantity stay within ``tolerance``; ``method`` that the
    solver is one of ``methods``; ``field`` that the scene declares a field of type ``field``."""

    name: str = key(description="What the check is called in the grade's table and reports.",
                     example="terminal speed")
    quantity: Quantity = key(description="What is checked.")
    points: float = key(1.0, "Points the check is worth.", "1", ge=0)
    body: Name | None = key(None, "The body (position, velocity, speed; and field: the field must act on it).")
    at: Literal["all", "end"] | list[float] = key(
        "all", "When: every frame of the reference, its last frame, or a list of times.", "s")
    expected: float | list[float] | str | list[str] | None = key(
        None, "The right answer: a number (speed, stopwatch), three numbers (position, velocity), or formulas of t "
              "(one, or three for a vector), e.g. ['3 * t', '2 + 7 * t - 4.905 * t**2', '0']; default: the "
              "reference run's values.")
    tolerance: float = key(1e-3, "Largest accepted difference (in the quantity's unit; a fraction for the "
                                 "drifts).", gt=0)
    stopwatch: Name | None = key(None, "The stopwatch whose interval is checked (quantity stopwatch).")
    methods: list[Method] | None = key(None, "Solver methods accepted (quantity method).")
    field: str | None = key(None, "Field type the scene must declare (quantity field), e.g. drag.")
    hint: str = key("", "Shown when the check fails: what to look at.")

    @field_validator("expected")
    @classmethod
    def _formulas(cls, expected: float | list[float] | str | list[str] | None) -> object:
        formulas = [expected] if isinstance(expected, str) else expected if isinstance(expected, list) else []
        for formula in formulas:
            if isinstance(formula, str):
                try:
                    compile_expression(formula, "t")
                except ExpressionError as error:
                    raise rule_error(str(error)) from None
        return expected

    @model_validator(mode="after")
    def _needs(self) -> CheckSpec:
        needed = {"position": "body", "velocity": "body", "speed": "body", "stopwatch": "stopwatch",
                  "method": "methods", "field": "field"}.get(self.quantity)
        if needed is not None and getattr(self, needed) is None:
            raise rule_error(f"a {self.quantity} check needs '{needed}'", needed)
        return self


class PartialCreditSpec(SceneModel):
    """The fraction of the points given to a submission that cannot be checked."""

    invalid: float = key(0.0, "When the scene does not validate.", "1", ge=0, le=1)
    failed: float = key(0.0, "When it validates but its simulation fails (diverges, reaches c, …).", "1", ge=0, le=1)


class AssignmentSpec(SceneModel):
    """An assignment: the task, what the student changes (marked TODO in the scene), and how it is graded."""

    title: str = key(description="The assignment's name.", example="Terminal velocity")
    task: str = key("", "What the student must do, in a sentence or two.")
    checks: list[CheckSpec] = key([], "What 'animbatch grade' scores.")
    partial_credit: PartialCreditSpec = key(PartialCreditSpec(), "Points for submissions that cannot be checked.")
    edit: list[str] | None = key(
        None, "What the student may change, as key paths in --set's syntax (bodies[bob].position, "
              "springs[*].stiffness, solver): 'animbatch grade' compares the submission with the reference and lists "
              "every other difference, path by path. Not given: differences are listed only.",
        example="[bodies[bob].position]")
    differences: Literal["fail", "list"] = key(
        "fail", "With 'edit': a submission that changes anything else scores 0 on every check ('fail'), or the "
                "differences are only listed ('list').")
    budget: float = key(4.0, "How many times the reference's simulation wall time a submission's may take (and at "
                             "least 2 s): a submission estimated to need more is refused before it runs, one that "
                             "uses it up is stopped, and every check then scores 0. Its own solver.max_cost is "
                             "ignored.", "1", gt=0)

    @field_validator("edit")
    @classmethod
    def _key_paths(cls, edit: list[str] | None) -> list[str] | None:
        for text in edit or []:
            try:
                parse_key_path(text)
            except ValueError as error:
                raise rule_error(f"{error}; write paths as --set does, e.g. bodies[bob].position") from None
        return edit

    @model_validator(mode="after")
    def _unique(self) -> AssignmentSpec:
        names = [check.name for check in self.checks]
        for index, name in enumerate(names):
            if name in names[:index]:
                raise rule_error(f"check name {name!r} is used twice; names must be unique", "checks")
        return self
