"""The documentation and the JSON Schema match the code, and the bundled scenes satisfy both."""

from __future__ import annotations

import json

import jsonschema
import pytest
from click.testing import CliRunner

from animbatch.cli import cli
from animbatch.scene.key_reference import BEGIN, END, generate, key_paths
from animbatch.scene.schema import SceneSpec
from animbatch.scene.yaml_source import load_yaml
from support.paths import REPO

DOC = REPO / "docs" / "scene-format.md"
SCENES = sorted([*(REPO / "scenes").glob("*.yaml"), *(REPO / "templates").glob("*.yaml")])


def test_generated_reference_is_up_to_date():
    """docs/scene-format.md holds exactly the reference generated from the schema (regenerate with the command in
    its marker if this fails)."""
    text = DOC.read_text(encoding="utf-8")
    section = BEGIN + text.split(BEGIN, 1)[1].split(END, 1)[0] + END
    assert section == generate()


def test_every_model_of_the_schema_has_a_reference_section():
    """Every kind of mapping a scene can contain (found by walking the schema from the top) has its own section in
    the key reference, so no key can be left out by forgetting a section."""
    from animbatch.scene.key_reference import SECTIONS, reachable_models

    documented = {model for _, _, model in SECTIONS}
    missing = sorted(model.__name__ for model in reachable_models() - documented)
    assert not missing, f"no reference section for {missing}"


def test_every_key_is_documented():
    """Each key path of the schema appears in the docs, and every model and field has a description."""
    text = DOC.read_text(encoding="utf-8")
    for path in key_paths():
        assert f"`{path}`" in text, path
    assert len(list(key_paths())) > 60


@pytest.mark.slow
def test_json_schema_is_valid_and_accepts_the_bundled_scenes():
    """'animbatch schema' prints a valid JSON Schema under which every scene in scenes/ is valid."""
    result = CliRunner().invoke(cli, ["schema"])
    assert result.exit_code == 0
    document = json.loads(result.output)
    jsonschema.Draft202012Validator.check_schema(document)
    validator = jsonschema.Draft202012Validator(document)
    for path in SCENES:
        data, _ = load_yaml(path.read_text(), str(path))
        errors = [e.message for e in validator.iter_errors(data)]
        assert errors == [], f"{path.name}: {errors}"
    assert not validator.is_valid({"bodies": [{"name": "a", "mas": 1}]})  # extra keys are refused there too


def test_schema_file_output(tmp_path):
    """'animbatch schema -o file' writes the same document."""
    assert CliRunner().invoke(cli, ["schema", "-o", str(tmp_path / "s.json")]).exit_code == 0
    assert json.loads((tmp_path / "s.json").read_text())["title"] == "animbatch scene"
    assert SceneSpec.model_json_schema()["properties"].keys() <= json.loads((tmp_path / "s.json").read_text())[
        "properties"].keys()


@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_bundled_scene_validates(path):
    """Every example scene is valid."""
    result = CliRunner().invoke(cli, ["validate", str(path)])
    assert result.exit_code == 0, result.output


def test_the_architecture_page_figures_are_what_their_commands_count():
    """docs/architecture.md gives each of its figures with the command that counts it; run in the checkout, each
    command prints the figure (a module added or an ignore removed without updating the page fails here)."""
    import re
    import subprocess

    page = (REPO / "docs" / "architecture.md").read_text(encoding="utf-8")
    table = page.split("### The figures, and how to count them", 1)[1].split("\n\n##", 1)[0]
    rows = re.findall(r"^\| (.+?) \| (\d+) \| `(.+)` \|$", table, flags=re.MULTILINE)
    assert len(rows) >= 5
    for figure, value, command in rows:
        printed = subprocess.run(["bash", "-c", command.replace("\\|", "|")], cwd=REPO, capture_output=True,
                                 text=True, check=True).stdout.strip()
        assert printed == value, f"{figure}: the page says {value}, '{command}' prints {printed}"


def test_the_reference_describes_a_list_of_points_or_nulls_as_such():
    """joints[].attach and springs[].attach are lists of two points or nulls, not mappings chosen by type (a user
    who read the old line wrote mappings); discriminated unions stay 'mapping (by `type`)'."""
    page = (REPO / "docs" / "scene-format.md").read_text(encoding="utf-8")
    for key in ("joints[].attach", "springs[].attach"):
        rows = [line for line in page.splitlines() if line.startswith(f"| `{key}` |")]
        assert rows and all("| list of 2 items (each [x, y, z] or null) or null |" in row for row in rows), key
    assert "| `colliders` | list of mappings (by `type`) |" in page
