"""A model whose polyhedra touch edge on edge in every way the edge search knows, states jittered about its start,
and the contacts one of the searches that take the box poses finds there (shared by the edge tests: the compiled
search against numpy's, and the events' followed pairs against the search)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from animbatch.compile.model import compile_scene
from animbatch.sim.contact.contacts import Contacts
from animbatch.sim.contact.detection import body_box_poses
from animbatch.sim.model import Model
from animbatch.sim.model.dynamics import Dynamics
from animbatch.stages import parse_scene

PRISM = [(-0.5, 0, -0.1), (-0.5, 0, 0.1), (-0.5, 0.2, 0), (0.5, 0, -0.1), (0.5, 0, 0.1), (0.5, 0.2, 0)]
PRISM_FACES = [(1, 2, 3), (4, 6, 5), (1, 4, 5), (1, 5, 2), (2, 5, 6), (2, 6, 3), (3, 6, 4), (3, 4, 1)]
TURNED_X, TURNED_Z = "{axis: [1, 0, 0], angle: 45}", "{axis: [0, 0, 1], angle: 45}"
REST = 2 * 0.1 * np.sqrt(2)  # a 0.2 m square beam turned 45° lying across a ridge turned 45°: centre height


def polyhedra_model(folder: Path) -> Model:
    """A model whose polyhedra touch edge on edge in every way the search knows, side by side: a beam across a fixed
    ridge, a beam across a ridge body, a plank across a plank face on face, a prism ridge on ridge, and a box
    on a gem."""
    prism = folder / "prism.obj"
    prism.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in PRISM)
                     + "".join(f"f {a} {b} {c}\n" for a, b, c in PRISM_FACES))
    beam = "type: rigid, shape: {type: box, size: [1.0, 0.2, 0.2]}, density: 500"
    text = f"""
        duration: 0.1
        fps: 10
        bodies:
          - {{name: beam1, {beam}, position: [0, {REST - 0.002}, 0], orientation: {TURNED_X}}}
          - {{name: ridge, type: rigid, shape: {{type: box, size: [0.2, 0.2, 1.0]}}, density: 500,
              position: [3, 0, 0], orientation: {TURNED_Z}}}
          - {{name: beam2, {beam}, position: [3, {REST - 0.001}, 0], orientation: {TURNED_X}}}
          - {{name: low, type: rigid, shape: {{type: box, size: [1.0, 0.1, 0.2]}}, density: 500, position: [6, 0, 0]}}
          - {{name: high, type: rigid, shape: {{type: box, size: [0.2, 0.1, 1.0]}}, density: 500,
              position: [6, 0.099, 0]}}
          - {{name: prism1, type: rigid, shape: {{type: mesh, file: prism.obj}}, density: 500,
              position: [9, 0, 0], orientation: {{axis: [0, 1, 0], angle: 90}}}}
          - {{name: prism2, type: rigid, shape: {{type: mesh, file: prism.obj}}, density: 500,
              position: [9, {0.2 + 2 / 3 * 0.2 - 0.002}, 0], orientation: {{axis: [1, 0, 0], angle: 180}}}}
          - {{name: gem, type: rigid, shape: {{type: mesh, file: prism.obj}}, density: 2600, position: [12, 0, 0]}}
          - {{name: cube, type: rigid, shape: {{type: box, size: [0.2, 0.2, 0.2]}}, density: 500,
              position: [12, 0.33, 0], orientation: {TURNED_X}}}
        colliders:
          - {{type: box, position: [0, 0, 0], size: [0.2, 0.2, 1.0], orientation: {TURNED_Z}}}
        contacts: {{}}
        """
    loaded = parse_scene(textwrap.dedent(text), filename="polyhedra.yaml", path=folder / "polyhedra.yaml")
    return compile_scene(loaded.spec, folder)


def jittered_states(model: Model, count: int, scale: float) -> list[np.ndarray]:
    """The start and states near it (positions and orientations jittered by about ``scale``), normalised."""
    rng = np.random.default_rng(11)
    found = [model.y0.copy()]
    system = Dynamics(model)
    for _ in range(count - 1):
        y = model.y0 + scale * rng.normal(size=model.y0.shape)
        system.project(y, joints=False)
        found.append(y)
    return found


def searched(model: Model, y: np.ndarray, search) -> Contacts:
    """What one of the searches that take the box poses (edges, sides) finds at state ``y``: margin 1 mm, every body
    travelling 2 mm."""
    system = Dynamics(model)
    state = system.kinematics(*system.split(np.array(y, float)), t=0.0, copy=True)
    world = model.contact_world
    centres, rotations = body_box_poses(world, state)
    return search(world, state, world.statics_at(0.0), centres, rotations, 0.001, np.full(model.body_count, 0.002))
