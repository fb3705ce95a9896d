"""Choose the off-screen OpenGL backend: EGL or OSMesa, never an X server.

VTK (>= 9.4) loads its OpenGL window class at run time, chosen by the ``VTK_DEFAULT_OPENGL_WINDOW`` environment
variable. We check which system libraries can actually be loaded, pick one, and set the variable before the first
render window exists. ``auto`` prefers EGL (it uses a GPU when there is one, and Mesa's llvmpipe otherwise, as fast
as OSMesa) and falls back to OSMesa.
"""

from __future__ import annotations

import ctypes
import os
from dataclasses import dataclass

from animbatch.errors import RenderError


@dataclass(frozen=True)
class Backend:
    name: str
    vtk_window_class: str
    libraries: tuple[tuple[str, ...], ...]  # each inner tuple: alternatives, one of which must load
    install_hint: str


BACKENDS: dict[str, Backend] = {
    "egl": Backend("egl", "vtkEGLRenderWindow",
                   (("libEGL.so.1",), ("libEGL_mesa.so.0", "libEGL_nvidia.so.0")),
                   "apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri"),
    "osmesa": Backend("osmesa", "vtkOSOpenGLRenderWindow", (("libOSMesa.so.8", "libOSMesa.so.6", "libOSMesa.so"),),
                      "apt-get install libosmesa6"),
}
AUTO_ORDER = ("egl", "osmesa")
BACKEND_CHOICES = ("auto", *BACKENDS)

#: What to install when no backend's libraries load (``animbatch doctor`` prints it too).
NO_BACKEND_INSTALL = (
    "no off-screen OpenGL library found, so frames cannot be rendered. Install OSMesa (Debian/Ubuntu: "
    "'apt-get install libosmesa6'; Fedora: 'dnf install mesa-libOSMesa') or EGL with Mesa ('apt-get install libegl1 "
    "libegl-mesa0 libgl1-mesa-dri'). 'bash scripts/dev.sh setup' installs OSMesa when run as root.")
NO_BACKEND_MESSAGE = NO_BACKEND_INSTALL + " 'animbatch doctor' says what this machine has."


def library_loads(library: str) -> bool:
    try:
        ctypes.CDLL(library)
    except OSError:
        return False
    return True


def is_available(backend: Backend) -> bool:
    """True when every library the backend needs can be loaded."""
    return all(any(library_loads(lib) for lib in alternatives) for alternatives in backend.libraries)


def select_backend(requested: str = "auto") -> Backend:
    """The backend to use: the requested one if it is usable, else the first usable one for ``auto``."""
    if requested == "auto":
        for name in AUTO_ORDER:
            if is_available(BACKENDS[name]):
                return BACKENDS[name]
        raise RenderError(NO_BACKEND_MESSAGE)
    if requested not in BACKENDS:
        raise RenderError(f"unknown backend {requested!r}; choose from {', '.join(BACKEND_CHOICES)}")
    backend = BACKENDS[requested]
    if not is_available(backend):
        raise RenderError(f"the {requested} backend needs a library that is not installed: {backend.install_hint}")
    return backend


def activate(backend: Backend) -> None:
    """Make VTK create this backend's render window (must happen before the first window is created)."""
    os.environ["VTK_DEFAULT_OPENGL_WINDOW"] = backend.vtk_window_class
