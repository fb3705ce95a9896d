"""Skipping the contact search in free flight (animbatch.sim.contact.clearance): a run that skips gives exactly the
trajectory of a run that searches every step, while searching a small fraction of the steps; and the bound that
allows a skip counts turning as well as moving (a mutant that forgets turning lets a spinning rod's tip through)."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import api
from animbatch.sim.contact import clearance, time_stepping
from support.scenes import counting, scene


def world(duration: float, method: str, bodies: list[str], colliders: list[str], g: float | None = None,
          restitution: float = 0.6, friction: float = 0.3) -> str:
    """A scene of ``bodies`` and ``colliders`` (flow mappings) of one material, at 20 fps and steps of 1 ms, in
    gravity ``g`` [m/s², downwards] or none."""
    field = f"{{type: gravity, g: [0, {-g}, 0]}}" if g is not None else ""
    return (f"duration: {duration}\nfps: 20\nsolver: {{method: {method}, dt: 1.0e-3}}\n"
            f"materials: {{m: {{restitution: {restitution}, static_friction: {friction}, "
            f"kinetic_friction: {friction}}}}}\n"
            f"bodies: [{', '.join(bodies)}]\ncolliders: [{', '.join(colliders)}]\nfields: [{field}]\n")


def ball(name: str, position: str, velocity: str = "[0, 0, 0]") -> str:
    return (f"{{name: {name}, type: rigid, shape: {{type: sphere, radius: 0.05}}, density: 500, position: {position}, "
            f"velocity: {velocity}, material: m}}")


# A 2 m rod spinning end over end at 20 rad/s, its centre 0.8 m above the floor: it starts along the floor (its axis
# is z), so a search that looks 0.5 m further finds nothing, and it turns its tips into the floor within a tenth of
# a second.
ROD = ("{name: rod, type: rigid, shape: {type: rod, length: 2.0, radius: 0.02}, density: 500, position: [-3, 0.8, 0], "
       "angular_velocity: [20, 0, 0], material: m}")
FLOOR = "{type: plane, material: m}"
# The rod, and a ball thrown across a room, over a low box, into a wall, then falling to the floor (long free flights
# between contacts).
THROWN = world(1.6, "symplectic_euler", [ball("ball", "[0, 1.0, 0]", "[3, 2, 0]"), ROD],
               [FLOOR, "{type: box, position: [1.0, 0.1, 0], size: [0.2, 0.2, 1.0], material: m}",
                "{type: plane, point: [2.5, 0, 0], normal: [-1, 0, 0], material: m}"], g=3.0)
# The rod alone in a weak field.
SPINNING = world(0.5, "symplectic_euler", [ROD], [FLOOR], g=0.1)
# Colliders on keyframes: a paddle sliding at 2 m/s and a bat swinging about its centre, towards balls at rest.
PADDLES = world(1.0, "verlet", [ball("near", "[0, 0, 0]"), ball("far", "[0.6, 0, 3.3]")], [
    "{type: box, position: [-1, 0, 0], size: [0.1, 0.4, 0.4], material: m, interpolation: linear, "
    "keyframes: [{time: 0}, {time: 1, offset: [2, 0, 0]}]}",
    "{type: box, position: [0.6, 0, 3], size: [1.0, 0.1, 0.1], material: m, interpolation: linear, "
    "keyframes: [{time: 0}, {time: 1, rotation: {axis: [0, 1, 0], angle: 180}}]}"], restitution=0.8, friction=0.0)


def trajectories(monkeypatch, *, skipping: bool, text: str = THROWN):
    searches = counting(monkeypatch, time_stepping, "detect")
    if not skipping:
        monkeypatch.setattr(clearance.Clearance, "clear", lambda self, state, travel: False)
        monkeypatch.setattr(clearance.Clearance, "look_ahead", lambda self, travel, margin: 0.0)
    trajectory = api.simulate(scene(text))
    monkeypatch.undo()
    return trajectory, len(searches)


@pytest.mark.slow  # several seconds: two runs of thousands of contact steps each
def test_skipping_the_search_in_free_flight_changes_nothing_and_searches_a_fraction_of_the_steps(monkeypatch):
    searched, every_step = trajectories(monkeypatch, skipping=False)
    skipped, fewer = trajectories(monkeypatch, skipping=True)
    assert fewer < every_step / 3
    # the ball and the rod's tips both strike something
    assert {body for _, body in searched.solver_stats["impacts"]} == {0, 1}
    np.testing.assert_array_equal(skipped.positions, searched.positions)
    np.testing.assert_array_equal(skipped.orientations, searched.orientations)
    assert skipped.solver_stats["impacts"] == searched.solver_stats["impacts"]


@pytest.mark.slow  # several seconds: two runs of thousands of contact steps each
def test_colliders_on_keyframes_count_their_own_moves_and_turns(monkeypatch):
    """The sliding paddle and the swinging bat strike their balls in the same steps whether the search is skipped
    or not; a mutant that ignores the colliders' moves lets both pass through their balls."""
    searched, every_step = trajectories(monkeypatch, skipping=False, text=PADDLES)
    skipped, fewer = trajectories(monkeypatch, skipping=True, text=PADDLES)
    assert {body for _, body in searched.solver_stats["impacts"]} == {0, 1}
    assert fewer < every_step / 2
    np.testing.assert_array_equal(skipped.positions, searched.positions)
    monkeypatch.setattr(clearance.Clearance, "_colliders_within", lambda self, t: True)
    with pytest.warns(UserWarning, match="missed a collision"):
        mutant = api.simulate(scene(PADDLES))
    monkeypatch.undo()
    assert not mutant.solver_stats["impacts"]


def test_a_skip_that_forgets_the_turn_misses_the_spinning_rods_tip(monkeypatch):
    """The mutant measures only how far each centre moved: the rod's centre hardly moves while its tips sweep
    metres, so the mutant skips the searches that would have found a tip at the floor, and the rod spins through
    it."""
    searched = api.simulate(scene(SPINNING))
    original = clearance.Clearance.clear

    def centres_only(self, state, travel):
        reach, self.reach = self.reach, np.zeros_like(self.reach)
        try:
            return original(self, state, travel)
        finally:
            self.reach = reach

    monkeypatch.setattr(clearance.Clearance, "clear", centres_only)
    with pytest.warns(UserWarning, match="missed a collision"):
        mutant = api.simulate(scene(SPINNING))
    monkeypatch.undo()
    assert searched.solver_stats["impacts"] and not mutant.solver_stats["impacts"]
    assert not np.allclose(mutant.positions, searched.positions, atol=1e-3)


@pytest.mark.parametrize("travel", [np.array([0.0, 0.0]), np.array([0.01, np.nan])])
def test_a_clearance_never_vouches_for_a_state_it_cannot_measure(travel):
    """Without a search that looked further, or with a travel that is not a number, the search runs."""
    from animbatch.sim.bodies import Kinematics

    state = Kinematics(np.zeros((2, 3)), np.zeros((2, 3)), None, None, 2, 0.0)
    fresh = clearance.Clearance(np.zeros(2))
    assert not fresh.clear(state, travel)
    fresh.found_nothing(state, 1.0)
    assert fresh.clear(state, travel) == bool(np.all(np.isfinite(travel)))
