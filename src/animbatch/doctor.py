"""``animbatch doctor``: what this machine can do, measured, and the exact command for what it lacks.

Off-screen rendering fails in ways that are hard to read from a traceback (a missing ``libEGL``, a VTK build that
still wants an X server, an ffmpeg without x264), and it is the first thing a new machine, a render node or a CI
runner gets wrong. The doctor checks, in order:

* the Python libraries animbatch imports, with their versions;
* each off-screen OpenGL backend (EGL, OSMesa): whether its system libraries load, and, when they do, a real test
  frame drawn with it, timed (first frame, which builds the scene's actors and compiles shaders, and the steady
  frames after it) and checked by its pixels (the test ball must be on it);
* ffmpeg (the binary imageio-ffmpeg ships) and the encoders of each video format, with a short test encode each;
* the compiled kernels (numba): each family built, or loaded from its disk cache, and timed. The first build on a
  machine compiles (about a minute in all); ``bash scripts/dev.sh test`` does it once before the tests, so that test
  processes do not each compile them.

Each backend draws in a process of its own: VTK picks its window class once per process, and EGL and OSMesa both
provide OpenGL symbols that must not meet in one process.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from animbatch.render import backend as backends
from animbatch.render.backend import AUTO_ORDER, BACKENDS, NO_BACKEND_INSTALL

#: The Python libraries animbatch needs: import name, distribution name, and what it is for.
LIBRARIES = (
    ("numpy", "numpy", "arrays"),
    ("scipy", "scipy", "integrators, sparse solves"),
    ("pydantic", "pydantic", "the scene format"),
    ("yaml", "pyyaml", "scene files"),
    ("vtk", "vtk", "drawing (>= 9.4 picks EGL or OSMesa at run time)"),
    ("pyvista", "pyvista", "drawing"),
    ("imageio_ffmpeg", "imageio-ffmpeg", "the ffmpeg binary"),
    ("PIL", "pillow", "PNG frames"),
    ("trimesh", "trimesh", "mesh files"),
    ("matplotlib", "matplotlib", "plots, study"),
    ("distributed", "distributed", "batch on Dask"),
    ("tqdm", "tqdm", "progress bars"),
)
#: Libraries some commands use when present.
OPTIONAL_LIBRARIES = (
    ("numba", "numba", "compiled kernels (without it the numpy code runs everything, the same but slower)"),
    ("pxr", "usd-core", "animbatch export --format usd, the default export (install: the 'usd' extra)"),
    ("openjd.model", "openjd-model", "checking OpenJD job templates (farm.md)"),
)
#: Browsers the report page's test opens it in (headless); the pages themselves open in any browser.
BROWSERS = ("chromium", "chromium-browser")

#: The test frame: a red ball over the ground, small enough to draw in well under a second in software.
PROBE_SCENE = """\
name: doctor
duration: 0.1
fps: 30
bodies:
  - {name: ball, radius: 0.5, position: [0, 0.5, 0], color: "#ff0000"}
render:
  resolution: [320, 240]
  ground: {level: 0}
"""
PROBE_FRAMES = 5
#: Video formats and the ffmpeg encoder each needs (see :mod:`animbatch.encode.video`).
ENCODERS = {"mp4": "libx264", "webm": "libvpx-vp9", "gif": "gif"}


@dataclass
class Check:
    """One line of the report: what was checked, whether it is usable, the details, and how to fix it."""

    name: str
    ok: bool
    detail: str
    fix: str = ""
    required: bool = True


@dataclass
class Report:
    libraries: list[Check] = field(default_factory=list)
    backends: list[Check] = field(default_factory=list)
    video: list[Check] = field(default_factory=list)
    probed: bool = True  # test frames were drawn (else only the backends' libraries were looked for)
    kernels: list[Check] = field(default_factory=list)

    @property
    def checks(self) -> list[Check]:
        return [*self.libraries, *self.backends, *self.video, *self.kernels]

    @property
    def can_render(self) -> bool:
        """At least one backend drew its test frame, and MP4 can be encoded."""
        mp4 = next((check for check in self.video if check.name == "mp4"), None)
        return any(check.ok for check in self.backends) and mp4 is not None and mp4.ok

    def as_dict(self) -> dict[str, Any]:
        return {"libraries": [asdict(c) for c in self.libraries], "backends": [asdict(c) for c in self.backends],
                "video": [asdict(c) for c in self.video], "kernels": [asdict(c) for c in self.kernels],
                "can_render": self.can_render, "probed": self.probed}


def check_libraries() -> list[Check]:
    """Each library: importable, and its version."""
    checks = []
    for module, distribution, purpose in (*LIBRARIES, *OPTIONAL_LIBRARIES):
        required = (module, distribution, purpose) in LIBRARIES
        try:
            importlib.import_module(module)
        except ImportError as error:
            fix = (f"{sys.executable} -m pip install {distribution}" if not required else
                   "bash scripts/dev.sh setup (or: pip install -e .)")
            checks.append(Check(distribution, False, f"missing ({error}); needed for {purpose}", fix, required))
            continue
        try:
            version = importlib.metadata.version(distribution)
        except importlib.metadata.PackageNotFoundError:
            version = "unknown version"
        checks.append(Check(distribution, True, f"{version} ({purpose})", required=required))
    browser = next((found for name in BROWSERS if (found := shutil.which(name))), None)
    checks.append(Check("chromium", True, f"{browser} (the report page's browser test)", required=False)
                  if browser else
                  Check("chromium", False, "not found; the report page's browser test is skipped without it",
                        "apt-get install chromium (bash scripts/dev.sh test installs it as root)", required=False))
    return checks


def found_library(alternatives: tuple[str, ...]) -> str | None:
    """The first of ``alternatives`` that loads, or None."""
    return next((library for library in alternatives if backends.library_loads(library)), None)


def check_backends(probe: bool = True) -> list[Check]:
    """Each off-screen backend: its libraries, and a timed test frame in a process of its own."""
    checks = []
    for name in AUTO_ORDER:
        backend = BACKENDS[name]
        if not backends.is_available(backend):
            missing = [" or ".join(alternatives) for alternatives in backend.libraries
                       if not found_library(alternatives)]
            checks.append(Check(name, False, f"not available: {', '.join(missing)} cannot be loaded",
                                backend.install_hint, required=False))
            continue
        libraries = ", ".join(str(found_library(alternatives)) for alternatives in backend.libraries)
        if not probe:
            checks.append(Check(name, True, f"libraries load ({libraries}); no test frame drawn", required=False))
            continue
        checks.append(_probe_check(name, libraries))
    return checks


def _probe_check(name: str, libraries: str) -> Check:
    with tempfile.TemporaryDirectory(prefix="animbatch-doctor-") as folder:
        image = Path(folder) / f"{name}.png"
        try:
            done = subprocess.run([sys.executable, "-m", "animbatch.doctor", "probe", name, str(image)],
                                  capture_output=True, text=True, timeout=300,
                                  env={**os.environ, "PYTHONWARNINGS": "ignore"})
        except subprocess.TimeoutExpired:
            return Check(name, False, "the test frame took more than 300 s", BACKENDS[name].install_hint, False)
        if done.returncode != 0 or not done.stdout.strip():
            reason = (done.stderr.strip().splitlines() or ["no output"])[-1]
            return Check(name, False, f"libraries load ({libraries}) but the test frame failed: {reason}",
                         BACKENDS[name].install_hint, required=False)
        timing = json.loads(done.stdout.strip().splitlines()[-1])
        seen = ball_pixels(image)
    if seen == 0:
        return Check(name, False, f"libraries load ({libraries}) but the test frame is blank (no ball on it)",
                     BACKENDS[name].install_hint, required=False)
    return Check(name, True, f"test frame {timing['width']}×{timing['height']}: first {timing['first']:.2f} s, "
                             f"then {1e3 * timing['steady']:.1f} ms per frame ({timing['window']}, {libraries})",
                 required=False)


def ball_pixels(image: Path) -> int:
    """How many pixels of the test frame are the ball's red (the check that something was really drawn)."""
    from PIL import Image

    pixels = np.asarray(Image.open(image).convert("RGB")).astype(int)
    red = (pixels[..., 0] > 120) & (pixels[..., 1] < 0.5 * pixels[..., 0]) & (pixels[..., 2] < 0.5 * pixels[..., 0])
    return int(red.sum())


def probe(backend_name: str, image: Path) -> dict[str, Any]:
    """Draw the test scene with one backend (in this process), save its last frame to ``image``, and time it."""
    from animbatch import stages
    from animbatch.render.backend import select_backend
    from animbatch.render.renderer import FrameRenderer

    scene = stages.parse_scene(PROBE_SCENE, filename="<doctor>")
    run = stages.plan(scene)
    trajectory = stages.simulate(run)
    geometry = stages.frame_geometry(run, trajectory)
    backend = select_backend(backend_name)
    started = time.perf_counter()
    with FrameRenderer(scene.spec.render, geometry, backend) as renderer:
        times = []
        for k in range(PROBE_FRAMES):
            index = min(k, trajectory.frame_count - 1)
            image_array = renderer.draw(float(trajectory.times[index]), trajectory.positions[index],
                                        trajectory.orientations[index], trajectory.angular_velocities[index])
            times.append(time.perf_counter() - started)
        window = renderer.plotter.ren_win.GetClassName()
    from PIL import Image

    Image.fromarray(image_array).save(image)
    width, height = scene.spec.render.resolution
    return {"first": times[0], "steady": (times[-1] - times[0]) / (len(times) - 1), "window": window,
            "width": width, "height": height}


def check_video(encode: bool = True) -> list[Check]:
    """ffmpeg, its encoders for mp4, webm and gif, and a short test encode of each."""
    try:
        import imageio_ffmpeg  # finds the ffmpeg binary: only when checking it

        binary = imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError) as error:
        return [Check("ffmpeg", False, f"not found ({error})", f"{sys.executable} -m pip install imageio-ffmpeg")]
    listing = subprocess.run([binary, "-hide_banner", "-encoders"], capture_output=True, text=True, timeout=60)
    version = subprocess.run([binary, "-version"], capture_output=True, text=True, timeout=60).stdout
    version = version.split("\n")[0].split(" Copyright")[0]
    checks = [Check("ffmpeg", True, f"{binary} ({version})")]
    encoders = {line.split()[1] for line in listing.stdout.splitlines() if len(line.split()) > 1}
    for kind, encoder in ENCODERS.items():
        if encoder not in encoders:
            checks.append(Check(kind, False, f"ffmpeg has no {encoder} encoder",
                                f"{sys.executable} -m pip install --force-reinstall imageio-ffmpeg (its ffmpeg has "
                                f"{encoder})", required=kind == "mp4"))
            continue
        checks.append(_test_encode(kind, encoder) if encode else Check(kind, True, encoder, required=kind == "mp4"))
    return checks


def _test_encode(kind: str, encoder: str) -> Check:
    from animbatch.encode.video import VideoWriter

    frames = [np.full((120, 160, 3), 40 * k, np.uint8) for k in range(6)]
    with tempfile.TemporaryDirectory(prefix="animbatch-doctor-") as folder:
        started = time.perf_counter()
        try:
            with VideoWriter(Path(folder) / f"test.{kind}", (160, 120), 30, kind=kind) as writer:
                for frame in frames:
                    writer.write(frame)
                path = writer.commit()
        except Exception as error:  # any failure of the encoder is what we report
            return Check(kind, False, f"{encoder} failed a test encode: {error}",
                         f"{sys.executable} -m pip install --force-reinstall imageio-ffmpeg", required=kind == "mp4")
        seconds = time.perf_counter() - started
        size = path.stat().st_size
    return Check(kind, True, f"{encoder}: 6 frames 160×120 in {seconds:.2f} s ({size} bytes)", required=kind == "mp4")


def check_kernels() -> list[Check]:
    """Each family of compiled kernels built (compiled, or loaded from numba's disk cache), timed; none where numba
    does not load or ``ANIMBATCH_KERNELS=numpy`` (numpy then runs everything, with the same results)."""
    from animbatch.sim.contact.impulses import build_contact_kernels
    from animbatch.sim.forces.springs import build_spring_kernel
    from animbatch.sim.integrators.linear_algebra import build_step_kernels
    from animbatch.sim.kernels import compiled_kernels, kernel_cache_folder
    from animbatch.sim.model.compiled import build_stepper_kernels
    from animbatch.sim.particles.compiled import build_particle_kernels

    if not compiled_kernels():
        return [Check("numba", False, "not used (ANIMBATCH_KERNELS=numpy, or numba does not load): numpy runs "
                                      "everything, with the same results, slower", f"{sys.executable} -m pip install "
                                      "numba", required=False)]
    checks = []
    for name, build in (("bodies, joints", build_stepper_kernels), ("contact solver", build_contact_kernels),
                        ("spring forces", build_spring_kernel), ("cloth steps", build_step_kernels),
                        ("particles", build_particle_kernels)):
        started = time.perf_counter()
        failure = build()
        seconds = time.perf_counter() - started
        checks.append(Check(name, failure is None, f"ready in {seconds:.1f} s" if failure is None else failure,
                            "numpy runs these instead (same results, slower)", required=False))
    checks.append(Check("cache", True, str(kernel_cache_folder()), required=False))
    return checks


def diagnose(probe: bool = True, encode: bool = True, kernels: bool = True) -> Report:
    return Report(check_libraries(), check_backends(probe), check_video(encode), probed=probe,
                  kernels=check_kernels() if kernels else [])


def format_report(report: Report) -> str:
    """The report as text: a section per kind, a mark per line, then every fix to apply."""
    lines = []
    for title, checks in (("Python libraries", report.libraries), ("Off-screen rendering", report.backends),
                          ("Video encoding", report.video), ("Compiled kernels", report.kernels)):
        if not checks:
            continue
        lines.append(title)
        for check in checks:
            mark = "ok " if check.ok else ("-- " if not check.required else "!! ")
            lines.append(f"  {mark}{check.name:<15} {check.detail}")
    fixes = [check for check in report.checks if not check.ok and check.fix]
    if not report.backends:  # the kernels alone (--kernels)
        pass
    elif not any(check.ok for check in report.backends):
        lines += ["", f"Cannot render: {NO_BACKEND_INSTALL}"]
    elif report.can_render:
        chosen = next(check.name for check in report.backends if check.ok)
        ready = (f"Ready: frames render with {chosen} (--backend auto picks it) and encode to MP4." if report.probed
                 else f"The libraries of {chosen} load; 'animbatch doctor' without --no-frames draws a test frame.")
        lines += ["", ready]
    if fixes:
        lines += ["", "To fix:" if not report.can_render else "Optional, for what is marked '--' or '!!':"]
        lines += [f"  {check.name}: {check.fix}" for check in fixes]
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    """``python -m animbatch.doctor probe BACKEND IMAGE``: the test frame, in a process of its own."""
    if len(argv) == 3 and argv[0] == "probe":
        print(json.dumps(probe(argv[1], Path(argv[2]))))
        return 0
    print("usage: python -m animbatch.doctor probe BACKEND IMAGE (use 'animbatch doctor')", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
