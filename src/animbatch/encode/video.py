"""Video output: MP4 (H.264 in yuv420p, plays in browsers), and WebM (VP9) or GIF on request, encoded by ffmpeg
while frames are still being rendered (or read back from PNGs).

Frames are piped to an ffmpeg process (the binary shipped with imageio-ffmpeg), which encodes in parallel with the
renderer, at the lowest CPU priority so that it takes only what drawing leaves idle. The file is written under a
temporary name and renamed only when ffmpeg has finished, so an interrupted run never leaves a truncated MP4 under
the final name. Frames are passed at their size (the schema requires even sizes, which yuv420p needs), never
resized to multiples of 16.

x264 presets, measured at 720p on a 2-core machine: ``veryfast`` about 140–200 fps, ``medium`` about 26–80 fps; the
default ``veryfast`` keeps the encoder ahead of the renderer.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import tempfile
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from animbatch.errors import RenderError
from animbatch.files import partial_path

#: How much lower than the renderer ffmpeg runs (the ``nice`` value added to its priority).
ENCODER_NICENESS = 19

#: Video kinds: ffmpeg codec, output pixel format, and extra options (``{preset}``/``{crf}`` filled in).
VIDEO_KINDS: dict[str, tuple[str, str, list[str]]] = {
    "mp4": ("libx264", "yuv420p", ["-preset", "{preset}", "-crf", "{crf}", "-movflags", "+faststart"]),
    # constant quality VP9; "good" with cpu-used 4 is several times faster than the default
    "webm": ("libvpx-vp9", "yuv420p", ["-b:v", "0", "-crf", "32", "-deadline", "good", "-cpu-used", "4"]),
    # one pass: ffmpeg buffers the frames, builds a palette from all of them, then maps every frame to it
    "gif": ("gif", "pal8", ["-vf", "split[a][b];[a]palettegen[p];[b][p]paletteuse", "-loop", "0"]),
}


class VideoWriter:
    """Streams RGB frames (H, W, 3) uint8 into a video of ``kind`` mp4, webm or gif. Use as a context manager;
    ``commit`` makes it final."""

    def __init__(self, path: str | Path, size: tuple[int, int], fps: float, *, preset: str = "veryfast",
                 crf: int = 20, kind: str = "mp4") -> None:
        if kind not in VIDEO_KINDS:
            raise ValueError(f"unknown video kind {kind!r}; choose from {', '.join(VIDEO_KINDS)}")
        self.path = Path(path)
        self.size = size  # (width, height) [px]
        self.fps = fps
        self.preset = preset
        self.crf = crf
        self.kind = kind
        self.frames_written = 0
        self._temporary = partial_path(self.path)
        self._process: subprocess.Popen[bytes] | None = None
        self._log: Any = None

    def open(self) -> VideoWriter:
        import imageio_ffmpeg  # finds the ffmpeg binary: only when encoding

        self.path.parent.mkdir(parents=True, exist_ok=True)
        codec, pixels, options = VIDEO_KINDS[self.kind]
        width, height = self.size
        command = [imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-v", "error", "-f", "rawvideo", "-vcodec", "rawvideo",
                   "-s", f"{width}x{height}", "-pix_fmt", "rgb24", "-r", str(Fraction(self.fps).limit_denominator()),
                   "-i", "-", "-an", "-vcodec", codec, "-pix_fmt", pixels,
                   *[option.format(preset=self.preset, crf=self.crf) for option in options],
                   "-f", self.kind, str(self._temporary)]
        self._log = tempfile.TemporaryFile()  # ffmpeg's messages, read when it fails (a pipe could fill and block)
        try:
            self._process = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                             stderr=self._log)
        except OSError as error:
            self._log.close()
            raise RenderError(f"could not start ffmpeg ({command[0]}): {error}") from None
        with contextlib.suppress(OSError):
            # the encoder yields the cores to the renderer drawing the next frames, and catches up in the gaps
            # (llvmpipe's threads wait for the slowest one, so taking a core from it costs the whole frame)
            os.setpriority(os.PRIO_PROCESS, self._process.pid, ENCODER_NICENESS)
        return self

    def write(self, image: np.ndarray) -> None:
        if self._process is None:
            raise RuntimeError("VideoWriter.open() was not called")
        height, width = image.shape[:2]
        if (width, height) != self.size:
            raise RenderError(f"frame size {width}×{height} differs from the video size {self.size[0]}×{self.size[1]}")
        pipe = self._process.stdin
        assert pipe is not None  # opened with stdin=PIPE
        try:
            pipe.write(np.ascontiguousarray(image, dtype=np.uint8).data)
        except (OSError, ValueError):
            raise RenderError(f"ffmpeg stopped while encoding {self.path}: {self._messages()}") from None
        self.frames_written += 1

    def _messages(self) -> str:
        """What ffmpeg wrote to its error stream (its last lines), after it ended."""
        process = self._process
        if process is not None:
            with contextlib.suppress(Exception):
                process.wait(timeout=10)
        self._log.seek(0)
        lines = self._log.read().decode(errors="replace").strip().splitlines()
        return " / ".join(lines[-5:]) or f"exit code {process.returncode if process else '?'}"

    def _close(self) -> int:
        """Close ffmpeg's input and wait for it to finish; returns its exit code."""
        process = self._process
        assert process is not None
        with contextlib.suppress(OSError):
            if process.stdin is not None:
                process.stdin.close()
        return process.wait()

    def commit(self) -> Path:
        """Finish encoding and move the video to its final name."""
        try:
            if self._close() != 0:
                raise RenderError(f"ffmpeg failed to finish {self.path}: {self._messages()}")
        finally:
            self._process = None
            self._log.close()
        self._temporary.replace(self.path)
        return self.path

    def abort(self) -> None:
        """Stop ffmpeg and delete the partial file."""
        if self._process is not None:
            with contextlib.suppress(Exception):
                self._process.kill()
                self._close()
            self._process = None
            self._log.close()
        with contextlib.suppress(FileNotFoundError):
            self._temporary.unlink()

    def __enter__(self) -> VideoWriter:
        return self.open()

    def __exit__(self, kind: object, error: object, traceback: object) -> None:
        if kind is not None or self._process is not None:
            self.abort()  # an exception, or a writer left open without commit()


Mp4Writer = VideoWriter  # the default kind is mp4


def middle_frame(video: Path) -> np.ndarray:
    """The middle frame (H, W, 3) uint8 RGB of a video file (a poster, a contact sheet's tile). The frames are
    counted first and only the middle one is kept: a long 1080p video decoded into memory would take gigabytes."""
    import imageio_ffmpeg  # finds the ffmpeg binary: only when reading videos

    count, _ = imageio_ffmpeg.count_frames_and_secs(str(video))
    reader = imageio_ffmpeg.read_frames(str(video), pix_fmt="rgb24")
    width, height = next(reader)["size"]
    frame = None
    for index, frame in enumerate(reader):
        if index == count // 2:
            reader.close()
            break
    if frame is None:
        raise RenderError(f"{video}: no frames to read")
    return np.frombuffer(frame, np.uint8).reshape(height, width, 3)
