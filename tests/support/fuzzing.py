"""Mutated scenes for the fuzz test (``tests/scene/test_fuzz.py``) and its long run (``benchmarks/fuzz.py``).

A mutant starts from a bundled scene (its duration cut to a fraction of a second) and takes one to three mutations,
each at a random key path: delete it, swap its type, put a hostile number in it (NaN, ±inf, 1e300, 1e-300, 0,
negatives, scaled by up to 1e12), wrap it in a list or mapping, change a list's length, replace a name by an unknown one, add an unknown key, nest
it thousands of levels deep, or write unicode into it; or, on the text, duplicate a line (a duplicate key) or cut the
file short. :func:`check` then holds animbatch to its promise: loading either succeeds or raises a SceneError whose
every issue has ``file:line:column``; simulating either succeeds or raises a documented error (an exit code from the
README's list) within its time budget. Anything else (a traceback, a hang) fails.
"""

from __future__ import annotations

import copy
import math
import re
import signal
import time
import warnings
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import yaml
from hypothesis import strategies as st

from animbatch import api
from animbatch.errors import AnimbatchError, SceneError
from animbatch.stages import parse_scene
from support.paths import REPO

SCENES = REPO / "scenes"
#: Exit codes the README documents for errors meant for the user.
DOCUMENTED_EXIT_CODES = {1, 3, 4}
#: Simulated time of every mutant [s]: long enough to take steps and hit contacts, short enough for CI.
DURATION = 0.2
#: Wall-time limit of one mutant's simulation [s]; the cost pre-flight must refuse anything slower than this.
TIME_LIMIT = 20.0
#: The cost budget given to each mutant [estimated s]; the pre-flight refuses runs it predicts to cost more.
MAX_COST = 5.0
LOCATION = re.compile(r"^fuzz\.yaml:\d+:\d+$")

HOSTILE_NUMBERS = [math.nan, math.inf, -math.inf, 1e300, -1e300, 1e-300, 0, 0.0, -0.0, -1, -1.5, 1e12, 1e35, 1e36,
                   2**63, 2**64, -(2**63), 10**40, 3, 1e-9, 1e6]
TEXTS = ["", " ", "ball", "nosuchbody", "gravty", "RK99", "../../etc/passwd", "/etc/shadow", "CON", "ü∆ø𝔘",
         "\u202e", "a" * 300, "tomato", "#zz0000", "1e3", "true", "null"]


def base_scenes() -> dict[str, dict[str, Any]]:
    """Every bundled scene as plain data, with its duration cut to DURATION."""
    scenes = {}
    for path in sorted(SCENES.glob("*.yaml")):
        data = yaml.safe_load(path.read_text())
        data["duration"] = min(float(data.get("duration", 1.0)), DURATION)
        scenes[path.stem] = data
    return scenes


BASES = base_scenes()


def _paths(data: Any) -> list[tuple]:
    """Every key path in plain data down to 10 levels (below that, only nesting added by a mutation)."""
    found, todo = [], [((), data)]
    while todo:
        prefix, value = todo.pop()
        found.append(prefix)
        if len(prefix) < 10:
            items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
            todo += [((*prefix, key), item) for key, item in items]
    return sorted(found, key=lambda path: [str(part) for part in path])


def _get(data: Any, path: tuple) -> Any:
    for part in path:
        data = data[part]
    return data


def _hostile_value(draw: st.DrawFn, old: Any) -> Any:
    # scaled numbers come up most often: they keep a scene valid and so reach the simulation
    kind = draw(st.sampled_from(["number", "scaled", "scaled", "scaled", "scaled", "type", "length", "text", "deep",
                                 "unknown_key", "wrap"]))
    if kind == "wrap":  # a list or mapping where one value was expected (a name, a number)
        return draw(st.sampled_from([[old], {"a": old}, [[old]]]))
    if kind == "number":
        return draw(st.sampled_from(HOSTILE_NUMBERS))
    if kind == "scaled" and isinstance(old, int | float) and not isinstance(old, bool):
        return old * draw(st.sampled_from([1e6, 1e9, 1e12, -1, 0, 1e-6, 1e-12]))
    if kind == "scaled" and isinstance(old, list) and old:
        factor = draw(st.sampled_from([1e6, 1e12, -1, 0, 1e-12]))
        return [v * factor if isinstance(v, int | float) and not isinstance(v, bool) else v for v in old]
    if kind == "length" and isinstance(old, list):
        return old[:-1] if old and draw(st.booleans()) else [*old, *(old[:1] or [1.0])]
    if kind == "text":
        return draw(st.sampled_from(TEXTS) | st.text(max_size=12))
    if kind == "deep":
        value: Any = old
        for _ in range(draw(st.sampled_from([3, 70, 3000]))):
            value = [value]
        return value
    if kind == "unknown_key" and isinstance(old, dict):
        return {**old, draw(st.sampled_from(["colour", "masss", "typo", "ü"])): 1}
    return draw(st.sampled_from([None, True, [], {}, "x", [1, 2], {"a": 1}, 7, [[1, 2, 3]], [{"name": "b"}]]))


@st.composite
def mutants(draw: st.DrawFn) -> tuple[str, str]:
    """(base scene's name, mutated YAML text)."""
    name = draw(st.sampled_from(sorted(BASES)))
    data = copy.deepcopy(BASES[name])
    for _ in range(draw(st.integers(1, 2))):
        path = draw(st.sampled_from(_paths(data)))
        if not path:
            continue
        parent, last = _get(data, path[:-1]), path[-1]
        if draw(st.integers(0, 5)) == 0:
            del parent[last]
        else:
            parent[last] = _hostile_value(draw, parent[last])
    try:
        text = yaml.safe_dump(data, sort_keys=False, allow_unicode=True, width=10_000)
    except (RecursionError, yaml.YAMLError):  # PyYAML's own emitter recurses: nest the text instead
        text = "bodies: " + "[" * 3000 + "]" * 3000 + "\n"
    lines = text.splitlines(keepends=True)
    edit = draw(st.integers(0, 9))
    if edit == 0 and lines:  # a duplicate key, or a repeated list item
        at = draw(st.integers(0, len(lines) - 1))
        lines.insert(at, lines[at])
    elif edit == 1 and lines:  # a file cut short
        lines = lines[: draw(st.integers(0, len(lines) - 1))]
    return name, "".join(lines)


@dataclass
class Tally:
    """What happened to the mutants: outcome -> count, and the slowest simulation."""

    outcomes: Counter = field(default_factory=Counter)
    slowest: tuple[float, str] = (0.0, "")
    failures: list[str] = field(default_factory=list)


class _OverTime(Exception):
    pass


def _alarm(signum: int, frame: Any) -> None:
    raise _OverTime


def check(base: str, text: str, tally: Tally | None = None, *, time_limit: float = TIME_LIMIT) -> str:
    """Load and (if valid) simulate a mutant; return its outcome, or raise AssertionError on a broken promise."""
    tally = tally if tally is not None else Tally()
    try:
        scene = parse_scene(text, filename="fuzz.yaml")
    except SceneError as error:
        for issue in error.issues:
            assert LOCATION.match(issue.source) or "file is empty" in issue.message, f"{base}: issue without file:line:column: {issue}\n{text}"
        tally.outcomes["invalid scene (SceneError)"] += 1
        return "invalid"
    scene = _with_cost_budget(scene)
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, time_limit)
    start = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            api.simulate(scene)
        outcome = "simulated"
    except AnimbatchError as error:
        assert error.exit_code in DOCUMENTED_EXIT_CODES, f"{base}: undocumented exit code {error.exit_code}: {error}"
        outcome = f"refused ({type(error).__name__})"
    except _OverTime:
        raise AssertionError(f"{base}: simulating took over {time_limit:g} s; the cost pre-flight let it through"
                             f"\n{text}") from None
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    elapsed = time.perf_counter() - start
    if elapsed > tally.slowest[0]:
        tally.slowest = (elapsed, base)
    tally.outcomes[outcome] += 1
    return outcome


def _with_cost_budget(scene: Any) -> Any:
    """The scene with its cost budget lowered to MAX_COST, so that what the fuzzer makes expensive is refused."""
    if not hasattr(scene.spec.solver, "max_cost"):
        return scene
    solver = scene.spec.solver.model_copy(update={"max_cost": MAX_COST})
    return type(scene)(scene.spec.model_copy(update={"solver": solver}), scene.source, scene.path)
