"""A whole render in this process, streamed: every frame goes to the video encoders as it is drawn.

This is ``animbatch render`` on one machine (without ``--jobs`` or ``--frames``): no PNG is written and read back
unless ``png`` is one of the formats, and ffmpeg encodes while the next frames are drawn, so the run ends shortly
after the last frame instead of one encoding pass later. The farm path (frame ranges, worker processes, ``animbatch
encode``) keeps its PNG frames, which are what lets a task be re-run: a streamed render that is interrupted leaves
no video and starts again from the first frame.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from animbatch.compile.plan import RunPlan
from animbatch.encode.images import PngSequenceWriter
from animbatch.encode.stream import FrameStream
from animbatch.encode.video import VideoWriter
from animbatch.farm.frame_files import RangeResult, draw_into, frames_folder, output_stem, prepare_frames
from animbatch.scene import LoadedScene
from animbatch.trajectory import Trajectory


@dataclass
class StreamResult:
    """What a streamed render drew and wrote: the frames, the outputs (videos, and the frames folder with
    ``png``), and the seconds ffmpeg took to finish after the last frame."""

    frames: RangeResult
    outputs: list[Path]
    encode_seconds: float


def stream_frames(run: RunPlan, trajectory: Trajectory, *, out_dir: str | Path, backend: str = "auto",
                  on_frame: Callable[[int], None] | None = None) -> StreamResult:
    """Draw every frame of ``trajectory`` (already checked against the run's scene) into the scene's videos, and
    into ``out_dir/<scene>/frames/`` when ``png`` is one of its formats; ``on_frame(index)`` once each is written."""
    scene, spec = run.scene, run.spec
    folder = Path(out_dir) / scene.name
    width, height = spec.render.resolution
    size = (width, height)
    video = spec.render.video
    videos = [VideoWriter(folder / f"{output_stem(scene)}.{kind}", size, spec.fps,
                          preset=video.preset, crf=video.crf, kind=kind)
              for kind in spec.render.formats if kind != "png"]
    png = PngSequenceWriter(prepare_frames(scene, trajectory, out_dir)) if "png" in spec.render.formats else None
    result = RangeResult()
    with FrameStream(videos, png) as stream:
        draw_into(stream, run, trajectory, list(range(trajectory.frame_count)), backend=backend, result=result,
                  on_frame=on_frame, queued=frames_queued(size))
        outputs, seconds = stream.commit()
    if png is not None:
        png.remove_beyond(trajectory.frame_count)
        outputs.append(png.folder)
    else:  # frames of an earlier render of this scene, now superseded by the videos
        shutil.rmtree(frames_folder(scene, out_dir), ignore_errors=True)
    return StreamResult(result, outputs, seconds)


#: Frames waiting for the encoders may take this much memory [bytes]: enough for the low-priority ffmpeg to fall
#: behind while a frame is drawn and catch up in the gaps, without holding up the renderer.
QUEUE_BYTES = 64 * 2**20


def frames_queued(size: tuple[int, ...]) -> int:
    """How many frames of ``size`` (width, height) may wait for the encoders: 2 to 16, within QUEUE_BYTES."""
    width, height = size
    return max(2, min(16, QUEUE_BYTES // (3 * width * height)))


def resumable_frames(scene: LoadedScene, trajectory: Trajectory, out_dir: str | Path) -> bool:
    """Whether frames of this very picture are on disk (an interrupted farm or ``--jobs`` render): then the render
    goes on from them, through PNG frames, rather than streaming from the first frame."""
    folder = frames_folder(scene, out_dir)
    if not any(folder.glob("frame_*.png")):
        return False
    prepare_frames(scene, trajectory, out_dir)  # deletes frames of another picture
    return any(folder.glob("frame_*.png"))
