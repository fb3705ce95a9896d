"""``animbatch watch``: a live preview that re-renders a scene on every save and shows it on a local page.

A small HTTP server (the standard library's, bound to 127.0.0.1 on a free port) serves one page, the videos and a
stream of server-sent events. A watcher (watchfiles) sees every save of the scene or of the files beside it that
it may read (meshes, textures, curves). Each save:

* validates the scene in this process: a scene that does not validate sends every error, with its
  ``file:line:column`` and fix, to the page, which keeps showing the last good video;
* otherwise renders its first seconds (``duration`` capped), or the frames of ``--frames`` (framed as the whole
  scene's render frames them), at draft quality into a fresh folder, in a child process, so that a save during a
  render kills it and starts over: a video is sent to the page only once its encoder has finished (written
  atomically), so nothing half-written is shown.

The page swaps the new video in without reloading. Videos are WebM, which every browser plays.
"""

from __future__ import annotations

import html
import os
import signal
import subprocess
import sys
import tempfile
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

from animbatch.timeline import FrameRange, Timeline

#: Files beside the scene whose saves start a new render: the scene format's own and what it may read.
WATCHED_SUFFIXES = (".yaml", ".yml", ".obj", ".stl", ".ply", ".off", ".glb", ".gltf", ".png", ".jpg", ".jpeg",
                    ".csv", ".json")
#: The longest preview [s] by default: the first seconds are what an edit changes first.
PREVIEW_SECONDS = 3.0
#: Seconds between keep-alive comments on an idle event stream.
KEEP_ALIVE = 10.0


@dataclass
class Broadcast:
    """The newest message for the page (an event name and its text), numbered, and a condition to wait on."""

    version: int = 0
    event: str = "status"
    data: str = "starting"
    videos: dict[str, Path] = field(default_factory=dict)
    changed: threading.Condition = field(default_factory=threading.Condition)

    def send(self, event: str, data: str) -> None:
        with self.changed:
            self.version += 1
            self.event, self.data = event, data
            self.changed.notify_all()

    def publish_video(self, path: Path) -> str:
        """Serve ``path`` under a new name and tell the page; returns the URL path."""
        with self.changed:
            name = f"{len(self.videos) + 1}{path.suffix}"
            self.videos[name] = path
        self.send("video", f"/video/{name}")
        return f"/video/{name}"


PAGE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>animbatch watch: {title}</title>
<style>
body {{ font-family: sans-serif; margin: 1.5em; background: #f4f5f7; color: #222; }}
video {{ max-width: 100%; background: #000; }}
#errors {{ background: #fff0f0; border: 1px solid #d33; padding: 0.8em; white-space: pre-wrap; }}
#status {{ color: #555; }}
</style></head>
<body>
<h1>{title}</h1>
<p id="status">waiting for the first render…</p>
<pre id="errors" hidden></pre>
<video id="video" controls autoplay loop muted playsinline></video>
<script>
const video = document.getElementById("video");
const errors = document.getElementById("errors");
const status = document.getElementById("status");
const events = new EventSource("/events");
events.addEventListener("video", (event) => {{
  video.src = event.data;
  video.play().catch(() => {{}});
  errors.hidden = true;
  errors.textContent = "";
  status.textContent = "rendered " + new Date().toLocaleTimeString();
}});
events.addEventListener("errors", (event) => {{
  errors.textContent = event.data;
  errors.hidden = false;
  status.textContent = "the scene has errors; showing the last good video";
}});
events.addEventListener("status", (event) => {{ status.textContent = event.data; }});
</script>
</body></html>
"""


def make_server(broadcast: Broadcast, title: str, port: int = 0) -> ThreadingHTTPServer:
    """The page's HTTP server on 127.0.0.1 (loopback only: the preview is for this machine), ``port`` 0 for a free
    one."""

    class Handler(BaseHTTPRequestHandler):
        def log_message(self, format: str, *args: Any) -> None:  # quiet: the terminal shows the renders
            pass

        def do_GET(self) -> None:
            if self.path in ("/", "/index.html"):
                self._send(PAGE.format(title=html.escape(title)).encode(), "text/html; charset=utf-8")
            elif self.path == "/events":
                self._stream()
            elif self.path.startswith("/video/") and self.path[len("/video/"):] in broadcast.videos:
                self._send(broadcast.videos[self.path[len("/video/"):]].read_bytes(), "video/webm")
            else:
                self.send_error(404)

        def _send(self, body: bytes, kind: str) -> None:
            self.send_response(200)
            self.send_header("Content-Type", kind)
            self.send_header("Content-Length", str(len(body)))
            self.send_header("Cache-Control", "no-store")
            self.end_headers()
            self.wfile.write(body)

        def _stream(self) -> None:
            self.send_response(200)
            self.send_header("Content-Type", "text/event-stream")
            self.send_header("Cache-Control", "no-store")
            self.end_headers()
            seen = 0
            try:
                while True:
                    with broadcast.changed:
                        broadcast.changed.wait_for(lambda: broadcast.version != seen, timeout=KEEP_ALIVE)
                        version, event, data = broadcast.version, broadcast.event, broadcast.data
                    if version == seen:
                        self.wfile.write(b": still here\n\n")
                    else:
                        seen = version
                        lines = "".join(f"data: {line}\n" for line in data.splitlines() or [""])
                        self.wfile.write(f"event: {event}\n{lines}\n".encode())
                    self.wfile.flush()
            except (BrokenPipeError, ConnectionResetError):
                return

    server = ThreadingHTTPServer(("127.0.0.1", port), Handler)
    server.daemon_threads = True
    return server


class PreviewLoop:
    """Validates and renders the scene each time it is asked to (:meth:`request`), one render at a time: a request
    during a render kills it and starts over."""

    def __init__(self, scene: Path, broadcast: Broadcast, workdir: Path, *, quality: str = "draft",
                 seconds: float = PREVIEW_SECONDS, frames: str | None = None, settings: tuple[str, ...] = (),
                 say: Callable[[str], None] = print) -> None:
        self.scene, self.broadcast, self.workdir = scene, broadcast, workdir
        self.quality, self.seconds, self.frames, self.settings, self.say = quality, seconds, frames, settings, say
        self.wanted = threading.Event()
        self.stopping = threading.Event()
        self.renders = 0

    def request(self) -> None:
        self.wanted.set()

    def stop(self) -> None:
        self.stopping.set()
        self.wanted.set()

    def run(self) -> None:
        """Serve requests until :meth:`stop`."""
        while True:
            self.wanted.wait()
            if self.stopping.is_set():
                return
            self.wanted.clear()
            self._render_once()

    def _render_once(self) -> None:
        from animbatch.errors import SceneError
        from animbatch.stages import load_scene

        try:
            spec = load_scene(self.scene, list(self.settings)).spec
        except SceneError as error:
            self.broadcast.send("errors", str(error))
            self.say(f"{self.scene}: does not validate (the page shows why)")
            return
        try:
            span = Timeline.of(spec.duration, spec.fps).frames(self.frames) if self.frames else None
        except ValueError as error:  # a range the scene does not have
            self.broadcast.send("errors", str(error))
            self.say(f"{self.scene}: {error}")
            return
        self.renders += 1
        out = self.workdir / f"render-{self.renders}"
        if span is None:  # the first seconds, encoded by the render
            duration = min(spec.duration, self.seconds)
            what, outputs = f"the first {duration:g} s", ["--formats", "webm", "--set", f"duration={duration!r}"]
        else:  # the whole scene simulated, so that the camera frames the range as the final render will; the
            # range's frames drawn as PNGs and encoded here
            what, outputs = f"frames {span}", ["--formats", "png", "--frames", str(span)]
        command = [sys.executable, "-m", "animbatch", "render", str(self.scene), "--out", str(out), *outputs,
                   "--quality", self.quality, "--no-progress"]
        for setting in self.settings:
            command += ["--set", setting]
        self.broadcast.send("status", f"rendering {what} at {self.quality} quality…")
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        while process.poll() is None:
            if self.wanted.wait(timeout=0.1):  # saved again: this render is out of date
                process.kill()
                process.wait()
                self._starting_over()
                return
        output = process.stdout.read() if process.stdout is not None else ""
        videos = sorted(out.glob("*/*.webm")) if span is None else self._encode_range(out, span, spec.fps)
        if self.wanted.is_set():  # saved while the range was encoded
            self._starting_over()
            return
        if process.returncode != 0 or not videos:
            self.broadcast.send("errors", output.strip() or f"the render failed (exit {process.returncode})")
            self.say(f"{self.scene}: the render failed (the page shows why)")
            return
        url = self.broadcast.publish_video(videos[0])
        self.say(f"{self.scene}: rendered -> {url}")

    def _starting_over(self) -> None:
        self.say(f"{self.scene}: saved during the render; starting over")

    def _encode_range(self, out: Path, span: FrameRange, fps: int) -> list[Path]:
        """The range's PNG frames (``out/<scene>/frames/``) as one WebM, written atomically; [] when frames are
        missing (the render failed) or a save came in while encoding (the video is dropped)."""
        import imageio.v3 as iio  # reads the PNGs: only when a range is previewed

        from animbatch.encode.video import VideoWriter

        paths = [path for index in span for path in out.glob(f"*/frames/frame_{index:05d}.png")]
        if len(paths) != len(span):
            return []
        first = iio.imread(paths[0])
        target = out / f"frames-{span}.webm"
        with VideoWriter(target, (first.shape[1], first.shape[0]), fps, kind="webm") as video:
            for path in paths:
                if self.wanted.is_set():
                    return []  # leaving the block without commit removes the partial file
                video.write(iio.imread(path)[..., :3])
            video.commit()
        return [target]


def watch(scene: Path, *, quality: str = "draft", seconds: float = PREVIEW_SECONDS, frames: str | None = None,
          port: int = 0, settings: tuple[str, ...] = (), say: Callable[[str], None] = print,
          ready: Callable[[str], None] | None = None, stop: threading.Event | None = None) -> None:
    """Serve the live preview of ``scene`` until interrupted (or ``stop`` is set): the page's URL is printed (and
    given to ``ready``), then every save of the scene or a file beside it re-validates and re-renders it."""
    import watchfiles

    scene = scene.resolve()
    broadcast = Broadcast()
    server = make_server(broadcast, scene.name, port)
    url = f"http://127.0.0.1:{server.server_address[1]}/"
    threading.Thread(target=server.serve_forever, daemon=True).start()
    stop = stop or threading.Event()
    # a terminated watch (kill, a service manager's stop) stops as Ctrl-C does, and its folder of renders goes with
    # it: left to the default, SIGTERM ends the process before any cleanup runs
    main = threading.current_thread() is threading.main_thread()  # (signals are only the main thread's to handle)
    on_terminate = signal.signal(signal.SIGTERM, lambda *_: stop.set()) if main else None
    with tempfile.TemporaryDirectory(prefix=f"animbatch-watch-{os.getpid()}-") as folder:
        loop = PreviewLoop(scene, broadcast, Path(folder), quality=quality, seconds=seconds, frames=frames,
                           settings=settings, say=say)
        worker = threading.Thread(target=loop.run, daemon=True)
        worker.start()
        say(f"watching {scene.name}: open {url} (Ctrl-C to stop)")
        if ready is not None:
            ready(url)
        loop.request()

        def relevant(change: watchfiles.Change, path: str) -> bool:
            return Path(path).suffix.lower() in WATCHED_SUFFIXES and not Path(path).name.startswith(".")

        try:
            for _changes in watchfiles.watch(scene.parent, watch_filter=relevant, stop_event=stop,
                                             raise_interrupt=False):
                loop.request()
        finally:
            loop.stop()
            worker.join(timeout=5)
            server.shutdown()
            server.server_close()
            if main:
                signal.signal(signal.SIGTERM, on_terminate if on_terminate is not None else signal.SIG_DFL)

