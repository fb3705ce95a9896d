"""The floor plan holds: one table of integration methods that the scene format agrees with, and the import
contracts (the wall at compile, no cycles) that .importlinter states."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from animbatch.compile.model import compile_scene
from animbatch.scene.schema import ADAPTIVE_METHODS, CONTACT_METHODS, FIXED_STEP_METHODS, SolverSpec
from animbatch.sim.integrators import FIXED_STEP_SCHEMES, METHODS, FixedStepIntegrator, ScipyIntegrator
from animbatch.sim.integrators.fixed_step import ButcherTableau
from animbatch.sim.integrators.methods import runge_kutta
from animbatch.sim.integrators.stability import amplification
from animbatch.sim.model import Dynamics
from support.paths import REPO
from support.scenarios import oscillator_exact, oscillator_scene
from support.scenes import scene


def test_the_scene_format_offers_exactly_the_methods_of_the_table():
    """Every method a scene may name is in the method table, in the same family, and nothing else is."""
    assert set(ADAPTIVE_METHODS) == {name for name, m in METHODS.items() if not m.fixed_step}
    assert set(FIXED_STEP_METHODS) == {name for name, m in METHODS.items() if m.fixed_step}
    for name in METHODS:  # and each validates as a solver method
        assert SolverSpec(method=name).method == name
    # validate refuses contacts to the others without loading the schemes
    assert set(CONTACT_METHODS) == {name for name, m in METHODS.items() if m.scheme and m.scheme.takes_constraints}


def test_the_methods_that_default_to_one_step_per_frame_are_the_implicit_fixed_step_ones():
    """Without solver.dt, the implicit fixed-step methods (stable at any step) take one step per frame; the step
    rule's list and the method table agree."""
    from animbatch.sim.integrators.step_plan import ONE_STEP_PER_FRAME

    assert set(ONE_STEP_PER_FRAME) == {name for name, m in METHODS.items() if m.fixed_step and m.implicit}


@pytest.mark.parametrize("name", [name for name, m in METHODS.items() if m.fixed_step])
def test_every_fixed_step_method_is_complete_in_the_table(name):
    """A fixed-step method has its scheme, its particle kernel and a stability matrix that tends to the identity
    (a consistent method) and agrees with its order: the one-step error on an undamped oscillator is O(h^(p+1))."""
    method = METHODS[name]
    assert method.scheme is not None and method.particle_step is not None and method.step_matrix is not None
    assert FixedStepIntegrator(name, dt=1e-3).method == name
    errors = []
    for h in (1e-2, 5e-3):
        matrix = method.step_matrix(h, 1.0, 0.0)
        exact = np.array([[np.cos(h), np.sin(h)], [-np.sin(h), np.cos(h)]])
        state = np.array([1.0, 0.0]) if len(matrix) == 2 else np.array([1.0, 0.0, -1.0])  # Verlet carries a
        errors.append(np.linalg.norm((matrix @ state)[:2] - exact @ np.array([1.0, 0.0])))
    assert np.log2(errors[0] / errors[1]) == pytest.approx(method.order + 1, abs=0.3)
    assert amplification(name, 1e-3, 1.0, 0.0) == pytest.approx(1.0, abs=1e-2)


def test_an_explicit_runge_kutta_method_is_one_entry_made_from_its_tableau(monkeypatch):
    """The recipe of docs/architecture.md holds: classic RK4, added as one table entry built from its Butcher
    tableau and nothing else, steps a damped oscillator at fourth order (halving dt divides the error by 16), its
    step matrix is I + Z + Z²/2 + Z³/6 + Z⁴/24, and its particle kernel steps a pool the same way as the scheme."""
    rk4 = ButcherTableau(a=((), (0.5,), (0.0, 0.5), (0.0, 0.0, 1.0)), b=(1 / 6, 1 / 3, 1 / 3, 1 / 6),
                         c=(0.0, 0.5, 0.5, 1.0), order=4)
    method = runge_kutta("rk4", "classic Runge–Kutta", rk4)
    monkeypatch.setitem(METHODS, "rk4", method)
    monkeypatch.setitem(FIXED_STEP_SCHEMES, "rk4", method.scheme)
    z = 0.1 * np.array([[0.0, 1.0], [-4.0, -0.4]])  # h = 0.1 s, ω = 2 rad/s, decay 0.2 /s
    taylor = np.eye(2) + z + z @ z / 2 + z @ z @ z / 6 + z @ z @ z @ z / 24
    assert method.step_matrix is not None and np.allclose(method.step_matrix(0.1, 2.0, 0.2), taylor, atol=1e-15)

    model = compile_scene(scene(oscillator_scene(0.2, method="verlet", duration=2.0, fps=10)).spec)
    errors = []
    for dt in (0.1 / 8, 0.1 / 16, 0.1 / 32):
        result = FixedStepIntegrator("rk4", dt=dt).integrate(Dynamics(model), model.y0, model.frame_times)
        x = model.positions(result.states)[:, 0, 0] - 1.0
        errors.append(np.abs(x - oscillator_exact(model.frame_times, 0.2, 5.0, 0.2)).max())
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - 4) < 0.3), orders

    def spring(x, v, mass, radius):  # ẍ = -4 x - 0.4 ẋ, per particle
        return -4.0 * x - 0.4 * v
    x0, v0 = np.array([[1.0, 0.0, 0.0]]), np.zeros((1, 3))
    assert method.particle_step is not None
    x1, v1, _ = method.particle_step(spring, x0, v0, spring(x0, v0, None, None), np.ones(1), np.ones(1), 0.1)
    assert np.allclose([x1[0, 0], v1[0, 0]], method.step_matrix(0.1, 2.0, 0.2) @ np.array([1.0, 0.0]))


@pytest.mark.parametrize("name", [name for name, m in METHODS.items() if not m.fixed_step])
def test_every_adaptive_method_has_its_scipy_solver(name):
    """An adaptive method names the scipy solver that steps it."""
    assert METHODS[name].solver is not None and ScipyIntegrator(name).method == name


def run_tool(name: str, *arguments: str) -> subprocess.CompletedProcess:
    """Run a checker installed beside this Python (the test extras install them) from the project's root."""
    command = shutil.which(name, path=str(Path(sys.executable).parent))
    if command is None:
        pytest.skip(f"{name} is not installed (bash scripts/dev.sh test installs it)")
    return subprocess.run([command, *arguments], cwd=REPO, capture_output=True, text=True, timeout=300)


def _sources_matching(pattern: str) -> list[str]:
    """The files of src/animbatch with a line matching the regular expression ``pattern`` (paths from src/)."""
    import re

    return sorted(str(path.relative_to(REPO / "src")) for path in (REPO / "src" / "animbatch").rglob("*.py")
                  if re.search(pattern, path.read_text(), re.MULTILINE))


def test_the_frame_count_and_the_default_step_are_each_written_once():
    """One rule for how many frames a run has (the timeline) and one for the step when the scene names none (the
    step plan): every stage reads them from there, on either side of the wall."""
    assert _sources_matching(r"math\.ceil\(\s*duration") == ["animbatch/timeline.py"]
    assert _sources_matching(r"^(?!from |import |__all__).*DEFAULT_DT") == ["animbatch/sim/integrators/step_plan.py"]


def test_the_tests_are_laid_out_like_the_code():
    """Every folder of tests/ mirrors a package or module of src/animbatch (tests/sim/contact tests
    animbatch.sim.contact, tests/sim/motion animbatch.sim.motion),
    besides the helpers (support/), the golden frames and the hard cases (stability/); no test module imports
    another test module or conftest (shared code lives in support/, fixtures in conftest.py)."""
    import ast

    tests = REPO / "tests"
    own = {"support", "golden", "stability", "__pycache__"}
    for folder in (path for path in tests.rglob("*") if path.is_dir()):
        relative = folder.relative_to(tests)
        if own & set(relative.parts):
            continue
        code = REPO / "src" / "animbatch" / relative
        assert (code / "__init__.py").is_file() or code.with_suffix(".py").is_file(), \
            f"tests/{relative} mirrors no package or module of src/animbatch"
    modules = {path.stem for path in tests.rglob("test_*.py")}
    for path in tests.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = ([alias.name for alias in node.names] if isinstance(node, ast.Import) else
                     [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            for name in names:
                assert name.split(".")[0] not in modules | {"conftest"}, \
                    f"{path.relative_to(REPO)} imports {name}: put what both need in tests/support/"


#: File names several packages share because each file is the same concept on its own floor: the scene format's
#: declaration, the compiler's translation, the simulation's numbers, the drawing (bodies.py in scene/schema,
#: compile and sim). Any other shared name means two different things, and fails the test below.
SAME_CONCEPT_ON_EACH_FLOOR = {"arrows", "bodies", "checks", "compiled", "contacts", "controllers", "fields",
                              "frame_geometry", "materials", "model", "stopwatches", "vertices"}


def test_a_file_name_means_one_thing():
    """No two modules share a file name unless they are the same concept on different floors (listed above); one
    class is called ModelBuilder (the simulation's; the compiler's subclass that also takes scene specs is
    SceneModelBuilder)."""
    import ast
    from collections import Counter

    names = Counter(path.stem for path in (REPO / "src" / "animbatch").rglob("*.py") if path.stem != "__init__")
    shared = {name for name, count in names.items() if count > 1}
    assert shared <= SAME_CONCEPT_ON_EACH_FLOOR, f"file names meaning different things: {shared - SAME_CONCEPT_ON_EACH_FLOOR}"
    builders = [path.relative_to(REPO) for path in (REPO / "src").rglob("*.py")
                for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
                if isinstance(node, ast.ClassDef) and node.name == "ModelBuilder"]
    assert len(builders) == 1, builders


def test_the_import_contracts_hold():
    """lint-imports finds every contract of .importlinter kept: the simulation never imports the scene format,
    rendering never imports the simulation, drivers sit above stages above the compiler, and no package cycles."""
    done = run_tool("lint-imports", "--config", str(REPO / ".importlinter"))
    assert done.returncode == 0, done.stdout + done.stderr


def test_ruff_finds_nothing():
    """ruff's rules of pyproject.toml hold, among them no module-level import of pyvista, vtk, imageio, matplotlib,
    dask or trimesh outside the packages that draw, encode, plot or distribute (start-up time of the CLI)."""
    done = run_tool("ruff", "check", "src", "tests", "benchmarks")
    assert done.returncode == 0, done.stdout + done.stderr


@pytest.mark.slow
def test_the_wall_type_checks():
    """mypy finds no error in the files of pyproject's [tool.mypy] (the simulation, the scene format, the compiler,
    the stages, drawing, exporting, teaching): the Model's tables are typed, optional parts are narrowed where used,
    and no ``type: ignore`` is left that is not needed. mypy keeps what it
    learnt in the user's cache, as the compiled kernels do, not in the checkout: a fresh clone on a machine that ran
    the suite before checks only what changed (about 40 s for the whole simulation otherwise). mypy tells a changed
    module by its contents, so a stale entry is never used."""
    cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "animbatch" / "mypy"
    done = run_tool("mypy", "--cache-dir", str(cache))
    assert done.returncode == 0, done.stdout + done.stderr


def test_the_type_checks_cover_the_wall_and_few_checks_are_waived():
    """mypy's files include every package the wall's types must hold in, and fewer than 20 ``type: ignore`` are left
    in src/, each with its reason after it."""
    import re
    import tomllib

    files = set(tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["mypy"]["files"])
    assert {f"src/animbatch/{part}" for part in ("sim", "compile", "stages.py", "render", "export", "teaching")} <= files
    waived = [(path.relative_to(REPO), line) for path in (REPO / "src").rglob("*.py")
              for line in path.read_text(encoding="utf-8").splitlines() if "type: ignore" in line]
    assert len(waived) < 20, waived
    for path, line in waived:
        assert re.search(r"type: ignore\[[\w-]+(, [\w-]+)*\]\s+#\s*\S", line), f"{path}: no reason given: {line}"


@pytest.mark.parametrize("method", [*METHODS, "analytic"])
def test_validate_describes_the_solver_as_the_integrator_built_from_it_does(method):
    """validate prints the method's line without building the integrator; it must be the line the run prints."""
    from animbatch.compile.integrator import make_integrator
    from animbatch.summary import describe_solver

    settings = {"method": method, "max_step": 0.01} if method in METHODS and not METHODS[method].fixed_step else \
        {"method": method, "dt": 2e-3} if method != "analytic" else {"method": method}
    solver = SolverSpec(**settings)
    assert describe_solver(solver) == make_integrator(solver).describe()


#: Modules that cost start-up time and that neither --help nor validate of a scene without meshes needs.
HEAVY = ("scipy.integrate", "scipy.sparse", "scipy.spatial", "scipy.linalg", "scipy.interpolate", "pyvista", "vtk",
         "trimesh", "matplotlib", "dask", "imageio", "numba")


@pytest.mark.slow
@pytest.mark.parametrize("arguments", [["--help"], ["validate", str(REPO / "scenes" / "projectile.yaml")],
                                       ["validate", str(REPO / "scenes" / "dominoes.yaml")]],
                         ids=["help", "validate projectile", "validate dominoes"])
def test_help_and_validate_load_no_heavy_library(arguments):
    """The start-up promise (under 0.5 s, measured by ``bench --only startup``) rests on what is imported: the
    command runs, and none of the heavy libraries is loaded (a fixed-step scene with contacts included)."""
    probe = ("import sys, runpy; sys.argv = ['animbatch', *sys.argv[1:]]\n"
             "try:\n    runpy.run_module('animbatch', run_name='__main__')\nexcept SystemExit as stop:\n"
             "    code = stop.code\nelse:\n    code = 0\n"
             f"print('LOADED', sorted(m for m in sys.modules if m.split('.')[0] in {{'scipy', 'pyvista', 'vtk', "
             f"'trimesh', 'matplotlib', 'dask', 'imageio', 'numba'}} and m.startswith({HEAVY!r})))\n"
             "sys.exit(code)")
    done = subprocess.run([sys.executable, "-c", probe, *arguments], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    loaded = done.stdout.rsplit("LOADED", 1)[1].strip()
    assert loaded == "[]", f"{' '.join(arguments)} loaded {loaded}"
