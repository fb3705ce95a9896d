"""Bad scenes give precise messages (file:line:column, key path, what is allowed, a fix) and never a traceback."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest
from click.testing import CliRunner

from animbatch.cli import cli
from animbatch.errors import SceneError
from support.scenes import scene

GOOD = """\
name: ok
duration: 1
bodies:
  - name: ball
    mass: 1.0
    position: [0, 1, 0]
fields:
  - type: gravity
"""


def validate(tmp_path: Path, text: str, *args: str) -> tuple[int, str]:
    path = tmp_path / "scene.yaml"
    path.write_text(textwrap.dedent(text))
    result = CliRunner().invoke(cli, ["validate", str(path), *args])
    return result.exit_code, result.output


def first_error(tmp_path: Path, text: str) -> str:
    code, output = validate(tmp_path, text)
    assert code == 1, output
    assert "Traceback" not in output
    return output.splitlines()[0].replace(str(tmp_path / "scene.yaml"), "scene.yaml")


def test_valid_scene_prints_one_summary_line(tmp_path):
    """A valid scene prints one line with its contents and exits 0."""
    code, output = validate(tmp_path, GOOD)
    assert code == 0
    assert output.count("\n") == 1
    assert "OK - 'ok': 1 body; fields: gravity; 1 s at 30 fps (30 frames); RK45" in output


def test_misspelt_key(tmp_path):
    """An unknown key is reported at the key, with the closest allowed key and the full list."""
    line = first_error(tmp_path, GOOD.replace("    mass: 1.0", "    mas: 1.0"))
    assert line.startswith("scene.yaml:5:5: bodies[0].mas: unknown key 'mas'; did you mean 'mass'? Allowed keys here:")
    assert "radius" in line and "velocity" in line


def test_wrong_type(tmp_path):
    """Text where a number belongs names the unit and the value given."""
    line = first_error(tmp_path, GOOD.replace("mass: 1.0", "mass: heavy"))
    assert line == "scene.yaml:5:11: bodies[0].mass: must be a number in kg (got 'heavy')"


def test_negative_mass(tmp_path):
    """A limit violation says the limit, the unit and the value."""
    line = first_error(tmp_path, GOOD.replace("mass: 1.0", "mass: -1.0"))
    assert line == "scene.yaml:5:11: bodies[0].mass: must be > 0 kg (got -1.0)"


def test_unknown_field_type(tmp_path):
    """A misspelt field type suggests the right one and lists all of them."""
    line = first_error(tmp_path, GOOD.replace("type: gravity", "type: gravty"))
    assert line == ("scene.yaml:8:11: fields[0].type: unknown field type 'gravty'; did you mean 'gravity'? "
                    "Allowed: gravity, gravitation, drag, wind, force, torque, angular_drag, buoyancy, aerodynamics, "
                    "electromagnetic, coulomb")


def test_malformed_yaml(tmp_path):
    """A YAML syntax error is reported with its position and the parser's explanation."""
    line = first_error(tmp_path, GOOD.replace("position: [0, 1, 0]", "position: [0, 1, 0"))
    # the unclosed '[' runs on until the ':' of 'fields:' on line 7, column 7
    assert line in ("scene.yaml:7:7: YAML syntax error: expected ',' or ']', but got ':' while parsing a flow "
                    "sequence",  # PyYAML's pure-Python parser
                    "scene.yaml:7:7: YAML syntax error: did not find expected ',' or ']' while parsing a flow "
                    "sequence")  # libyaml's


def test_missing_file(tmp_path):
    """A missing file is one line, with a close file name suggested."""
    (tmp_path / "projectile.yaml").write_text(GOOD)
    result = CliRunner().invoke(cli, ["validate", str(tmp_path / "projectle.yaml")])
    assert result.exit_code == 1
    assert result.output.strip() == (f"{tmp_path / 'projectle.yaml'}: no such file; did you mean "
                                     f"'{tmp_path / 'projectile.yaml'}'?")


def test_missing_file_for_render_is_not_a_traceback(tmp_path):
    """Every command reports a missing scene the same way, without a traceback."""
    result = CliRunner().invoke(cli, ["render", str(tmp_path / "nope.yaml")])
    assert result.exit_code == 1 and "no such file" in result.output and "Traceback" not in result.output


def test_all_errors_of_a_file_are_reported_at_once(tmp_path):
    """validate lists schema errors and cross-reference errors together, in file order, with a count."""
    code, output = validate(tmp_path, """\
        duration: 0
        bodies:
          - {name: a, mass: 0}
          - {name: a, radious: 1}
        springs:
          - {between: [a, b], stiffness: 10}
        fields:
          - {type: drag, model: linear}
    """)
    lines = [line.replace(str(tmp_path / "scene.yaml"), "scene.yaml") for line in output.splitlines()]
    assert code == 1
    assert lines == [
        "scene.yaml:1:11: duration: must be > 0 s (got 0)",
        "scene.yaml:3:21: bodies[0].mass: must be > 0 kg (got 0)",
        "scene.yaml:4:12: bodies[1].name: name 'a' is already used by bodies[0]; names must be unique",
        "scene.yaml:4:15: bodies[1].radious: unknown key 'radious'; did you mean 'radius'? "
        "Allowed keys here: type, name, mass, radius, position, velocity, charge, material, collide, color, metallic, "
        "roughness",
        "scene.yaml:6:19: springs[0].between[1]: unknown body or anchor 'b' Known: a",
        "scene.yaml:8:5: fields[0].coefficient: required key missing: the linear drag law needs 'coefficient' "
        "(C in N·s/m)",
        "6 errors",
    ]


@pytest.mark.parametrize("text, expected", [
    ("bodies: [{name: a, position: [1, 2]}]", "bodies[0].position: must be a list of 3 numbers [x, y, z] in m"),
    ("bodies: [{name: a}]\nsolver: {method: rk44}", "solver.method: must be one of RK23, RK45"),
    ("bodies: [{name: a, color: bleu}]", "bodies[0].color: unknown colour 'bleu'; did you mean 'blue'?"),
    ("bodies: [{name: 2a}]", "bodies[0].name: names start with a letter"),
    ("bodies: [{name: a}]\nfields: [{type: drag, model: stokes, coefficient: 1}]",
     "fields[0].coefficient: not used by the stokes law"),
    ("bodies: [{name: a}]\nrender: {resolution: [641, 480]}", "render.resolution[0]: must be even (got 641)"),
    ("bodies: [{name: a}]\nrender: {camera: {position: [1, 1, 1]}}",
     "render.camera.position: give both position and focal_point"),
    ("bodies: [{name: a}]\nfields: [{type: gravitation}]", "gravitation acts between bodies and needs at least 2"),
    ("bodies: [{name: a}]\nanchors: [{name: p, position: [0,0,0]}, {name: q, position: [1,0,0]}]\n"
     "springs: [{between: [p, q], stiffness: 1}]", "springs[0].between: both ends ('p', 'q') are anchors"),
    ("bodies: [{name: a}]\nfields: [{type: gravity, bodies: [b]}]", "fields[0].bodies[0]: unknown body or emitter 'b'"),
    ("bodies: []", "bodies: a scene needs at least one body"),
    ("bodies: [{name: a, mass: .inf}]", "bodies[0].mass: must be a finite number"),
    ("bodies: [{name: a, mass: true}]", "bodies[0].mass: must be a number in kg (got true)"),
    ("bodies: [{name: a}]\nsolver: {method: verlet, dt: 1e-3, extra: 1}", "solver.extra: unknown key 'extra'"),
    ("- 1\n- 2", "the scene must be a mapping of keys"),
    ("bodies: [{name: a}]\nbodies: []", "bodies: duplicate key (first given at line 1)"),
    ("bodies: !!python/object/apply:os.system [ls]", "YAML tag not allowed"),
])
def test_specific_messages(text, expected):
    """Each kind of mistake gets its own precise message."""
    with pytest.raises(SceneError) as caught:
        scene(text)
    assert expected in str(caught.value)


def test_yaml_follows_1_2_scalars():
    """1e-6 is a float (not text), 'no' stays text, 012 is twelve."""
    loaded = scene("""
        name: no
        fps: 012
        solver: {rtol: 1e-6}
        bodies: [{name: a}]
    """)
    assert loaded.spec.name == "no" and loaded.spec.fps == 12 and loaded.spec.solver.rtol == 1e-6


# ------------------------------------------------------------------ overrides


def test_set_overrides_change_values_and_are_validated():
    """--set paths with indices, names and new keys change the scene before validation."""
    loaded = scene(GOOD, "bodies[ball].mass=2.5", "bodies.0.velocity=[1, 0, 0]", "solver.dt=1e-3",
                   "solver.method=verlet", "render.resolution=[640, 360]")
    body = loaded.spec.bodies[0]
    assert body.mass == 2.5 and body.velocity == [1, 0, 0]
    assert loaded.spec.solver.method == "verlet" and loaded.spec.solver.dt == 1e-3
    assert loaded.spec.render.resolution == [640, 360]


def test_a_backslash_n_in_an_unquoted_text_override_starts_a_line_as_in_a_double_quoted_yaml_string():
    """A shell cannot easily pass a newline: 'render.time_label=a\\nb' is two lines; a single-quoted value keeps
    the backslash, as YAML does."""
    assert scene(GOOD, r"render.time_label=t = {t:.2f} s\nE = {E:.3f} J").spec.render.time_label == (
        "t = {t:.2f} s\nE = {E:.3f} J")
    assert scene(GOOD, r'render.time_label="a\nb"').spec.render.time_label == "a\nb"
    assert scene(GOOD, r"render.time_label='a\nb'").spec.render.time_label == "a\\nb"


def test_the_index_one_past_a_lists_end_appends_an_item_which_is_validated_like_the_others():
    loaded = scene(GOOD, "fields[1]={type: drag, model: linear, coefficient: 0.1}")
    assert [field.type for field in loaded.spec.fields] == [field.type for field in scene(GOOD).spec.fields] + ["drag"]
    with pytest.raises(SceneError, match=r"bodies\[1\]\.type: .*did you mean 'particle'"):
        scene(GOOD, "bodies[1]={type: particel, mass: 1}")


@pytest.mark.parametrize("override, expected", [
    ("bodies[0].mass=-2", "--set bodies[0].mass=-2: bodies[0].mass: must be > 0 kg (got -2)"),
    ("bodies[ghost].mass=1", "--set bodies[ghost].mass=1: bodies[ghost]: no item named 'ghost' in bodies; names: ball"),
    ("bodies[3].mass=1", "--set bodies[3].mass=1: bodies[3]: index 3 is out of range: bodies has 1 item"),
    ("solver.metod=RK45", "--set solver.metod=RK45: solver.metod: unknown key 'metod'; did you mean 'method'?"),
    ("duration", "--set duration: expected key.path=value"),
])
def test_bad_overrides_point_at_the_override(override, expected):
    """Errors in overrides name the override instead of a file position."""
    with pytest.raises(SceneError) as caught:
        scene(GOOD, override)
    assert str(caught.value).startswith(expected)


def test_cli_shortcut_errors_name_the_flag(tmp_path):
    """--dt and --resolution are validated like the file, and errors quote the flag as typed."""
    path = tmp_path / "scene.yaml"
    path.write_text(GOOD)
    result = CliRunner().invoke(cli, ["info", str(path), "--dt", "-1", "--method", "verlt"])
    assert result.exit_code == 1
    assert "--dt -1: solver.dt: must be > 0 s (got -1)" in result.output
    assert "--method verlt: solver.method: must be one of" in result.output and "did you mean 'verlet'?" in result.output


def test_yaml_merge_keys_override_without_being_duplicates():
    """'<<: *anchor' merges shared values; the item's own keys override them, and errors point at the own value."""
    loaded = scene("""
        bodies:
          - &bead {name: b1, mass: 0.1, radius: 0.04, position: [0.2, 2, 0]}
          - {<<: *bead, name: b2, position: [0.4, 2, 0]}
    """)
    assert [(b.name, b.mass, b.position) for b in loaded.spec.bodies] == [
        ("b1", 0.1, [0.2, 2, 0]), ("b2", 0.1, [0.4, 2, 0])]
    with pytest.raises(SceneError, match=r"test.yaml:4:56: bodies\[1\].mass: must be > 0 kg"):
        scene("""
            bodies:
              - &bead {name: b1, mass: 0.1, radius: 0.04, position: [0.2, 2, 0]}
              - {<<: *bead, name: b2, position: [0.4, 2, 0], mass: -1}
        """)


def test_a_method_that_cannot_keep_contacts_is_refused_where_it_is_named(tmp_path):
    """Explicit Euler and midpoint move positions with the velocities from before the step, so bodies would sink
    into a collider: a scene with contacts that asks for one (by any alias) is refused at solver.method, with the
    methods that can. Without contacts, or with the ball out of collisions, the same method is fine."""
    with_floor = GOOD + "colliders:\n  - type: plane\n"
    line = first_error(tmp_path, with_floor + "solver:\n  method: RK2\n")
    assert line.startswith("scene.yaml:12:11: solver.method: midpoint cannot keep contacts")
    assert "Use symplectic_euler or verlet" in line
    assert validate(tmp_path, with_floor + "solver:\n  method: verlet\n")[0] == 0
    assert validate(tmp_path, GOOD + "solver:\n  method: euler\n")[0] == 0
    unfloored = with_floor.replace("    position: [0, 1, 0]", "    position: [0, 1, 0]\n    collide: false")
    assert validate(tmp_path, unfloored + "solver:\n  method: euler\n")[0] == 0
