"""How surfaces look: colour, metallic and roughness from a body's own keys, else from its material (the scene's
materials or the built-in table); physically based shading checked by pixels, and looks kept out of the physics."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import stages
from animbatch.compile.frame_geometry import surface_look
from animbatch.materials import BUILT_IN_LOOKS
from animbatch.render.backend import select_backend
from animbatch.render.renderer import FrameRenderer
from animbatch.scene.loader import physics_fingerprint
from support.paths import REPO
from support.rendering import ready_to_draw

LOOKS = """
name: looks
duration: 0.1
fps: 10
materials:
  brass: {restitution: 0.5, static_friction: 0.4, kinetic_friction: 0.3, color: "#b5a642", metallic: 1,
          roughness: 0.35}
bodies:
  - {name: plain, radius: 0.1}
  - {name: steel, radius: 0.1, material: steel}
  - {name: painted, radius: 0.1, material: steel, color: "#00ff00"}
  - {name: polished, radius: 0.1, material: steel, roughness: 0.05}
  - {name: brass, radius: 0.1, material: brass}
  - {name: rough, radius: 0.1, roughness: 0.9}
colliders: [{type: plane, material: wood}]
"""


def test_a_look_comes_from_the_body_then_its_material_then_the_defaults():
    spec = stages.parse_scene(LOOKS).spec
    looks = {body.name: surface_look(spec, body) for body in spec.bodies}
    steel = BUILT_IN_LOOKS["steel"]
    assert looks["plain"] == (None, None), "the default material has no look: palette colour, plain shading"
    assert looks["steel"] == (steel.color, (steel.metallic, steel.roughness))
    assert looks["painted"] == ("#00ff00", (steel.metallic, steel.roughness)), "own colour, the material's finish"
    assert looks["polished"] == (steel.color, (steel.metallic, 0.05)), "own roughness, the material's metallic"
    assert looks["brass"] == ("#b5a642", (1.0, 0.35)), "a scene's material"
    assert looks["rough"] == (None, (0.0, 0.9)), "one key of a finish: the other takes its default"
    assert surface_look(spec, spec.colliders[0]) == (BUILT_IN_LOOKS["wood"].color, (0.0, 0.7))


def test_looks_do_not_change_the_physics():
    """Changing a colour, metallic or roughness of a body or material keeps the physics hash, so the bake is
    reused."""
    base = physics_fingerprint(stages.parse_scene(LOOKS).spec)
    for change in ('roughness: 0.35}', 'roughness: 0.8}'), ("{name: rough, radius: 0.1, roughness: 0.9}",
                                                           "{name: rough, radius: 0.1, metallic: 1}"):
        assert physics_fingerprint(stages.parse_scene(LOOKS.replace(*change)).spec) == base
    assert physics_fingerprint(stages.parse_scene(LOOKS.replace("radius: 0.1, material: brass",
                                                                "radius: 0.2, material: brass")).spec) != base


SPHERE = """
name: sphere
duration: 0.1
fps: 10
bodies: [{{name: ball, radius: 0.5, position: [0, 0, 0], color: "#ff0000", metallic: {metallic}, roughness: 0.25}}]
render:
  resolution: [200, 200]
  background: "#808080"
  show_time: false
  camera: {{position: [0, 0.8, 3], focal_point: [0, 0, 0]}}
"""


def brightest(metallic: float) -> np.ndarray:
    """The mean colour of the 30 brightest pixels of the sphere's face: its specular highlights."""
    scene = stages.parse_scene(SPHERE.format(metallic=metallic))
    trajectory, geometry = ready_to_draw(scene)
    with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
        image = renderer.draw(0.0, trajectory.positions[0]).astype(float)
    rows, columns = np.nonzero(np.abs(image - 128).sum(axis=2) > 30)
    radius = np.sqrt(len(rows) / np.pi)
    # the face, not the rim: at grazing angles every surface reflects white (Fresnel), metals too
    face = np.hypot(rows - rows.mean(), columns - columns.mean()) < 0.7 * radius
    ball = image[rows[face], columns[face]]
    return ball[np.argsort(ball.sum(axis=1))[-30:]].mean(axis=0)


@pytest.mark.slow
@pytest.mark.render
def test_a_metal_tints_its_highlights_with_its_colour_and_a_dielectric_does_not():
    """Physically based shading: a dielectric reflects about 4 % of every colour alike, so the highlight on red
    plastic is white; a metal's reflectance is its base colour, so the highlight on red metal stays red."""
    plastic, metal = brightest(0.0), brightest(1.0)
    assert min(plastic[1], plastic[2]) > 0.6 * plastic[0], plastic
    assert max(metal[1], metal[2]) < 0.35 * metal[0], metal


def test_the_documented_table_of_looks_is_the_built_in_one():

    text = REPO.joinpath("docs", "scene-format.md").read_text(encoding="utf-8")
    rows = {}
    for line in text.splitlines():
        cells = [cell.strip().strip("`") for cell in line.strip("|").split("|")]
        if len(cells) == 4 and cells[1].startswith("#"):
            rows[cells[0]] = (cells[1], float(cells[2]), float(cells[3]))
    assert rows == {name: (look.color, look.metallic, look.roughness) for name, look in BUILT_IN_LOOKS.items()}


SHEET = """
name: sheet
duration: 0.1
fps: 10
solver: {{method: backward_euler}}
bodies:
  - name: sheet
    type: cloth
    grid: {{size: [1.0, 1.0], resolution: [6, 6]}}
    position: [0, 1, 0]
    orientation: {{axis: [1, 0, 0], angle: {angle}}}
    density: 0.2
    structural: {{stiffness: 100}}
    pin: [{{corners: [top-left, top-right, bottom-left, bottom-right]}}]
    color: "#d8d0c0"
    back_color: "#d8d0c0"
render:
  resolution: [320, 180]
  show_time: false
  camera: {{position: [0.9, 1.64, 2.6], focal_point: [0, 1, 0]}}
"""


def sheet_brightness(angle: float) -> float:
    """The mean brightness (0…255) of a flat, pinned sheet turned ``angle`` [deg] about x, under the default
    lights and camera, on its pixels (those that differ from the empty frame)."""
    scene = stages.parse_scene(SHEET.format(angle=angle))
    trajectory, geometry = ready_to_draw(scene)
    with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
        image = renderer.draw(0.0, trajectory.positions[0]).astype(int)
        for actor in renderer.plotter.renderer.actors.values():
            actor.SetVisibility(False)
        empty = renderer.draw(0.0, trajectory.positions[0]).astype(int)
    sheet = np.abs(image - empty).max(axis=2) > 12
    assert sheet.sum() > 5000, "the sheet fills a good part of the frame"
    return float(image[sheet].mean())


@pytest.mark.slow
def test_a_sheet_seen_on_its_side_turned_away_from_the_key_light_is_at_least_half_as_bright():
    """The camera sees the sheet's face tilted up towards the key light (−30°: normal (0, 0.5, 0.87)), then the
    same sheet tilted down, the face it shows turned away from the key (30°: normal (0, −0.5, 0.87)), as a bedsheet
    swinging towards the camera: that side still reads as cloth (at least half as bright; it was a fifth). Its
    other face, seen from the same side (150°, 210°: the back by winding), is lit the same: two-sided."""
    toward, away = sheet_brightness(-30), sheet_brightness(30)
    assert away >= 0.5 * toward, (toward, away)
    assert toward > 150, "and the face towards the key is bright"
    assert abs(sheet_brightness(150) - toward) < 2 and abs(sheet_brightness(210) - away) < 2
