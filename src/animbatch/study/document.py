"""Regenerate ``docs/accuracy.md``: the work-precision study of the bundled scenes, with plots and a guide.

    bash scripts/dev.sh accuracy            # or: .venv/bin/python -m animbatch.study.document

Each scene in :data:`SCENES` is studied with its own ``study`` settings (every applicable integrator); the plots,
tables, CSV and JSON go to ``docs/accuracy/<scene>/`` and the page links them. The guide at the end is written
from what these studies show; the numbers around it are measured on the machine that ran the command (named on
the page), so they move from machine to machine while their ratios hold.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
import warnings
from pathlib import Path

from animbatch import stages
from animbatch.files import write_text_atomic
from animbatch.study.report import write_outputs
from animbatch.study.study import TARGETS, StudyResult, run_study

#: The bundled scenes the page studies, each standing for a kind of scene.
SCENES = {
    "projectile": "uniform gravity only: every method with a second-order or better step is exact up to round-off",
    "damped_oscillator": "three damped springs to fixed anchors (closed form): smooth, mildly stiff",
    "two_body_orbit": "a Kepler binary (closed form): long-run energy and angular momentum matter",
    "hanging_chain": "a chain of eight beads on springs under gravity (tight DOP853 reference): a small spring mesh",
    "bouncing_balls": "four balls bouncing on a plane (tight reference with located impacts): contacts",
    "double_pendulum": "the first 6 s of a chaotic double pendulum on two rods (distance joints; tight reference): "
                       "joints, and errors that chaos amplifies",
    "mixed_pile": "the first second of twelve boxes, balls, logs, pills and gems dropped into a bin (a fixed-step "
                  "reference at frame/256, checked at frame/128): a contact pile, and the chaos of many impacts",
    "curtain": "the first 1.5 s of a 30×24 curtain falling from two corners (ω up to 5·10³ rad/s; tight reference "
               "checked by Radau): stiff cloth",
    "fireworks": "three bursts of 2500 sparks under gravity and quadratic drag (compared particle by particle with "
                 "a tight reference): emitted particles",
}

#: Settings changed for the study (as ``--set`` would): shorter runs where the whole scene would take too long.
OVERRIDES = {
    "double_pendulum": ["duration=6", "study.repeats=2"],
    # adaptive runs stop at the first crowd of contact events (named), so two tolerances show it
    "mixed_pile": ["duration=1", "study.methods=[RK23, RK45, DOP853, Radau, BDF, LSODA, symplectic_euler, verlet, "
                   "backward_euler]", "study.rtols=[1.0e-3, 1.0e-5]", "study.repeats=1"],
    "curtain": ["duration=1.5", "study.rtols=[1.0e-2, 1.0e-3, 1.0e-4, 1.0e-5, 1.0e-6]", "study.dt_levels=9",
                "study.repeats=1"],
}

GUIDE = """\
## Which integrator for which scene

What the studies above show, as a rule of thumb (the tables give the numbers):

- **Smooth motion, no contact** (projectiles, orbits, oscillators, drag): an adaptive explicit pair. **DOP853**
  reaches 1e-6 and beyond for the least time; **RK45** is as good at the 1e-3 ("visually exact") level and the
  default. Requested tolerance and achieved error differ (see err/rtol in the tables): the error is that of the
  whole run, the tolerance a per-step target, so pick rtol one or two decades below the error you want.
- **Long runs where invariants matter** (orbits, undamped springs): **verlet** (velocity Verlet) keeps energy in a
  bounded band and angular momentum to round-off for as long as you run it; adaptive methods drift slowly and
  steadily. Verlet is second order: halving dt quarters its error.
- **Fixed steps**: explicit **euler** and **midpoint** are for teaching; euler is first order and gains energy on
  every orbit and spring (the stability guard stops it when the gain runs away). **symplectic_euler** is first order
  but stable up to ω dt = 2 on springs and the most robust with many contacts.
- **Stiff springs and cloth** (ω dt ≫ 1 at the frame rate): **backward_euler** at one step per frame for a render:
  stable at any step, it damps every vibration it cannot resolve, and costs a fraction of any other method (the
  curtain's 1.5 s in 0.6 s, the motion plausible but 3.5 % of the scene's size away from the exact one; the error
  shrinks only slowly with dt, 1.7× per halving, because the damping is what it trades for stability). For an
  *accurate* cloth the adaptive explicit methods are as fast as anything here: their steps are held at the stability
  limit whatever the tolerance (hence their flat lines), and at that step DOP853 is already accurate to 2·10⁻⁵ at
  rtol 1e-3. **BDF** and **Radau** get the analytic sparse Jacobian, but a cloth's fast vibrations are lightly
  damped and real, so their steps are limited by accuracy and each costs sparse factorisations and solves: BDF takes
  about as long as DOP853 (3–7 s), but its errors stay between 4·10⁻⁵ and 7·10⁻³ where DOP853's reach 10⁻⁷, and
  Radau is 2.5–5× slower than either. Implicit adaptive methods pay off where the fast modes are strongly damped
  (truly stiff: they decay instead of ringing); on the 64×64 cloth of the scene format's "Stiff springs" benchmark
  too, BDF and RK45 take about as long, and backward Euler 12× less. Fixed-step explicit methods are refused
  outright where their step is unstable: on the curtain every step down to frame/64 (frame/128 for symplectic_euler,
  all nine for verlet, whose dampers limit it to 1·10⁻⁴ s; explicit euler at frame/128 passes the check and is
  stopped where it diverges); at frame/256 symplectic_euler reaches 4·10⁻⁵ in 4.8 s. The pre-flight check warns when
  an adaptive explicit method would need millions of steps. **LSODA** gets no analytic Jacobian (it takes only dense
  ones) and timed out on the curtain; the pre-flight check warns about it on large spring systems.
- **Contacts**: the adaptive path locates every impact on the solver's dense output, so its bounce times are as
  accurate as its tolerance; fixed-step methods bounce within one step (a first-order error in contact times, see
  the contact column) and are the robust choice for piles and resting stacks. Explicit euler and midpoint are not
  offered with collisions.
- **LSODA** switches between Adams and BDF by itself: a safe choice when you do not know whether a scene is stiff,
  and on these scenes often among the fastest to 1e-6.
- **Chaotic scenes** (the hanging chain released sideways, many bodies in contact): small errors grow
  exponentially, so over a long run only a high-order adaptive method at a tight tolerance stays close to the
  reference; no fixed-step method reaches 1e-3 on the chain at dt ≥ frame/32. The motion of a loose run is still
  plausible, just not the same motion: choose by what the animation must show.
- **Jointed scenes** (the double pendulum on two rods): every method holds the rods (they are projected), so the
  error is in the motion, and chaos multiplies it. For tight errors a high-order adaptive method is the tool:
  **LSODA** reaches 1e-6 first. Of the fixed steps **verlet** converges at its order (1e-3 at about frame/16), and
  on the compiled equations of motion a fixed step and its projection cost so little that it reaches 1e-3 in tens
  of milliseconds, as soon as DOP853. **symplectic_euler**, whose rods are projected by SHAKE after each step
  (positions and momenta together), converges at first order and reaches 1e-3 at about frame/32; projecting the
  positions alone, as it did before, gained energy at every step, and none of its runs got there.
  **backward_euler** takes the very same steps here (with no springs its linear system holds the masses alone, and
  the rods act explicitly and are projected as for symplectic Euler), tens of times slower: it has no compiled
  form.
- **Trees of rigid bodies on hinges and sliders** (a chain of bars, a whip, a cart-pole; no loop, limit, motor or
  contact): **verlet**, **euler** and **midpoint** step their joint coordinates, so the joints hold exactly and a
  step costs O(bodies). On a chain of 20 hinged bars falling from the horizontal (5 s at 1 ms, `--only peers`), the
  energy stays within ±2.8 J of its scale of 37 J under verlet (±4.9 J for verlet in maximal coordinates), ±1.5 J
  under midpoint and ±0.13 J under **symplectic_euler**. That one keeps maximal coordinates and its SHAKE projection
  for this reason; on the angles it would drift by tens of joules, as MuJoCo's Euler does (±72 J).
- **Contact piles** (twelve bodies dropped into a bin): the motion is chaotic from the first impacts. Halving the
  reference's own step moves the pile by a tenth of its size within a second, so no run can be measured closer than
  that, and none differs from the reference by much more: every fixed step, from one per frame to 1 ms, is 9-15 %
  away. A pile is a plausible motion, not a unique one: choose its step for robustness and cost (the ledger reports
  overlaps, missed contacts and energy gains), not for convergence. The adaptive methods crawl from one contact
  event to the next and do not get through the first second (each timed out, or stopped where a hundred events fell
  at one instant, naming the method); symplectic and backward Euler (the same steps without springs) take a third of
  a second at one step per frame and about two at 1 ms, verlet up to twice as long.
- **Emitted particles** (fireworks: three bursts of 2500 sparks under gravity and quadratic drag, no colliders):
  smooth, independent motions, so every method converges at its order, compared spark by spark. RK45 and DOP853
  are within 2·10⁻¹⁰ at any tolerance (RK23 within 2·10⁻⁷), in 0.6-1 s set by a call per frame interval; among the
  fixed steps **verlet** (second order) is the one to use: 3·10⁻⁵ at one step per frame, 5·10⁻⁷ at eight steps a
  frame in 0.23 s, and the compiled pool makes sixteen steps a frame cost less than one in numpy (0.32 s against
  0.41 s: the pools go compiled once their numpy steps would take half a second). Euler and symplectic Euler are
  first order (2·10⁻³ and 6·10⁻³ at a step per frame); midpoint is second order but evaluates twice a step and has
  no compiled pool. With colliders, bounces are found along each step's chord (along each frame's chord for
  adaptive methods): use a fixed step there.
- **Implicit methods on non-stiff scenes** (Radau, BDF on the orbit, the chain): they work, but each step costs
  Jacobians and factorisations that an explicit method does not need; they pay off only when springs are stiff.
"""


LEDGER = """\
## Accuracy on every run: the ledger

A study sweeps every method; a single `render`, `simulate` or `bake` reports its own accuracy too. Its *ledger*
(see [the scene format](scene-format.md#the-accuracy-ledger)) gives the step used, the work of every part, which of
energy, momentum and angular momentum the scene conserves (and why not), and their drift over the run relative to
their scale in the scene. A drift above `solver.drift_warning` (default 1 %) warns, naming what to change; so does
a collision the method missed. `render` writes the quantities at every frame to `quantities.csv` beside
`report.json`, and `--plot` (or `animbatch plot`) draws them.

The two-body orbit over ten orbits (20 s, `--set duration=20`), as the ledger reports it for some settings:

"""

#: The runs of the ledger table: (method, settings as --set would give them).
LEDGER_RUNS = [("euler", ["solver.dt=1.0e-3"]), ("symplectic_euler", ["solver.dt=1.0e-3"]),
               ("verlet", ["solver.dt=1.0e-3"]), ("verlet", ["solver.dt=1.0e-2"]), ("RK45", ["solver.rtol=1.0e-6"]),
               ("DOP853", ["solver.rtol=1.0e-10"])]


def ledger_table(root: Path) -> str:
    """The ledger of the two-body orbit over ten orbits under :data:`LEDGER_RUNS`, as a Markdown table."""
    lines = ["| method | setting | steps | wall time | energy drift | angular momentum drift | warning |",
             "|---|---|---|---|---|---|---|"]
    for method, settings in LEDGER_RUNS:
        scene = stages.load_scene(root / "scenes" / "two_body_orbit.yaml",
                               ["duration=20", f"solver.method={method}", "solver.atol=1.0e-12", *settings])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ledger = stages.simulate(scene, reactions=False).ledger
        work, drift = ledger["work"]["bodies"], ledger["conservation"]
        lines.append(f"| {method} | {settings[0].split('.', 1)[1]} | {work['steps']} | "
                     f"{_seconds(work['wall_time'], False)} | {drift['energy']['drift']:.2g} | "
                     f"{drift['angular_momentum']['drift']:.2g} | {'yes' if ledger['warnings'] else 'no'} |")
    return "\n".join(lines) + "\n"


def _seconds(value: float | None, bound: bool) -> str:
    if value is None:
        return "—"
    return ("≤ " if bound else "") + (f"{value * 1e3:.3g} ms" if value < 1 else f"{value:.3g} s")


def _fastest(result: StudyResult, target: float) -> str:
    reached = [(merit.time_to[target].seconds, merit.method) for merit in result.merits
               if merit.time_to[target].seconds is not None]
    if not reached:
        return f"no method reached {target:g}"
    seconds, method = min(reached)
    return f"**{method}** ({_seconds(seconds, False)})"


def section(name: str, what: str, result: StudyResult, folder: str) -> str:
    """The page's section for one scene: what it is, its reference, its plot and its figures of merit."""
    lines = [f"## {name}", "", f"`scenes/{name}.yaml`: {what}.", "",
             f"Reference: {result.reference}. Length scale {result.length_scale:.3g} m, speed scale "
             f"{result.speed_scale:.3g} m/s; conserved: "
             f"{', '.join(k.replace('_', ' ') for k, v in result.conserved.items() if v) or 'nothing'}.", "",
             f"Fastest to 1e-3: {_fastest(result, 1e-3)}; to 1e-6: {_fastest(result, 1e-6)}.", "",
             f"![work-precision plot of {name}]({folder}/study.png)", "",
             "| method | time to 1e-3 | time to 1e-6 | observed order | failed runs |",
             "|---|---|---|---|---|"]
    for merit in result.merits:
        cells = [_seconds(merit.time_to[t].seconds, merit.time_to[t].bound) for t in TARGETS]
        order = "—" if merit.order is None else f"{merit.order:.2f}"
        lines.append(f"| {merit.method} | {cells[0]} | {cells[1]} | {order} | {merit.failures} |")
    for method, why in result.skipped.items():
        lines.append(f"| {method} | not run: {why} | | | |")
    lines += ["", f"Every run (errors, drifts, work, failures with their reasons): [table]({folder}/study.txt), "
              f"[CSV]({folder}/study.csv), [JSON]({folder}/study.json).", ""]
    return "\n".join(lines)


def page(sections: list[str], seconds: float | None, ledger: str) -> str:
    """The whole page; ``seconds``: what the studies and the ledger took (None: not known for every scene)."""
    took = "" if seconds is None else f" in {seconds:.0f} s"
    header = f"""\
# What accuracy costs in time

<!-- generated by `bash scripts/dev.sh accuracy` (python -m animbatch.study.document); edit
     src/animbatch/study/document.py, not this file -->

`animbatch study scene.yaml` runs a scene with every applicable integrator, adaptive ones over a sweep of
tolerances and fixed-step ones over a sweep of steps, and plots each run's error against its wall time. This page
shows the study of {len(sections)} bundled scenes; regenerate it with `bash scripts/dev.sh accuracy`.

How to read it:

- **error**: the RMS distance of every body (or emitted particle) from the reference over all frames, relative to
  the scene's length scale (what a viewer sees); 1e-3 is "visually exact", 1e-6 "accurate". The reference is the
  closed form where the scene declares `study: {{closed_form: true}}`, a fine fixed-step run where it declares
  `study.reference`, otherwise DOP853 at the tightest tolerance that succeeds, each checked against a second run;
  hollow markers are runs whose error is within twice the reference's own accuracy.
- **time**: the best of several timed runs after an untimed one, with BLAS pinned to one thread, each on what a
  render with that setting runs in a process that has loaded the compiled kernels (as a notebook or a batch worker
  has: the compiled equations of motion from an estimate of 50 ms). "Time to 1e-3" is
  interpolated in log–log between the runs either side of the target and never extrapolated ("≤" marks a bound:
  even the fastest run was more accurate).
- **observed order**: the slope of log error against log dt (fixed steps) or against log steps (adaptive), read
  only where the runs span a factor 3 in work and lie on a line; "—" where the error is not set by the step
  (exact to round-off, limited by the reference, set by a startup step or by chaos).

Measured on {platform.node()} ({os.cpu_count()} CPUs, Python {platform.python_version()}){took}.

"""
    return header + "\n".join(sections) + "\n" + GUIDE + "\n" + ledger


def ledger_section(root: Path) -> str:
    """The page's last section: the ledger and its table."""
    return LEDGER + ledger_table(root)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Regenerate docs/accuracy.md from studies of the bundled scenes.")
    parser.add_argument("--root", type=Path, default=Path(__file__).resolve().parents[3],
                        help="the repository (scenes/ and docs/ inside)")
    parser.add_argument("--timeout", type=float, default=30.0, help="wall-time limit per run [s]")
    parser.add_argument("--repeats", type=int, help="timed repeats per run (default: each scene's study.repeats)")
    parser.add_argument("--only", action="append", choices=list(SCENES), metavar="SCENE",
                        help="study only this scene (repeatable); the others' sections are rebuilt from their "
                             "docs/accuracy/<scene>/study.json")
    parser.add_argument("--page", action="store_true",
                        help="study nothing: rebuild the page (and each scene's table and plot) from the saved "
                             "study.json files, after an edit of the guide")
    args = parser.parse_args(argv)
    if args.page and args.only:
        parser.error("--page studies nothing: drop --only, or --page")
    studied = set() if args.page else set(args.only or SCENES)

    started = time.perf_counter()
    docs = args.root / "docs"
    sections: list[str] = []
    seconds: float | None = 0.0
    for name, what in SCENES.items():
        folder = docs / "accuracy" / name
        if name not in studied:
            saved = folder / "study.json"
            if not saved.is_file():
                parser.error(f"{saved} is missing: study {name} too (drop --only, or add --only {name})")
            result = StudyResult.from_dict(json.loads(saved.read_text()))
            if args.page:
                write_outputs(result, folder)  # the table, CSV and plot as this version writes them
        else:
            overrides = [*OVERRIDES.get(name, []), f"study.timeout={args.timeout}",
                         *([f"study.repeats={args.repeats}"] if args.repeats else [])]
            loaded = stages.load_scene(args.root / "scenes" / f"{name}.yaml", overrides)
            print(f"studying {name} …", file=sys.stderr, flush=True)
            result = run_study(loaded, progress=lambda line: print(f"  {line}", file=sys.stderr, flush=True))
            write_outputs(result, folder)
        seconds = None if seconds is None or result.seconds is None else seconds + result.seconds
        sections.append(section(name, what, result, f"accuracy/{name}"))
    ledger_started = time.perf_counter()
    ledger = ledger_section(args.root)
    if seconds is not None:
        seconds += time.perf_counter() - ledger_started
    write_text_atomic(docs / "accuracy.md", page(sections, seconds, ledger))
    print(f"wrote {docs / 'accuracy.md'} in {time.perf_counter() - started:.0f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
