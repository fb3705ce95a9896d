"""The whole scene: :class:`SceneSpec`, with the checks that span its sections."""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import Field, model_validator

from animbatch.scene.schema.assignment import AssignmentSpec
from animbatch.scene.schema.bodies import AnchorSpec
from animbatch.scene.schema.contacts import ColliderSpec, ContactSpec, MaterialPairSpec, MaterialSpec
from animbatch.scene.schema.controllers import ControllerSpec
from animbatch.scene.schema.deformable import BodySpec, SpringSpec
from animbatch.scene.schema.emitters import EmitterSpec
from animbatch.scene.schema.fields import FieldSpec
from animbatch.scene.schema.joints import JointSpec
from animbatch.scene.schema.keys import Name, SceneModel, key, rule_error
from animbatch.scene.schema.render import RenderSpec
from animbatch.scene.schema.solver import FixedStepMethod, Method, SolverSpec
from animbatch.scene.schema.stopwatches import ClocksSpec, StopwatchSpec
from animbatch.timeline import frame_count


class StudyReferenceSpec(SceneModel):
    """A fixed-step reference for ``animbatch study``, where a tight adaptive run would crawl (a pile, a stack)."""
    method: FixedStepMethod = key("symplectic_euler", "Fixed-step method of the reference run.")
    dt: float = key(description="Step of the reference run; it is checked against the same method at twice this "
                                "step, and that difference is the reference's accuracy.", unit="s", gt=0,
                    example=1.0e-4)


class StudySpec(SceneModel):
    """Settings of ``animbatch study``: the work-precision study of this scene (no effect on a render)."""
    closed_form: bool = key(False, "Measure errors against closed-form solutions instead of a tight reference run. "
                                   "Every body must have one: a projectile (uniform gravity only), a fall with "
                                   "linear drag (and gravity, optionally wind), a mass on one spring to a fixed "
                                   "anchor moving along the spring (gravity allowed along it), or one of a pair "
                                   "attracting each other by gravitation alone (Kepler orbit).")
    reference: StudyReferenceSpec | None = key(
        None, "A fixed-step reference run instead of tight DOP853 (for piles and resting stacks, where adaptive "
              "methods crawl through contact events).", example={"method": "symplectic_euler", "dt": 1.0e-4})
    methods: list[Method] | None = key(None, "Integrators to study (default: every one that applies to the scene).",
                                       example=["RK45", "DOP853", "verlet"])
    rtols: list[Annotated[float, Field(gt=0, lt=1)]] = key(
        [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10],
        "Relative tolerances swept for adaptive methods; atol is rtol times each component's scale (the scene's "
        "length for positions, its speed for velocities).", "1", min_length=1)
    dt_levels: int = key(6, "Steps swept for fixed-step methods: dt = frame interval / 2^k for k = 0 … dt_levels-1.",
                         "1", ge=1, le=16)
    repeats: int = key(3, "Timed repeats per run after an untimed one that measures the errors; the minimum wall "
                          "time is reported.", "1", ge=1, le=20)
    timeout: float = key(60.0, "Wall-time limit per run; a run that exceeds it is reported as a timeout.", "s", gt=0)

    @model_validator(mode="after")
    def _one_reference(self) -> "StudySpec":
        if self.closed_form and self.reference is not None:
            raise rule_error("a study has one reference: closed_form (exact motion) or reference (a fixed-step "
                             "run), not both", "reference")
        return self


class SceneSpec(SceneModel):
    """A whole scene: what exists, what acts on it, how to integrate it and how to draw it."""
    name: Name | None = key(None, "Scene name; output goes to renders/<name>/ (default: the file name).")
    description: str = key("", "Free text, shown by 'animbatch info'.")
    duration: float = key(5.0, "Length of the animation; frames are at t = k/fps for k = 0 … ceil(duration·fps)-1.",
                          "s", gt=0, le=86400)
    fps: int = key(30, "Frames per second of the animation (and of the trajectory samples).", "Hz", ge=1, le=240)
    solver: SolverSpec = key(SolverSpec(), "Integrator settings.")
    bodies: list[BodySpec] = key([], "Simulated bodies: particles (the default type) and rigid bodies.")
    anchors: list[AnchorSpec] = key([], "Fixed points for springs.")
    springs: list[SpringSpec] = key([], "Springs and dampers.")
    joints: list[JointSpec] = key([], "Joints between bodies and to the world: rods, ropes, pulleys, ball "
                                      "joints, hinges, sliders and welds (see Joints).")
    controllers: list[ControllerSpec] = key([], "PD controllers (virtual springs) pulling bodies towards targets.")
    emitters: list[EmitterSpec] = key([], "Particle emitters (particle systems).")
    seed: int = key(0, "Seed of every random draw (the attributes of emitted particles): the same seed gives the "
                       "same particles, bit for bit.", "1", ge=0, lt=2**63)
    fields: list[FieldSpec] = key([], "Force fields; only the declared ones are compiled.")
    materials: dict[Name, MaterialSpec] = key({}, "Materials of your own, by name (added to the built-in ones).")
    material_pairs: list[MaterialPairSpec] = key([], "Coefficients for particular pairs of materials.")
    colliders: list[ColliderSpec] = key([], "Fixed obstacles: planes, boxes, spheres, meshes.")
    contacts: ContactSpec | None = key(None, "Contact settings; collisions are on when this or colliders exist.")
    assignment: AssignmentSpec | None = key(None, "For teaching: the task and the checks 'animbatch grade' scores "
                                                  "(see docs/teaching.md).")
    clocks: ClocksSpec | None = key(None, "Proper-time clocks that bodies carry (time dilation); omit for none.")
    stopwatches: list[StopwatchSpec] = key([], "Stopwatches that time events of the run (a fall, a period), shown "
                                               "on the frame and reported.")
    render: RenderSpec = key(RenderSpec(), "Rendering and output settings.")
    study: StudySpec = key(StudySpec(), "Settings of 'animbatch study' (error against work per integrator).")
    sweep: dict[str, list[Any]] = key(
        {}, "Values to sweep with 'animbatch batch' (key path -> list of values): one variant per combination, as "
        "with --sweep; ignored by the other commands.", example={"springs[0].stiffness": [100, 1000, 10000]})

    @property
    def has_contacts(self) -> bool:
        """Whether collisions are simulated at all: only when the scene asks for them (colliders or a ``contacts``
        section) and some body takes part (colliders that nothing touches are scenery, and cost no contact pass)."""
        return (bool(self.colliders) or self.contacts is not None) and any(body.collide for body in self.bodies)

    @property
    def frame_count(self) -> int:
        """Number of frames (:func:`animbatch.timeline.frame_count`)."""
        return frame_count(self.duration, self.fps)


#: Top-level keys that do not change the physics (excluded from the physics hash).
PRESENTATION_KEYS = frozenset({"name", "description", "render", "solver", "study", "sweep", "stopwatches",
                               "assignment"})
