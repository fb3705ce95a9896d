"""The ``animbatch`` command: argument parsing only; the work is done by :mod:`animbatch.api`.

Exit codes: 0 success, 1 invalid scene or trajectory, 2 bad command-line usage, 3 simulation failed,
4 rendering failed, 130 interrupted.

Each command imports the library inside its function: ``animbatch --help`` and a mistyped option answer without
loading numpy, scipy or pydantic (start-up time is the only reason for imports inside functions in this package).
"""

from __future__ import annotations

import functools
import json
import re
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar, cast

import click

from animbatch.errors import AnimbatchError, SceneError
from animbatch.scene.overrides import Override
from animbatch.version import __version__

if TYPE_CHECKING:
    from animbatch.farm.run import RunReport
    from animbatch.scene import LoadedScene

F = TypeVar("F", bound=Callable[..., Any])


def _reports_errors(command: F) -> F:
    """Print AnimbatchErrors as plain messages (no traceback) and exit with their code."""

    @functools.wraps(command)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return command(*args, **kwargs)
        except SceneError as error:
            click.echo(str(error), err=True)
            sys.exit(error.exit_code)
        except AnimbatchError as error:
            click.echo(f"error: {error}", err=True)
            sys.exit(error.exit_code)
        except KeyboardInterrupt:
            click.echo("interrupted: partial outputs were removed", err=True)
            sys.exit(130)

    return cast(F, wrapper)


def _scene_options(command: F) -> F:
    """--set and the solver shortcuts, shared by every command that reads a scene."""
    options = [
        click.option("--set", "settings", multiple=True, metavar="KEY.PATH=VALUE",
                     help="Override any scene value, e.g. --set bodies[ball].mass=2 (repeatable)."),
        click.option("--method", metavar="NAME", help="Integrator (solver.method), e.g. RK45, DOP853, Radau, verlet."),
        click.option("--dt", metavar="SECONDS", help="Fixed step (solver.dt)."),
        click.option("--rtol", metavar="NUMBER", help="Relative tolerance (solver.rtol)."),
        click.option("--atol", metavar="NUMBER", help="Absolute tolerance (solver.atol)."),
        click.option("--max-step", metavar="SECONDS", help="Largest adaptive step (solver.max_step)."),
        click.option("--fps", metavar="N", help="Frames per second (fps)."),
        click.option("--max-cost", metavar="TIME", help="Wall-time budget of the simulation (solver.max_cost): "
                                                       "seconds, or 30min, 2h; 0 = no limit."),
    ]
    for option in reversed(options):
        command = option(command)
    return command


_TIME_UNITS = {"": 1, "s": 1, "min": 60, "m": 60, "h": 3600, "d": 86400}


def _seconds(text: str) -> str:
    """'90', '90s', '30min', '2h', '1d' -> seconds, as text for the override; anything else is passed on unchanged,
    so that the scene's validation reports it with the key's rules."""
    match = re.fullmatch(r"\s*([0-9.eE+-]+)\s*(s|min|m|h|d|)\s*", text)
    if match is None:
        return text
    try:
        return repr(float(match.group(1)) * _TIME_UNITS[match.group(2)])
    except ValueError:
        return text


def _overrides(settings: tuple[str, ...], **shortcuts: str | None) -> list[Override]:
    """Command-line settings as overrides; shortcuts such as --dt keep their own spelling for error messages."""
    # Values stay text here: they are read as YAML and validated with the scene, like --set.
    keys = {"method": "solver.method", "dt": "solver.dt", "rtol": "solver.rtol", "atol": "solver.atol",
            "max_step": "solver.max_step", "fps": "fps", "max_cost": "solver.max_cost",
            "resolution": "render.resolution", "formats": "render.formats", "quality": "render.quality"}
    result: list[Override] = list(settings)
    for name, value in shortcuts.items():
        if value is None:
            continue
        flag = "--" + name.replace("_", "-")
        if name == "resolution":
            width, _, height = value.lower().partition("x")
            result.append((f"render.resolution=[{width},{height}]", f"{flag} {value}"))
        elif name == "formats":
            result.append((f"render.formats=[{value}]", f"{flag} {value}"))
        elif name == "max_cost":
            result.append((f"{keys[name]}={_seconds(value)}", f"{flag} {value}"))
        else:
            result.append((f"{keys[name]}={value}", f"{flag} {value}"))
    return result


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 110})
@click.version_option(__version__, prog_name="animbatch")
def cli() -> None:
    """Turn YAML scene files into physically based animations, rendered headless.

    \b
    animbatch validate scenes/projectile.yaml
    animbatch info scenes/projectile.yaml
    animbatch render scenes/projectile.yaml            # -> renders/projectile/projectile.mp4
    animbatch simulate scenes/projectile.yaml -o run.npz
    animbatch render scenes/projectile.yaml --trajectory run.npz --resolution 640x360
    animbatch new --list                               # assignment templates
    animbatch grade mine.yaml --reference solution.yaml
    """


@cli.command()
@click.argument("scenes", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--set", "settings", multiple=True, metavar="KEY.PATH=VALUE", help="Override a scene value.")
def validate(scenes: tuple[Path, ...], settings: tuple[str, ...]) -> None:
    """Check scene files; report every error of each file, exit 1 if any is invalid."""
    # the scene loader with the compiler's geometry checks, not the stages: validating loads no solver
    from animbatch.compile.checks import compile_checks
    from animbatch.scene.loader import load_scene
    from animbatch.summary import one_line_summary

    failed = 0
    for path in scenes:
        try:
            click.echo(one_line_summary(load_scene(path, list(settings), geometry_checks=compile_checks)))
        except SceneError as error:
            click.echo(str(error), err=True)
            failed += 1
    if failed:
        if len(scenes) > 1:
            click.echo(f"{failed} of {len(scenes)} scene files are invalid", err=True)
        sys.exit(1)


@cli.command()
@click.argument("videos", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The video to write (mp4).")
@click.option("--gap", default=4, show_default=True, help="Pixels between the videos.")
@_reports_errors
def compose(videos: tuple[Path, ...], output: Path, gap: int) -> None:
    """Put VIDEOS side by side in one video (e.g. a kinematic and a dynamic render of the same scene). They must
    share a frame rate; a shorter one holds its last frame."""
    from animbatch.encode.compose import side_by_side

    click.echo(f"wrote {side_by_side(list(videos), output, gap=gap)}")


@cli.command()
@click.argument("template", required=False)
@click.argument("destination", required=False, type=click.Path(path_type=Path))
@click.option("--list", "listing", is_flag=True, help="List the templates, each with what it teaches.")
@click.option("--force", is_flag=True, help="Replace DESTINATION if it exists.")
@_reports_errors
def new(template: str | None, destination: Path | None, listing: bool, force: bool) -> None:
    """Start an assignment from a template: copy TEMPLATE (see --list) to DESTINATION (a file or folder; default
    ./TEMPLATE.yaml). Its TODO markers say what to change; 'animbatch grade' scores it."""
    from animbatch.teaching.templates import start, templates

    if listing or template is None:
        found = templates()
        width = max(len(t.name) for t in found)
        for item in found:
            click.echo(f"{item.name:<{width}}  {item.description}")
        if template is None and not listing:
            click.echo("\nanimbatch new TEMPLATE [DESTINATION] copies one.", err=True)
        return
    target = start(template, destination, force=force)
    click.echo(f"wrote {target}: edit the lines marked TODO, then 'animbatch render {target}'")


def _not_mapped_count(count: int) -> str:
    return f", {count} element{'' if count == 1 else 's'} not mapped (listed above)" if count else ""


@cli.command(name="import")
@click.argument("model", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path),
              help="The scene to write [default: MODEL's name with .yaml, beside it].")
@click.option("--force", is_flag=True, help="Replace OUTPUT if it exists.")
@_reports_errors
def import_model(model: Path, output: Path | None, force: bool) -> None:
    """Turn an MJCF model (MuJoCo's XML) into a scene: bodies with their geoms as shapes, hinge, slide and ball
    joints with their limits, position and velocity servos as motors, gravity and the time step. What does not map
    is listed, and written at the top of the scene."""
    from animbatch.files import write_text_atomic
    from animbatch.scene.mjcf import import_mjcf
    from animbatch.stages import load_scene

    target = output or model.with_suffix(".yaml")
    if target.exists() and not force:
        raise click.UsageError(f"{target} exists; give --force to replace it, or -o another file")
    imported = import_mjcf(model)
    for line in imported.not_mapped:
        click.echo(f"not mapped: {line}", err=True)
    write_text_atomic(target, imported.text)
    scene = load_scene(target)  # what was written is a valid scene, or this says why
    joints = len(scene.spec.joints)
    click.echo(f"wrote {target}: {len(scene.spec.bodies)} bodies, {joints} joint{'' if joints == 1 else 's'}"
               f"{_not_mapped_count(len(imported.not_mapped))}")


@cli.command()
@click.argument("submission", type=click.Path(path_type=Path), required=False)
@click.option("--reference", "-r", type=click.Path(dir_okay=False, path_type=Path),
              help="The teacher's solved scene (its 'assignment' lists the checks), or a trajectory file (.npz).")
@click.option("--checks", type=click.Path(dir_okay=False, path_type=Path),
              help="A scene whose 'assignment' lists the checks (needed when the reference is a trajectory).")
@click.option("--json", "json_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Also write the result as JSON (Gradescope's results.json shape); '-': to standard output, the "
                   "table then going to standard error.")
@click.option("--junit", "junit_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Also write the result as JUnit XML; '-': to standard output, as --json.")
@click.option("--out", "-o", "out_dir", type=click.Path(path_type=Path),
              help="A class: the folder for class.csv, index.html and each submission's page [default: "
                   "SUBMISSION-grades beside it]. --bundle: the zip to write [default: autograder.zip].")
@click.option("--bundle", "bundle_reference", type=click.Path(dir_okay=False, path_type=Path),
              help="Write a Gradescope autograder (setup.sh, run_autograder) for this reference scene, instead of "
                   "grading.")
@click.option("--workers", type=click.IntRange(min=1), help="A class: grading processes (default: one per core).")
@click.option("--scheduler", help="A class: grade on this Dask scheduler instead of a local cluster.")
@click.option("--reports", is_flag=True, help="A class: also render each checked submission's report page (its video "
                                              "at draft quality, ledger and energy plot), linked from the class page.")
@_reports_errors
def grade(submission: Path | None, reference: Path | None, checks: Path | None, json_path: Path | None,
          junit_path: Path | None, out_dir: Path | None, bundle_reference: Path | None, workers: int | None,
          scheduler: str | None, reports: bool) -> None:
    """Grade SUBMISSION (a scene or trajectory) against the reference: a table of the assignment's checks, each
    with what was compared; exit 0 when every check passes, 1 otherwise, 2 when the grading cannot run.

    SUBMISSION can be a folder: every scene in it (or every folder holding one, as Gradescope exports them) is
    graded in parallel into a class table (class.csv, index.html); a re-run grades only what changed."""
    import warnings as _warnings

    from animbatch.teaching.grade import grade as run_grade
    from animbatch.teaching.grade import summary_line

    if bundle_reference is not None:
        from animbatch.teaching.bundle import write_bundle

        written = write_bundle(bundle_reference, out_dir or Path("autograder.zip"))
        click.echo(f"wrote {written}: upload it as the assignment's autograder on Gradescope (docs/teaching.md)")
        return
    if submission is None or reference is None:
        raise click.UsageError("give a SUBMISSION (a scene, or a folder of them) and --reference REF, or --bundle REF")
    if submission.is_dir():
        if json_path is not None or junit_path is not None:
            raise click.UsageError("--json and --junit are for one submission: a class gets class.csv and each "
                                   "submission's results.json in --out")
        from animbatch.teaching.classroom import class_summary, grade_class

        grades = grade_class(submission, reference, out=out_dir, checks_from=checks, workers=workers,
                             scheduler=scheduler, reports=reports,
                             on_row=lambda row: click.echo(f"  {row.name}: {row.score:g} / {row.max_score:g} "
                                                           f"({row.status})", err=True))
        click.echo(class_summary(grades))
        return

    piped = [path for path in (json_path, junit_path) if str(path) == "-"]
    if len(piped) > 1:
        raise click.UsageError("only one of --json and --junit can go to standard output ('-')")
    with _warnings.catch_warnings():  # accuracy warnings of the two runs are not the student's grade
        _warnings.simplefilter("ignore")
        report = run_grade(submission, reference, checks_from=checks)
    click.echo(report.table(), err=bool(piped))  # with a report on standard output, the table goes beside it
    click.echo(summary_line(report), err=bool(piped))
    click.echo(report.write(json_path, junit_path), nl=False)
    if not report.passed:
        sys.exit(1)


@cli.command()
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@click.option("--no-frames", is_flag=True, help="Check libraries only: draw no test frame, encode no test video.")
@click.option("--kernels", "kernels_only", is_flag=True,
              help="Only build the compiled kernels (or load them from the disk cache), timed.")
def doctor(as_json: bool, no_frames: bool, kernels_only: bool) -> None:
    """Check this machine: Python libraries, off-screen backends (EGL, OSMesa) with a timed test frame each, ffmpeg
    and its encoders, the compiled kernels; print the exact command for anything missing. Exit 1 when frames cannot
    be rendered (with --kernels: when a kernel family fails to build)."""
    from animbatch.doctor import Report, check_kernels, diagnose, format_report

    report = Report(kernels=check_kernels()) if kernels_only else diagnose(probe=not no_frames,
                                                                          encode=not no_frames)
    click.echo(json.dumps(report.as_dict(), indent=2) if as_json else format_report(report))
    if kernels_only:
        if not all(check.ok for check in report.kernels):
            sys.exit(1)
    elif not report.can_render and not no_frames:
        sys.exit(1)


@cli.command()
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), help="Write to a file.")
def schema(output: Path | None) -> None:
    """Print the JSON Schema of the scene format (for editor completion and checks)."""
    from animbatch.scene.schema import SceneSpec

    document = SceneSpec.model_json_schema()
    document["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    document["title"] = "animbatch scene"
    text = json.dumps(document, indent=2) + "\n"
    if output is None:
        click.echo(text, nl=False)
    else:
        from animbatch.files import write_text_atomic

        write_text_atomic(output, text)


@cli.command()
@click.argument("scene", type=click.Path(dir_okay=False, path_type=Path))
@_scene_options
@_reports_errors
def info(scene: Path, settings: tuple[str, ...], **shortcuts: str | None) -> None:
    """Show the compiled model: force terms, state layout, bodies and their masses."""
    from animbatch.info import describe_model
    from animbatch.stages import load_scene, plan

    loaded = load_scene(scene, _overrides(settings, **shortcuts))
    click.echo(describe_model(plan(loaded)))


@cli.command()
@click.argument("scene", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path),
              help="Trajectory file (.npz); default renders/<scene>/<scene>.npz.")
@_scene_options
@click.option("--progress/--no-progress", default=None, help="Progress bar (default: on a terminal).")
@_reports_errors
def simulate(scene: Path, output: Path | None, settings: tuple[str, ...], progress: bool | None,
             **shortcuts: str | None) -> None:
    """Simulate a scene and save its trajectory, sampled at the frame times."""
    from animbatch import api
    from animbatch.progress import Progress

    loaded = api.load_scene(scene, _overrides(settings, **shortcuts))
    trajectory = api.simulate(loaded, progress=Progress(enabled=progress))
    from animbatch.sim.ledger import summary

    target = trajectory.save(output or Path("renders") / loaded.name / f"{loaded.name}.npz")
    seconds = trajectory.solver_stats.get("wall_time", 0.0) + trajectory.particle_stats.get("wall_time", 0.0)
    watches = "".join(f" | {reading.describe()}"
                      for reading in api.stopwatch_readings(loaded.spec.stopwatches, trajectory))
    click.echo(f"{loaded.name}: {trajectory.frame_count} frames -> {target} | {summary(trajectory.ledger)} | "
               f"{seconds:.3f} s{watches}")


@cli.command()
@click.argument("scene", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path),
              help="Folder for study.csv/.json/.png/.txt; default renders/<scene>/.")
@click.option("--methods", metavar="LIST", help="Comma-separated integrators (study.methods; default: all).")
@click.option("--repeats", type=click.IntRange(1, 20), help="Timed repeats per run (study.repeats).")
@click.option("--timeout", type=click.FloatRange(min=0, min_open=True), help="Seconds per run (study.timeout).")
@click.option("--closed-form", is_flag=True, default=None, help="Measure against closed forms (study.closed_form).")
@click.option("--set", "settings", multiple=True, metavar="KEY.PATH=VALUE", help="Override a scene value.")
@_reports_errors
def study(scene: Path, out_dir: Path | None, methods: str | None, repeats: int | None, timeout: float | None,
          closed_form: bool | None, settings: tuple[str, ...]) -> None:
    """What accuracy costs in time: run the scene with every integrator over a sweep of tolerances and steps, and
    report each run's error against a reference next to its wall time (table, CSV, JSON and a log-log plot)."""
    from animbatch import api
    from animbatch.study import run_study, table, write_outputs

    extra = [(f"study.methods=[{methods}]", f"--methods {methods}") if methods else None,
             (f"study.repeats={repeats}", f"--repeats {repeats}") if repeats else None,
             (f"study.timeout={timeout}", f"--timeout {timeout}") if timeout else None,
             ("study.closed_form=true", "--closed-form") if closed_form else None]
    overrides = _overrides(settings) + [item for item in extra if item]
    loaded = api.load_scene(scene, overrides)
    result = run_study(loaded, progress=lambda line: click.echo(line, err=True))
    click.echo(table(result))
    paths = write_outputs(result, out_dir or Path("renders") / loaded.name)
    click.echo(f"\nwrote {', '.join(str(p) for p in paths.values())}")
    failed = [row for row in result.rows if row.status != "ok"]
    if failed:
        click.echo(f"{len(failed)} of {len(result.rows)} runs failed (listed above with their reasons).")


@cli.command()
@click.argument("scene", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--trajectory", type=click.Path(dir_okay=False, path_type=Path),
              help="Render this trajectory (from 'animbatch simulate') instead of simulating.")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), default=Path("renders"),
              show_default=True, help="Output folder; files go to OUT/<scene name>/.")
@click.option("--backend", type=click.Choice(["auto", "egl", "osmesa"]), default="auto", show_default=True,
              help="Off-screen OpenGL backend.")
@click.option("--resolution", metavar="WxH", help="Frame size, e.g. 1920x1080 (render.resolution).")
@click.option("--quality", metavar="PRESET", help="draft, preview or final (render.quality): frame size, "
              "anti-aliasing, tessellation and shadows, where the scene does not set them.")
@click.option("--formats", metavar="LIST", help="Outputs: mp4, webm, gif, png, comma-separated (render.formats).")
@click.option("--frames", metavar="FIRST-LAST", help="Render only these frames (e.g. 120-239) from the cache, and "
              "encode nothing; complete frames are skipped.")
@click.option("--jobs", type=click.IntRange(min=1), help="Render processes drawing PNG frames, encoded after the last "
              "one (default: one process that streams its frames into the encoder as it draws them).")
@click.option("--plot", is_flag=True, help="Also draw the per-frame quantities (energy, momentum, angular momentum, "
              "speeds) to quantities.png beside report.json and quantities.csv.")
@click.option("--camera", metavar="NAME", help="Render through this camera of render.cameras (render.use_camera), "
              "or 'all': render.camera and every named camera, into separate videos <scene>-<camera>.mp4.")
@click.option("--report", "page", type=click.Choice(["html"]), help="html: also write OUT/<scene>/index.html, a page "
              "with the video, a poster frame, the ledger and the energy plot (implies --plot).")
@_scene_options
@click.option("--progress/--no-progress", default=None, help="Progress bars (default: on a terminal or in a notebook).")
@_reports_errors
def render(scene: Path, trajectory: Path | None, out_dir: Path, backend: str, settings: tuple[str, ...],
           progress: bool | None, frames: str | None, jobs: int | None, plot: bool, camera: str | None,
           page: str | None, **shortcuts: str | None) -> None:
    """Bake (or reuse the cached simulation), render the frames off-screen and encode the videos into
    renders/<scene>/, streaming each frame into the encoder as it is drawn (or drawn in parallel with --jobs).
    Frames already complete on disk are not drawn again."""
    render_scene(scene, trajectory=trajectory, out_dir=out_dir, backend=backend, settings=settings,
                 progress=progress, frames=frames, jobs=jobs, plot=plot, camera=camera, page=page, **shortcuts)


def render_scene(scene: Path | LoadedScene, *, trajectory: Path | None, out_dir: Path, backend: str,
                 settings: tuple[str, ...], progress: bool | None, frames: str | None, jobs: int | None, plot: bool,
                 camera: str | None, page: str | None, **shortcuts: str | None) -> list[RunReport]:
    """What ``animbatch render`` does with its options (parsed by click), for a scene file or a scene loaded
    already (the ``%%animbatch`` cell magic's): one run per camera asked for, each summary printed, then the page.
    Returns the reports, in camera order."""
    from animbatch import api
    from animbatch.progress import Progress

    overrides = _overrides(settings, **shortcuts)
    cameras: list[str | None] = [camera]
    if camera == "all":  # the simulation is baked once; each camera then reuses it from the cache
        cameras = [None, *api.load(scene, overrides).spec.render.cameras]
    reports = []
    for name in cameras:
        chosen = overrides + ([(f"render.use_camera={name}", f"--camera {name}")] if name is not None else [])
        try:
            report = api.run(scene, overrides=chosen, out_dir=out_dir, backend=backend, trajectory=trajectory,
                             progress=Progress(enabled=progress), jobs=jobs, frames=frames, plot=plot or bool(page))
        except ValueError as error:  # a --frames range the scene does not have
            raise click.BadParameter(str(error), param_hint="--frames") from None
        click.echo(report.summary())
        reports.append((name, report))
    if page and frames is None:  # one page for all the cameras rendered
        from animbatch.farm.page import run_page

        click.echo(f"{reports[0][1].scene}: page -> {run_page(reports, out_dir / reports[0][1].scene)}")
    return [report for _, report in reports]


@cli.command()
@click.argument("scene", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--quality", type=click.Choice(["draft", "preview"]), default="draft", show_default=True,
              help="Render quality of the preview (render.quality).")
@click.option("--seconds", type=click.FloatRange(min=0, min_open=True), default=3.0, show_default=True,
              help="Preview the first this many seconds of the scene (all of it when shorter).")
@click.option("--frames", metavar="FIRST-LAST", help="Preview these frames instead (e.g. 90-150, as render's "
              "--frames), framed as in the whole scene's render.")
@click.option("--port", type=click.IntRange(min=0, max=65535), default=0, show_default=True,
              help="Port on 127.0.0.1 (0: a free one).")
@click.option("--set", "settings", multiple=True, metavar="KEY.PATH=VALUE",
              help="Override any scene value, as for render.")
@_reports_errors
def watch(scene: Path, quality: str, seconds: float, frames: str | None, port: int,
          settings: tuple[str, ...]) -> None:
    """Serve a live preview of SCENE on a local page (127.0.0.1, the address is printed): every save of the scene
    or of a file beside it re-validates it and re-renders its first seconds (or --frames); a scene that does not
    validate shows its errors there, with the last good video kept."""
    from animbatch.watch import watch as serve

    serve(scene, quality=quality, seconds=seconds, frames=frames, port=port, settings=settings, say=click.echo)


def _reads_a_run(verb: str) -> Callable[[F], F]:
    """The arguments of a command that reads a run (see :func:`_run_of`): the scene, --trajectory, --out, the scene
    options and --progress."""
    decorators = [
        click.argument("scene", type=click.Path(dir_okay=False, path_type=Path)),
        click.option("--trajectory", type=click.Path(dir_okay=False, path_type=Path),
                     help=f"{verb} this trajectory (from 'animbatch simulate') instead of the scene's bake."),
        click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), default=Path("renders"),
                     show_default=True, help="Output folder; files go to OUT/<scene name>/."),
        _scene_options,
        click.option("--progress/--no-progress", default=None,
                     help="Progress bar while simulating (default: on a terminal)."),
    ]

    def decorate(function: F) -> F:
        for decorator in reversed(decorators):
            function = decorator(function)
        return function

    return decorate


def _run_of(plan: Any, trajectory: Path | None, out_dir: Path, progress: bool | None) -> Any:
    """The run a command reads: the trajectory file given (checked against the scene), or the scene's bake (reused
    from its cache, or simulated first)."""
    from animbatch import api
    from animbatch.farm import bake as bake_scene
    from animbatch.progress import Progress
    from animbatch.sim.ledger import summary
    from animbatch.trajectory import Trajectory

    if trajectory is not None:
        run = Trajectory.load(trajectory)
        api.check_trajectory(plan.scene, plan.model, run, trajectory)
        return run
    baked = bake_scene(plan, out_dir=out_dir, progress=Progress(enabled=progress))
    # the wait before the command's own output is the simulation's: say so, or that the cache spared it
    how = "read from the cache" if baked.reused else f"simulated in {baked.seconds:.2f} s"
    click.echo(f"{plan.name}: trajectory {how} -> {baked.path} | {summary(baked.trajectory.ledger)}")
    return baked.trajectory


@cli.command()
@_reads_a_run("Plot")
@_reports_errors
def plot(scene: Path, trajectory: Path | None, out_dir: Path, settings: tuple[str, ...], progress: bool | None,
         **shortcuts: str | None) -> None:
    """Draw the run's energy (kinetic, potential, total), momentum, angular momentum and each body's speed against
    time into OUT/<scene>/quantities.png, with the numbers in quantities.csv. Uses --trajectory, or the scene's bake
    (simulating it first when there is none)."""
    from animbatch import api
    from animbatch.sim.ledger import summary

    loaded = api.load_scene(scene, _overrides(settings, **shortcuts))
    plan = api.plan(loaded)
    model = plan.model
    if not model.body_count:
        raise click.UsageError(f"{scene} has no bodies to plot (emitted particles carry no energy or momentum "
                               "series)")
    run = _run_of(plan, trajectory, out_dir, progress)
    written = api.write_quantities(loaded, model, run, out_dir / loaded.name, plot=True)
    click.echo(f"{loaded.name}: {', '.join(map(str, written))} | {summary(run.ledger)}")


@cli.command()
@_reads_a_run("Export")
@click.option("--format", "kinds", type=click.Choice(["usd", "ply", "obj", "csv"]), multiple=True, default=("usd",),
              show_default=True,
              help="usd: <scene>.usdc, a USD stage for Blender and Houdini (bodies, cloth, particles, camera, "
                   "lights); ply, obj: ply/ or obj/<name>.<frame>, each cloth, lattice and emitter per frame; csv: "
                   "transforms.csv, every body's position and orientation. Repeat for several.")
@_reports_errors
def export(scene: Path, trajectory: Path | None, kinds: tuple[str, ...], out_dir: Path, settings: tuple[str, ...],
           progress: bool | None, **shortcuts: str | None) -> None:
    """Export the run for other tools into OUT/<scene>/ (see docs/export.md). Uses --trajectory, or the scene's
    bake (simulating it first when there is none). SCENE may be a trajectory file itself for --format csv, which
    needs nothing else."""
    from animbatch import api, stages
    from animbatch.export import export as export_run
    from animbatch.trajectory import Trajectory

    geometry = render = None
    fps = 30.0
    if scene.suffix == ".npz":  # a trajectory alone holds every body's motion, not the shapes, looks or camera
        drawn = sorted(set(kinds) - {"csv"})
        if drawn:
            raise click.UsageError(f"--format {', '.join(drawn)} needs the scene file too (shapes, colours, cloth "
                                   f"triangles, camera): animbatch export SCENE.yaml --trajectory {scene} "
                                   f"--format {drawn[0]}. A trajectory alone exports --format csv.")
        ignored = (["--trajectory"] if trajectory else []) + (["--set"] if settings else []) + \
            [f"--{key.replace('_', '-')}" for key, value in shortcuts.items() if value is not None]
        if ignored:  # the run is what the file holds: nothing would change it
            raise click.UsageError(f"{', '.join(ignored)} cannot change a trajectory file exported as it is; give "
                                   "the scene file to bake it with other settings")
        run = Trajectory.load(scene)
        name = run.scene_name
    else:
        loaded = api.load_scene(scene, _overrides(settings, **shortcuts))
        plan = api.plan(loaded)
        run = _run_of(plan, trajectory, out_dir, progress)
        name, render, fps = loaded.name, loaded.spec.render, loaded.spec.fps
        geometry = stages.frame_geometry(plan, run) if set(kinds) - {"csv"} else None
    for kind in dict.fromkeys(kinds):
        started = time.perf_counter()
        written = export_run(run, out_dir / name, kind, geometry, render, fps)
        if not written:
            click.echo(f"{name}: {kind}: nothing to write ({kind} files hold cloth, lattices and emitted particles, "
                       "and this scene has none; its bodies are in --format usd or csv)")
            continue
        where = str(written[0]) if len(written) == 1 else f"{len(written)} files in {written[0].parent}"
        click.echo(f"{name}: {kind}, {run.frame_count} frames in {time.perf_counter() - started:.2f} s -> {where}")


@cli.command()
@click.argument("scene", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), default=Path("renders"),
              show_default=True, help="Output folder; the cache goes to OUT/<scene name>/cache/.")
@click.option("--force", is_flag=True, help="Simulate even when a matching cache exists.")
@click.option("--checkpoint-every", type=click.IntRange(min=1), metavar="N",
              help="Save the states every N frames; an interrupted bake resumes from the last checkpoint.")
@_scene_options
@click.option("--progress/--no-progress", default=None, help="Progress bar (default: on a terminal).")
@_reports_errors
def bake(scene: Path, out_dir: Path, force: bool, checkpoint_every: int | None, settings: tuple[str, ...],
         progress: bool | None, **shortcuts: str | None) -> None:
    """Simulate the scene into its trajectory cache (keyed by physics, solver settings and package version), or
    say that the cache is already up to date."""
    from animbatch import api
    from animbatch.farm import bake as bake_scene
    from animbatch.farm.frame_files import prepare_frames
    from animbatch.progress import Progress

    loaded = api.load_scene(scene, _overrides(settings, **shortcuts))
    result = bake_scene(loaded, out_dir=out_dir, progress=Progress(enabled=progress), force=force,
                        checkpoint_every=checkpoint_every)
    prepare_frames(loaded, result.trajectory, out_dir)  # before any render task: frames of another picture go
    from animbatch.sim.ledger import summary

    what = "up to date" if result.reused else f"baked in {result.seconds:.2f} s"
    click.echo(f"{loaded.name}: {result.trajectory.frame_count} frames, cache {what} -> {result.path} | "
               f"{summary(result.trajectory.ledger)}")


@cli.command()
@click.argument("scene", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), default=Path("renders"),
              show_default=True, help="Output folder (frames are read from OUT/<scene name>/frames/).")
@click.option("--formats", metavar="LIST", help="Videos: mp4, webm, gif, comma-separated (default: the scene's).")
@click.option("--resolution", metavar="WxH", help="Frame size the frames were rendered at, as given to render "
              "(render.resolution).")
@click.option("--quality", metavar="PRESET", help="The quality preset the frames were rendered with, as given to "
              "render (render.quality): it decides their size where the scene does not.")
@click.option("--set", "settings", multiple=True, metavar="KEY.PATH=VALUE", help="Override a scene value.")
@_reports_errors
def encode(scene: Path, out_dir: Path, formats: str | None, resolution: str | None, quality: str | None,
           settings: tuple[str, ...]) -> None:
    """Encode the rendered frames into videos (every frame must be complete, at the size the scene and these
    options give: the error lists missing ones, and says so when the frames on disk have another size)."""
    from animbatch import api
    from animbatch.farm.encode import encode as encode_frames

    loaded = api.load_scene(scene, _overrides(settings, formats=formats, resolution=resolution, quality=quality))
    kinds = tuple(kind for kind in loaded.spec.render.formats if kind != "png")
    if not kinds:
        raise click.BadParameter("no video format chosen (png frames are already on disk)", param_hint="--formats")
    frame_count = loaded.spec.frame_count
    # the options that decide the frames, for the render command the error suggests
    options = ([f"--resolution {resolution}"] if resolution else []) + ([f"--quality {quality}"] if quality else []) \
        + [f"--set {setting}" for setting in settings]
    result = encode_frames(loaded, frame_count, out_dir=out_dir, kinds=kinds, render_options=" ".join(options))
    click.echo(f"{loaded.name}: {result.frame_count} frames -> {', '.join(map(str, result.outputs))} "
               f"({result.seconds:.2f} s)")


@cli.command()
@click.argument("scenes", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), default=Path("renders"),
              show_default=True, help="Output folder; each scene goes to OUT/<scene name>/.")
@click.option("--workers", type=click.IntRange(min=1), help="Worker processes of the local Dask cluster (default: "
              "one per core).")
@click.option("--scheduler", metavar="ADDRESS", help="Use an existing Dask cluster (tcp://host:8786) instead.")
@click.option("--chunk-size", type=click.IntRange(min=1), default=48, show_default=True,
              help="Frames per render task.")
@click.option("--backend", type=click.Choice(["auto", "egl", "osmesa"]), default="auto", show_default=True)
@click.option("--resolution", metavar="WxH", help="Frame size of every scene, e.g. 640x360 (render.resolution).")
@click.option("--quality", metavar="PRESET", help="draft, preview or final for every scene (render.quality), as "
              "render takes it.")
@click.option("--formats", metavar="LIST", help="Outputs of every scene: mp4, webm, gif, png (render.formats).")
@click.option("--set", "settings", multiple=True, metavar="KEY.PATH=VALUE", help="Override a value in every scene.")
@click.option("--sweep", "sweeps", multiple=True, metavar="KEY.PATH=V1,V2,…", help="Render one variant per value "
              "(repeat for every combination of several keys); one scene only. Writes sweep.csv and "
              "contact-sheet.png into OUT/<scene>-sweep/.")
@click.option("--report", "page", type=click.Choice(["html", "none"]), default="html", show_default=True,
              help="html: write index.html (OUT/, or OUT/<scene>-sweep/ for a sweep): every run's video, poster, "
                   "ledger and energy plot, and a sweep's table sortable by each column.")
@_reports_errors
def batch(scenes: tuple[Path, ...], out_dir: Path, workers: int | None, scheduler: str | None, chunk_size: int,
          backend: str, settings: tuple[str, ...], sweeps: tuple[str, ...], page: str,
          **frame_options: str | None) -> None:
    """Render many scenes on Dask: each is baked, rendered in chunks in parallel, then encoded. Every job runs to
    its end; a summary table follows, and the exit code is 1 if any job failed. --resolution, --quality and
    --formats apply to every scene, as render's do."""
    from animbatch.farm import batch as farm_batch
    from animbatch.farm.sweep import finish_sweep, plan_batch

    try:
        plan = plan_batch(scenes, _overrides(settings, **frame_options), sweeps, out_dir)
    except ValueError as error:
        raise click.BadParameter(str(error), param_hint="--sweep") from None
    results = farm_batch.run_batch(plan.jobs, out_dir=out_dir, workers=workers, scheduler=scheduler,
                                   chunk_size=chunk_size, backend=backend, plot=page == "html",
                                   on_result=lambda r: click.echo(f"{r.label}: {r.status}", err=True))
    click.echo(farm_batch.summary(results))
    if plan.sweep_folder is not None:
        written = finish_sweep(plan, results)
        click.echo(f"sweep: {', '.join(str(path) for path in written)}")
    if page == "html":
        from animbatch.farm.page import batch_page

        click.echo(f"page: {batch_page(plan, results, out_dir)}")
    if any(result.status != "ok" for result in results):
        sys.exit(1)


@cli.group()
def farm() -> None:
    """Job scripts for farm managers, for sites without Dask."""


def _farm_job_options(function: Callable[..., Any]) -> Callable[..., Any]:
    """The options every farm job writer takes: the scene, the shared output folder, the chunk size and --set."""
    for option in reversed([
            click.argument("scene", type=click.Path(dir_okay=False, path_type=Path)),
            click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path),
                         default=Path("renders"), show_default=True,
                         help="Output folder the jobs write to (must be shared by the nodes)."),
            click.option("--chunk-size", type=click.IntRange(min=1), default=48, show_default=True,
                         help="Frames per render task."),
            click.option("--set", "settings", multiple=True, metavar="KEY.PATH=VALUE",
                         help="Override a scene value.")]):
        function = option(function)
    return function


def _scene_frames(scene: Path, settings: tuple[str, ...]) -> tuple[Any, int]:
    """The loaded scene and its number of frames."""
    from animbatch import api

    loaded = api.load_scene(scene, list(settings))
    return loaded, loaded.spec.frame_count


@farm.command("slurm")
@_farm_job_options
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), help="Script file (default: "
              "renders/<scene>/submit-slurm.sh).")
@click.option("--sbatch-option", "options", multiple=True, metavar="OPTION",
              help="Passed to every sbatch call, e.g. --sbatch-option=--partition=short (repeatable).")
@_reports_errors
def farm_slurm(scene: Path, output: Path | None, out_dir: Path, chunk_size: int, options: tuple[str, ...],
               settings: tuple[str, ...]) -> None:
    """Write a script that submits the scene as a SLURM bake job, an array of render jobs (afterok) and an encode
    job (afterok)."""
    from animbatch.farm.slurm import slurm_script
    from animbatch.files import write_text_atomic

    loaded, frames = _scene_frames(scene, settings)
    target = output or out_dir / loaded.name / "submit-slurm.sh"
    write_text_atomic(target, slurm_script(scene, frames=frames, name=loaded.name, out_dir=out_dir, chunk=chunk_size,
                                           overrides=settings, options=options, script=str(target)))
    target.chmod(0o755)
    click.echo(f"{loaded.name}: {frames} frames in {-(-frames // chunk_size)} render tasks -> {target}; "
               f"submit with: bash {target}")


@farm.command("openjd")
@_farm_job_options
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), help="Template file (default: "
              "renders/<scene>/openjd-job.yaml).")
@_reports_errors
def farm_openjd(scene: Path, output: Path | None, out_dir: Path, chunk_size: int, settings: tuple[str, ...]) -> None:
    """Write an Open Job Description job template (Bake -> Render tasks of frame chunks -> Encode), for render
    managers that take OpenJD, such as AWS Deadline Cloud."""
    from animbatch.farm.openjd import openjd_template, openjd_yaml
    from animbatch.files import write_text_atomic

    loaded, frames = _scene_frames(scene, settings)
    target = output or out_dir / loaded.name / "openjd-job.yaml"
    write_text_atomic(target, openjd_yaml(openjd_template(scene, frames=frames, name=loaded.name, out_dir=out_dir,
                                                          chunk=chunk_size, overrides=settings)))
    click.echo(f"{loaded.name}: {frames} frames in {-(-frames // chunk_size)} render tasks -> {target}; "
               f"check with: openjd check {target}")


def _show_warning(message: Warning | str, category: type[Warning], *args: Any, **kwargs: Any) -> None:
    """Our own warnings as one plain line on stderr (others as Python formats them)."""
    from animbatch.errors import AnimbatchWarning

    if issubclass(category, AnimbatchWarning):
        click.echo(f"warning: {message}", err=True)
    else:
        _python_showwarning(message, category, *args, **kwargs)


_python_showwarning = warnings.showwarning


def main() -> None:
    warnings.showwarning = _show_warning
    from animbatch.sim import kernels  # light: numba itself loads only when a kernel is used

    kernels.announce = lambda message: click.echo(f"note: {message}", err=True)
    cli(prog_name="animbatch")


if __name__ == "__main__":
    main()
