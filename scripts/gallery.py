"""Regenerate the gallery (``docs/gallery.md`` and ``docs/gallery/*.jpg``): one still of every bundled scene at
``final`` quality, so that a reader sees what animbatch draws before installing it.

    bash scripts/dev.sh gallery            # every scene (several minutes: each is simulated to its still)
    bash scripts/dev.sh gallery projectile # only these

Each still is the frame at 60 % of the scene's duration, 960×540, rendered by the library exactly as
``animbatch render --quality final`` draws it (simulated only as far as that frame).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from PIL import Image

from animbatch import api, stages
from animbatch.files import write_text_atomic
from animbatch.render.backend import select_backend
from animbatch.render.renderer import FrameRenderer

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "scenes"
PAGE = ROOT / "docs" / "gallery.md"
IMAGES = ROOT / "docs" / "gallery"
SIZE = (960, 540)
AT = 0.6  # of the duration


def still_frame(path: Path) -> tuple[int, float, str]:
    """Which frame of a scene is its still, the time it shows [s], and the scene's description."""
    spec = stages.load_scene(path).spec
    frame = max(0, round(AT * spec.duration * spec.fps) - 1)
    return frame, frame / spec.fps, spec.description or ""


def still(path: Path) -> Image.Image:
    """The scene's still."""
    loaded = stages.load_scene(path)
    frame, _, _ = still_frame(path)
    scene = stages.load_scene(path, ["render.quality=final", f"render.resolution=[{SIZE[0]}, {SIZE[1]}]",
                                     f"duration={(frame + 1) / loaded.spec.fps!r}"])
    model = api.compile_model(scene)
    trajectory = api.simulate(scene, model=model)
    geometry = stages.frame_geometry(stages.plan(scene, model=model), trajectory)
    frame = min(frame, trajectory.frame_count - 1)
    with FrameRenderer(scene.spec.render, geometry, select_backend()) as renderer:
        image = renderer.draw(float(trajectory.times[frame]), trajectory.positions[frame],
                              trajectory.orientations[frame], trajectory.angular_velocities[frame],
                              (trajectory.particles, frame))
    return Image.fromarray(image)


def page(entries: list[tuple[str, str, float]]) -> str:
    lines = ["# Gallery", "",
             "One still of every scene in `scenes/`, drawn at `--quality final` (here 960×540) by "
             "`bash scripts/dev.sh gallery`, which regenerates this page. Render any of them with "
             "`animbatch render scenes/NAME.yaml`.", ""]
    for name, description, t in entries:
        lines += [f"## `{name}.yaml`", "", f"{description} (t = {t:.2f} s)" if description else f"t = {t:.2f} s",
                  "", f"![{name}](gallery/{name}.jpg)", ""]
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="*", help="only these scenes (file names without .yaml)")
    args = parser.parse_args()
    paths = sorted(SCENES.glob("*.yaml"))
    IMAGES.mkdir(parents=True, exist_ok=True)
    entries = []
    for path in paths:
        name = path.stem
        target = IMAGES / f"{name}.jpg"
        _, t, description = still_frame(path)
        entries.append((name, description, t))
        if args.names and name not in args.names:
            continue
        started = time.perf_counter()
        partial = target.with_suffix(".partial.jpg")
        still(path).save(partial, quality=88, optimize=True)
        partial.replace(target)
        print(f"{name}: {time.perf_counter() - started:.1f} s -> {target.relative_to(ROOT)}", flush=True)
    write_text_atomic(PAGE, page(entries))
    print(f"wrote {PAGE.relative_to(ROOT)} ({len(entries)} scenes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
