"""``animbatch import``: an MJCF model becomes a scene that moves as MuJoCo moves the model (checked against MuJoCo
itself when it is installed, and against a pendulum's closed form always); what does not map is listed with its
line, never dropped."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest
from click.testing import CliRunner

from animbatch import api
from animbatch.cli import cli
from animbatch.scene.mjcf import MjcfError, import_mjcf
from support.paths import REPO, SCENES

CHAIN = """<mujoco model="chain">
  <option timestep="0.001"/>
  <default>
    <geom type="capsule" size="0.02" density="800"/>
    <joint type="hinge" axis="0 1 0"/>
  </default>
  <worldbody>
    <light pos="0 0 3"/>
    <body name="link1">
      <joint name="j1"/>
      <geom fromto="0 0 0 0.3 0 0"/>
      <body name="link2" pos="0.3 0 0">
        <joint name="j2"/>
        <geom fromto="0 0 0 0.3 0 0"/>
        <body name="link3" pos="0.3 0 0" euler="0 0 30">
          <joint name="j3"/>
          <geom fromto="0 0 0 0.25 0 0" size="0.025"/>
        </body>
      </body>
    </body>
  </worldbody>
  <sensor><jointpos joint="j1"/></sensor>
</mujoco>
"""


def _write(tmp_path, text, name="model.xml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _against_mujoco(path):
    """Our joints' angles and MuJoCo's over 1 s (benchmarks/peers.py's comparison, which its table prints too)."""
    pytest.importorskip("mujoco")
    sys.path.insert(0, str(REPO / "benchmarks"))
    import peers

    return peers.imported_angles(path)


def test_an_imported_chain_swings_as_mujoco_swings_it(tmp_path):
    path = _write(tmp_path, CHAIN)
    ours, theirs = _against_mujoco(path)
    assert theirs[-1].max() > 0.3  # they swung
    np.testing.assert_allclose(ours, theirs, atol=1e-6)


def test_an_imported_figure_with_ball_joints_defaults_and_a_servo_moves_as_mujoco_moves_it():
    path = SCENES / "models" / "figure.xml"
    ours, theirs = _against_mujoco(path)
    assert theirs[-1].max() > 1.0
    np.testing.assert_allclose(ours, theirs, atol=1e-6)


def test_a_hinged_capsule_swings_with_the_compound_pendulums_period(tmp_path):
    """T = 2π √(I_pivot / (m g d)) for small swings, the capsule's m and I from MuJoCo's geom sizes (a cylinder
    of length l = 2 h and two hemispherical caps of radius r, density 1000): the import keeps the mass properties."""
    r, h, tilt = 0.03, 0.2, 0.05  # [m], [m], [rad]: the bar hangs from its top end, tilted a little
    path = _write(tmp_path, f"""<mujoco><compiler angle="radian"/>
      <worldbody><body name="bar" euler="{tilt} 0 0"><joint axis="1 0 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 {-2 * h}" size="{r}"/></body></worldbody></mujoco>""")
    scene = api.parse_scene(import_mjcf(path).text, filename="bar.yaml", overrides=[
        "duration=4", "fps=200", "solver.method=DOP853", "solver.rtol=1e-10", "solver.atol=1e-12"])
    trajectory = api.simulate(scene)
    length = 2 * h  # of the cylinder between the caps
    cylinder, cap = 1000 * math.pi * r**2 * length, 1000 * 2 / 3 * math.pi * r**3
    mass, d = cylinder + 2 * cap, h  # the centre of mass halfway down
    # about the centre, then moved to the pivot (parallel axes)
    centre = (cylinder * (length**2 / 12 + r**2 / 4)
              + 2 * cap * (2 / 5 * r**2 + length**2 / 4 + 3 / 8 * length * r))
    period = 2 * math.pi * math.sqrt((centre + mass * d**2) / (mass * 9.81 * d))
    period *= 1 + tilt**2 / 16  # the first correction for the amplitude
    height = trajectory.positions[:, 0, 1]  # the centre rises and falls twice a period
    lows = [trajectory.times[k] for k in range(1, len(height) - 1)
            if height[k] < height[k - 1] and height[k] <= height[k + 1]]
    measured = 2 * float(np.mean(np.diff(lows)))
    assert measured == pytest.approx(period, rel=2e-3)


def test_what_does_not_map_is_listed_with_its_line_and_written_at_the_top_of_the_scene(tmp_path):
    path = _write(tmp_path, CHAIN.replace('<geom fromto="0 0 0 0.25 0 0" size="0.025"/>',
                                          '<geom fromto="0 0 0 0.25 0 0" size="0.025"/>\n'
                                          '          <geom type="mesh" mesh="hand"/>\n'
                                          '          <inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>'))
    imported = import_mjcf(path)
    line = _line_of(path.read_text())
    assert imported.not_mapped == [
        f"line {line('<light')}: <light>: not mapped (the renderer has its own lights and camera)",
        f"line {line('mesh=')}: <geom type='mesh'>: not mapped (spheres, capsules, cylinders and boxes are)",
        f"line {line('<inertial')}: <inertial> of body 'link3': its mass and inertia come from its geoms instead",
        f"line {line('<sensor')}: <sensor>: not mapped"]
    assert f"#   - line {line('mesh=')}: <geom type='mesh'>" in imported.text.split("\nname:")[0]


def _line_of(text):
    """The 1-based line on which a piece of ``text`` first appears."""
    return lambda piece: text[:text.index(piece)].count("\n") + 1


def test_the_defaults_classes_and_childclass_reach_the_geoms_and_joints(tmp_path):
    path = _write(tmp_path, """<mujoco><default><default class="arm"><geom type="box" size="0.1 0.2 0.3"/>
        <joint type="slide" axis="1 0 0" range="-0.5 0.25"/></default></default>
      <worldbody><body name="a" childclass="arm"><joint/><geom/>
        <body name="b" pos="0 0 -1"><joint type="hinge" axis="0 0 1" range="-90 45"/><geom class="main" size="0.05"/>
        </body></body></worldbody></mujoco>""")
    scene = import_mjcf(path).scene
    a, b = scene["bodies"]
    assert a["shape"] == {"type": "box", "size": [0.2, 0.4, 0.6]}
    assert b["shape"] == {"type": "sphere", "radius": 0.05}  # class="main": the main defaults, a sphere
    slide, hinge = scene["joints"]
    assert slide["type"] == "slider" and slide["limits"] == [-0.5, 0.25] and slide["axis"] == [1, 0, 0]
    assert hinge["limits"] == pytest.approx([-math.pi / 2, math.pi / 4])  # degrees, MuJoCo's default unit
    assert hinge["axis"] == [0, 1, 0]  # MuJoCo's z is our y


def test_the_command_writes_a_valid_scene_lists_what_it_left_and_keeps_an_existing_file(tmp_path):
    path = _write(tmp_path, CHAIN)
    runner = CliRunner()
    result = runner.invoke(cli, ["import", str(path)])
    assert result.exit_code == 0, result.output
    assert f"not mapped: line {_line_of(CHAIN)('<sensor')}: <sensor>: not mapped" in result.output
    assert "wrote" in result.output and "3 bodies, 3 joints, 2 elements not mapped" in result.output
    assert api.load_scene(tmp_path / "model.yaml").spec.name == "chain"
    again = runner.invoke(cli, ["import", str(path)])
    assert again.exit_code != 0 and "--force" in again.output
    not_mjcf = _write(tmp_path, "<robot name='r'/>", "robot.urdf")
    refused = runner.invoke(cli, ["import", str(not_mjcf)])
    assert refused.exit_code == 1 and "not an MJCF file" in refused.output
    with pytest.raises(MjcfError, match="cannot be read as XML"):
        import_mjcf(_write(tmp_path, "<mujoco><worldbody>", "broken.xml"))
