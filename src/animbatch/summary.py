"""The one line ``animbatch validate`` prints per scene: what the scene holds and how it will be solved.

Kept apart from :mod:`animbatch.info` (which compiles the model) so that validating a scene loads nothing of the
simulation but the methods' descriptions."""

from __future__ import annotations

from animbatch.scene import LoadedScene
from animbatch.scene.schema import SolverSpec
from animbatch.sim.integrators.description import describe_method

__all__ = ["describe_solver", "one_line_summary", "plural"]


def describe_solver(solver: SolverSpec) -> str:
    """The scene's method and its settings in one line, as the integrator built from them describes itself."""
    return describe_method(solver.method, adaptive=solver.is_adaptive, dt=solver.dt, rtol=solver.rtol,
                           atol=solver.atol, max_step=solver.max_step)


def plural(count: int, word: str, plural: str | None = None) -> str:
    return f"{count} {word if count == 1 else (plural or word + 's')}"


def one_line_summary(scene: LoadedScene) -> str:
    """``scenes/x.yaml: OK - 'x': 3 bodies, 2 springs; fields gravity, drag; 4 s at 30 fps (120 frames); RK45 …``."""
    spec = scene.spec
    parts = [plural(len(spec.bodies), "body", "bodies")]
    if spec.emitters:
        parts.append(plural(len(spec.emitters), "emitter"))
    if spec.anchors:
        parts.append(plural(len(spec.anchors), "anchor"))
    if spec.springs:
        parts.append(plural(len(spec.springs), "spring"))
    fields = ", ".join(field.type for field in spec.fields) or "none"
    return (f"{scene.path or scene.name}: OK - '{scene.name}': {', '.join(parts)}; fields: {fields}; "
            f"{spec.duration:g} s at {spec.fps} fps ({spec.frame_count} frames); "
            f"{describe_solver(spec.solver)}")
