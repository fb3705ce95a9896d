"""A run shows itself in a notebook: its video, its accuracy ledger and its energy plot, embedded in one HTML output
(what Jupyter displays for the RunReport that ``animbatch.api.run`` returns)."""

from __future__ import annotations

import base64
import re

import pytest

from animbatch import api
from support.paths import REPO

pytestmark = pytest.mark.render


def test_a_run_displays_its_video_ledger_and_energy_plot_embedded(tmp_path):
    report = api.run(REPO / "scenes" / "projectile.yaml", out_dir=tmp_path, plot=True,
                     overrides=["render.resolution=[320, 180]", "duration=0.5"])
    page = report._repr_html_()
    video = re.search(r'<video[^>]* src="data:video/mp4;base64,([^"]+)"', page)
    assert video is not None
    assert base64.b64decode(video.group(1)) == (tmp_path / "projectile" / "projectile.mp4").read_bytes()
    image = re.search(r'<img[^>]* src="data:image/png;base64,([^"]+)"', page)
    assert image is not None
    assert base64.b64decode(image.group(1)) == (tmp_path / "projectile" / "quantities.png").read_bytes()
    # the ledger: the method, and energy conserved (gravity alone) with its drift; momentum not, and why
    assert "<th>method</th><td colspan=2>RK45 (adaptive)" in page
    assert re.search(r"<th>energy</th><td>conserved: all forces derive from potentials: gravity</td><td>drift "
                     r"[0-9.e+-]+ % of [0-9.]+ J</td>", page)
    assert "<th>momentum</th><td>not conserved: gravity is an external force</td>" in page
    assert report.summary().split(" | ")[0].replace(">", "&gt;") in page
