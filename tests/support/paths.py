"""Where things are in the repository, whatever folder a test module sits in."""

from __future__ import annotations

from pathlib import Path

#: The repository's root folder.
REPO = Path(__file__).resolve().parents[2]
#: The bundled scenes.
SCENES = REPO / "scenes"
