"""Self-collision of cloth: the velocity filter against the geometry and mechanics it must keep (no crossing along
the step, momentum kept, Coulomb friction), and whole runs whose cloth folds, meets a pole or another cloth, with
the frames searched for crossing triangle pairs."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import api
from animbatch.errors import SceneError
from animbatch.sim.deformable.intersections import crossing_pairs
from animbatch.sim.deformable.topology import grid, unique_edges
from animbatch.sim.kernels import self_contact
from support.scenes import scene

pytestmark = pytest.mark.filterwarnings("ignore::animbatch.errors.AccuracyWarning")


def _filter(x, v, w, triangles, thickness=0.01, friction=0.0, h=0.01, cell=0.05):
    n = len(x)
    v = np.array(v, float)
    stats = self_contact.filter_velocities(np.asarray(x, float), v, np.asarray(w, float), np.full(n, thickness),
                                           np.full(n, friction), np.asarray(triangles, np.int64),
                                           unique_edges(np.asarray(triangles)).astype(np.int64), h, cell)
    return v, dict(zip(self_contact.STATS, stats))


def _sheets(gap: float, speed: float, resolution: int = 8):
    """Two 0.3 m sheets, ``gap`` [m] apart along z at their centres (the second one shifted by a fraction of a cell
    and tilted by a slope of 0.1 along y, so that passing through each other makes crossing pairs), closing at
    ``speed`` [m/s] each."""
    sheet = grid((0.3, 0.3), (resolution, resolution))
    lower = sheet.vertices.copy()
    upper = sheet.vertices + np.array([0.013, 0.007, gap])
    upper[:, 2] += 0.1 * sheet.vertices[:, 1]
    x = np.vstack([lower, upper])
    v = np.vstack([np.tile([0, 0, speed], (len(lower), 1)), np.tile([0, 0, -speed], (len(upper), 1))])
    triangles = np.vstack([sheet.triangles, sheet.triangles + len(lower)])
    return x, v, triangles


@pytest.mark.parametrize("speed", [0.5, 5.0, 50.0])
def test_two_sheets_thrown_at_each_other_never_cross_along_the_step_and_keep_their_momentum(speed):
    """Sheets 2 cm apart closing at 2 × speed: at 50 m/s they would pass 1 m through each other in the step. After
    the filter no point of the straight drift crosses (checked at 50 instants), the sheets' momentum is unchanged
    (the impulses are pairwise, and impact zones keep it), and the sheets no longer close on each other."""
    x, v, triangles = _sheets(0.02, speed)
    h = 0.01
    instants = np.linspace(0.02, 1.0, 50)
    crossed = [len(crossing_pairs(x + tau * h * v, triangles)) for tau in instants]
    assert max(crossed) > 0 or speed < 1.0  # what the filter prevents
    w = np.ones(len(x)) / 0.002
    after, stats = _filter(x, v, w, triangles, h=h)
    assert stats["unresolved"] == 0
    for tau in instants:
        assert len(crossing_pairs(x + tau * h * after, triangles)) == 0, tau
    assert np.allclose(after.sum(axis=0), v.sum(axis=0), atol=1e-9 * speed * len(x))
    lower, upper = after[: len(x) // 2, 2].mean(), after[len(x) // 2:, 2].mean()
    assert upper >= lower - 1e-9 * speed or speed < 1.0  # where they met, the upper sheet no longer closes on the lower


def test_a_vertex_thrown_at_a_held_triangle_stops_on_its_side_and_the_triangle_does_not_move():
    """A free vertex at 20 m/s, 3 cm above a triangle whose corners are held (inverse mass 0): the step would carry
    it 17 cm through. It leaves on its own side, at the separating speed the filter gives (a twentieth of the
    thickness per step), and the triangle's corners keep their velocities."""
    x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.2, 0.3, 0.03]], float)
    v = np.array([[0, 0, 0]] * 3 + [[0, 0, -20.0]], float)
    h, thickness = 0.01, 0.01
    after, stats = _filter(x, v, [0, 0, 0, 1.0], [[0, 1, 2]], thickness=thickness, h=h, cell=0.2)
    assert stats["collisions"] >= 1
    assert np.all(after[:3] == 0)
    assert after[3, 2] == pytest.approx(self_contact.SEPARATE * thickness / h, rel=1e-9)
    assert x[3, 2] + h * after[3, 2] > 0


def test_coulomb_friction_takes_mu_times_the_normal_change_off_the_sliding_speed():
    """A vertex 4 mm above a held triangle (within the 1 cm thickness), sinking at 1 m/s and sliding at 3 m/s: the
    repulsion changes its normal velocity by Δv_n (to a tenth of the missing thickness per step), and friction
    takes μ Δv_n off its sliding speed, in the sliding direction only."""
    x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.2, 0.3, 0.004]], float)
    v = np.array([[0, 0, 0]] * 3 + [[3.0, 0, -1.0]], float)
    h, thickness, mu = 0.01, 0.01, 0.3
    after, _ = _filter(x, v, [0, 0, 0, 1.0], [[0, 1, 2]], thickness=thickness, friction=mu, h=h, cell=0.2)
    target = self_contact.RESTORE * (thickness - 0.004) / h
    change = target - (-1.0)
    assert after[3, 2] == pytest.approx(target, rel=1e-9)
    assert after[3, 0] == pytest.approx(3.0 - mu * change, rel=1e-9) and after[3, 1] == 0


def test_a_sheet_at_rest_far_from_itself_is_left_exactly_alone():
    """A flat sheet moving as one (no pair closer than its thickness, none closing): every velocity is unchanged."""
    sheet = grid((1.0, 1.0), (24, 24))
    v = np.tile([0.3, -2.0, 0.1], (len(sheet.vertices), 1))
    thickness = 0.5 * 1.0 / 23  # half an edge: the default, twice the vertex radius
    after, stats = _filter(sheet.vertices, v, np.ones(len(v)), sheet.triangles, thickness=thickness, cell=1 / 23)
    assert np.array_equal(after, v) and stats["repelled"] == stats["collisions"] == 0


HEADER = """
duration: {duration}
fps: 30
solver: {{method: backward_euler, dt: {dt}}}
materials:
  cotton: {{restitution: 0.0, static_friction: 0.5, kinetic_friction: 0.4}}
bodies:
"""
POLE_SHEET = """
  - name: sheet
    type: cloth
    grid: {{size: [1.0, 1.0], resolution: [{n}, {n}]}}
    position: [0, 1.0, 0.2]
    velocity: [0, 0, -2]
    density: 0.15
    structural: {{stiffness: 300, damping: 0.05}}
    shear: {{stiffness: 60, damping: 0.01}}
    bend: {{stiffness: 0.2, damping: 0.001}}
    material: cotton
    self_collision: {on}
colliders:
  - {{type: box, position: [0, 1.0, 0], size: [0.08, 2.0, 0.08], material: wood}}
"""


def _pole(n: int, on: bool, duration: float = 0.6):
    return api.simulate(scene(HEADER.format(duration=duration, dt=0.002) + POLE_SHEET.format(n=n, on=str(on).lower())))


def test_a_sheet_thrown_at_a_pole_wraps_it_and_its_halves_meet_behind_it_without_crossing():
    """A sheet thrown at 2 m/s at a post 8 cm wide wraps around it; its two halves swing round and meet behind it.
    Without self-collision they pass through each other (the frames' search finds crossing pairs); with it, no
    frame has a crossing pair, and the halves stay on their own sides: the sheet's vertices right of the post's
    plane x = 0 at the start are still there at the end."""
    loose = _pole(24, False)
    assert loose.ledger["surfaces"] is not None and loose.ledger["surfaces"]["pairs"] > 0
    held = _pole(24, True)
    assert held.ledger.get("surfaces") is None
    folding = held.ledger["work"]["bodies"]["self_collision"]
    assert folding["collisions"] + folding["repelled"] > 0 and folding["unresolved"] == 0
    x = held.positions  # (F, P, 3)
    right = x[0, :, 0] > 0.05
    behind = x[-1, :, 2] < -0.04  # the part that came round the post
    assert behind.any()
    assert np.all(x[-1, right & behind, 0] > 0) and np.all(x[-1, ~right & behind & (x[0, :, 0] < -0.05), 0] < 0)


LAYERS = """
  - name: under
    type: cloth
    grid: {size: [0.6, 0.6], resolution: [12, 12]}
    position: [0, 0.02, 0]
    orientation: {axis: [1, 0, 0], angle: -90}
    density: 0.15
    structural: {stiffness: 300, damping: 0.05}
    material: cotton
  - name: over
    type: cloth
    grid: {size: [0.3, 0.3], resolution: [7, 7]}
    position: [0.01, 0.25, 0.02]
    orientation: {axis: [1, 0, 0], angle: -90}
    density: 0.15
    structural: {stiffness: 300, damping: 0.05}
    material: cotton
colliders:
  - {type: plane, point: [0, 0, 0], normal: [0, 1, 0], material: wood}
fields:
  - {type: gravity}
"""


def test_a_towel_dropped_on_another_rests_on_it_one_thickness_up():
    """A small towel dropped on a larger one lying on the floor comes to rest on it, one thickness above it (each
    towel's default is half its edge; a pair of them keeps the larger, half the under towel's 5.45 cm edge), less
    what gravity takes in the steps before the repulsion answers (of order g h² = 0.17 mm at h = 1/240 s)."""
    h = 1 / 240
    trajectory = api.simulate(scene(HEADER.format(duration=1.0, dt=h) + LAYERS))
    assert trajectory.ledger.get("surfaces") is None
    x = trajectory.positions[-1]
    names = trajectory.body_names
    under = np.array([name.startswith("under[") for name in names])
    over = np.array([name.startswith("over[") for name in names])
    floor_height = x[under, 1].mean()
    spacing_under, spacing_over = 0.6 / 11, 0.3 / 6
    thickness = max(0.5 * spacing_under, 0.5 * spacing_over)
    rise = x[over, 1].mean() - floor_height
    assert thickness - 20 * 9.81 * h * h <= rise <= thickness + 1e-3
    # the towels meet through their surfaces, not through their vertex spheres: the overlap audit finds nothing
    assert all(entry is None for entry in (trajectory.ledger.get("contacts") or {}).values())


def test_self_collision_asked_of_a_method_that_cannot_apply_it_is_refused_at_its_key():
    """RK45 has no step between forces and move to filter: asking it for self-collision is a scene error at the
    body's key, naming the methods that can; left unset, the cloth simply runs without it."""
    text = (HEADER.format(duration=0.1, dt=0.002) + POLE_SHEET.format(n=6, on="true")).replace(
        "{method: backward_euler, dt: 0.002}", "{method: RK45}")
    with pytest.raises(SceneError) as caught:
        api.load(scene(text))
    message = str(caught.value)
    assert "bodies[0].self_collision" in message and "backward_euler" in message
    api.load(scene(text.replace("    self_collision: true\n", "")))


def test_a_spread_out_sheet_is_a_height_field_and_a_folded_or_coiled_one_is_not():
    """The shortcut that skips the search must only take sheets that cannot meet themselves: a rippling sheet is a
    height field; one folded over (normals turned round) is not; nor is a strip coiled one and a tenth turns up a
    ramp, whose normals all face up but whose border, seen from above, crosses itself."""
    from animbatch.sim.deformable.self_collision import height_field
    from animbatch.sim.deformable.topology import open_edges

    sheet = grid((1.0, 1.0), (24, 24))
    border = open_edges(sheet.triangles)
    rippled = sheet.vertices + np.stack([0 * sheet.vertices[:, 0], 0 * sheet.vertices[:, 0],
                                         0.05 * np.sin(6 * sheet.vertices[:, 0])], axis=1)
    assert height_field(rippled, sheet.triangles, border)
    folded = sheet.vertices.copy()
    over = folded[:, 0] > 0.2  # folded back over x = 0.2, 1 cm above
    folded[over, 0], folded[over, 2] = 0.4 - folded[over, 0], 0.01
    assert not height_field(folded, sheet.triangles, border)
    strip = grid((1.0, 0.1), (60, 4))
    angle = (strip.vertices[:, 0] + 0.5) * 2.2 * np.pi
    radius = 0.3 + strip.vertices[:, 1]
    coiled = np.stack([radius * np.cos(angle), radius * np.sin(angle), 0.02 * angle], axis=1)
    assert not height_field(coiled, strip.triangles, open_edges(strip.triangles))
    assert height_field(strip.vertices, strip.triangles, open_edges(strip.triangles))


def test_the_counters_are_named_as_the_kernel_returns_them():
    """The constraint names the kernel's counters without importing numba at start-up: the two lists agree."""
    from animbatch.sim.contact.self_collision_step import COUNTERS

    assert COUNTERS == self_contact.STATS


def test_without_compiled_kernels_self_collision_is_off_and_a_warning_says_so(monkeypatch):
    """ANIMBATCH_KERNELS=numpy: the cloth runs without self-collision (it would take seconds a step in Python), and
    the run says so, naming the cloth; the crossing audit still reports a pass-through."""
    monkeypatch.setenv("ANIMBATCH_KERNELS", "numpy")
    with pytest.warns(RuntimeWarning, match="self-collision of 'sheet' needs its compiled kernels"):
        trajectory = api.simulate(scene(HEADER.format(duration=0.1, dt=0.002) + POLE_SHEET.format(n=6, on="true")))
    assert "self_collision" not in trajectory.ledger["work"]["bodies"]
