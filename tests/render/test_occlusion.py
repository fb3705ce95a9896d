"""Ambient occlusion of the ground, checked against the form factor of a sphere integrated over the sky."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch.render.occlusion import OCCLUSION_STRENGTH, TEXTURE_SIZE, ground_light, sphere_occlusion


def hidden_sky(offset: float, height: float, radius: float, samples: int = 400_000) -> float:
    """The cosine-weighted fraction of the sky above a point of the plane z = 0 that a sphere hides, integrated by
    sampling rays: directions drawn with density cos θ / π over the upper hemisphere, a ray counted if it meets the
    sphere of ``radius`` centred ``height`` above the plane and ``offset`` along x."""
    rng = np.random.default_rng(7)
    u1, u2 = rng.random(samples), rng.random(samples)
    sin_theta, phi = np.sqrt(u1), 2 * np.pi * u2  # Malley's method: cosine-weighted directions
    rays = np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), np.sqrt(1 - u1)], axis=1)
    centre = np.array([offset, 0.0, height])
    along = rays @ centre
    miss_squared = centre @ centre - along**2
    return float(np.mean((along > 0) & (miss_squared <= radius**2)))


@pytest.mark.parametrize("offset, height, radius", [(0.0, 1.0, 0.5), (0.6, 0.8, 0.3), (2.0, 1.0, 0.4),
                                                    (0.0, 0.35, 0.3)])
def test_a_sphere_hides_the_sky_by_its_form_factor(offset, height, radius):
    """(n · d / |d|) · r² / |d|², the form factor of a sphere wholly above the horizon, against the hidden fraction
    of the cosine-weighted sky found by casting rays."""
    expected = hidden_sky(offset, height, radius)
    assert sphere_occlusion(np.array(offset), np.array(height), np.array(radius)) == pytest.approx(expected,
                                                                                                   abs=3e-3)


def test_a_sphere_resting_on_the_ground_hides_all_of_the_sky_right_under_it():
    assert sphere_occlusion(np.array(0.0), np.array(0.2), np.array(0.2)) == 1.0
    assert sphere_occlusion(np.array(0.0), np.array(0.1), np.array(0.2)) == 1.0  # sunk into it
    assert sphere_occlusion(np.array(0.5), np.array(-0.3), np.array(0.2)) == 0.0  # under the ground


def texel_light(heights, radius, centres, texel=0.01):
    return ground_light(np.asarray(centres, float), np.asarray(heights, float), np.asarray(radius, float), texel)


def test_the_ground_is_darkest_under_a_resting_body_and_fades_with_distance_and_height():
    centre = [[128.0, 128.0]]
    resting = texel_light([0.2], [0.2], centre)
    assert resting.min() == pytest.approx(1 - OCCLUSION_STRENGTH, abs=0.01)
    assert np.unravel_index(resting.argmin(), resting.shape) in {(127, 127), (127, 128), (128, 127), (128, 128)}
    row = resting[128, 128:]
    assert np.all(np.diff(row) >= -1e-12), "lighter further out"
    assert resting[0, 0] == 1.0 and resting[128, 128 + 90] == 1.0, "nothing beyond the body's reach"
    raised = texel_light([0.6], [0.2], centre)
    assert raised.min() > resting.min(), "a body higher up darkens less"
    assert texel_light([10.0], [0.2], centre).min() == 1.0, "a body far above darkens nothing"


def test_bodies_hide_independent_parts_of_the_sky_so_their_light_multiplies():
    one = texel_light([0.3], [0.2], [[100.0, 128.0]])
    other = texel_light([0.3], [0.2], [[140.0, 128.0]])
    both = texel_light([0.3, 0.3], [0.2, 0.2], [[100.0, 128.0], [140.0, 128.0]])
    np.testing.assert_allclose(both, one * other, atol=1e-12)


def test_a_body_near_the_edge_darkens_only_the_texels_inside_and_does_not_wrap_around():
    edge = texel_light([0.2], [0.2], [[2.0, 128.0]])
    assert edge[128, 0] < 0.7
    assert edge[:, TEXTURE_SIZE - 40:].min() == 1.0
