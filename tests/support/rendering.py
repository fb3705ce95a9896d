"""What render tests share: a scene simulated and made ready to draw, and a ball crossing the view."""

from __future__ import annotations

from typing import Any

from animbatch import api, stages

#: A red ball crossing 6 m at 5 m/s over a plain ground, 320×180, no overlay: add render keys after it.
CHASE = """
name: chase
duration: 1.2
fps: 10
bodies:
  - {name: ball, radius: 0.15, position: [0, 1, 0], velocity: [5, 0, 0], color: "#ff0000"}
render:
  resolution: [320, 180]
  ground: {grid: false}
"""


def ready_to_draw(scene: Any) -> tuple[Any, Any]:
    """The trajectory of a loaded ``scene`` and its frame geometry: what a FrameRenderer draws from."""
    model = api.compile_model(scene)
    trajectory = api.simulate(scene, model=model)
    return trajectory, stages.frame_geometry(stages.plan(scene, model=model), trajectory)
