"""The gallery in docs/ shows every bundled scene: a scene added without redrawing it fails here, naming the
command that redraws it."""

from __future__ import annotations

from support.paths import REPO


def test_the_gallery_has_a_still_of_every_bundled_scene():
    page = (REPO / "docs" / "gallery.md").read_text(encoding="utf-8")
    missing = [path.stem for path in sorted((REPO / "scenes").glob("*.yaml"))
               if f"(gallery/{path.stem}.jpg)" not in page or not (REPO / "docs" / "gallery" / f"{path.stem}.jpg")
               .is_file()]
    assert not missing, f"not in docs/gallery.md: {', '.join(missing)}; run 'bash scripts/dev.sh gallery {' '.join(missing)}'"
