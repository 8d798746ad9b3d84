"""core.radar_beam: the nearest ground in a radar altimeter's beam, against geometry worked by hand."""

from __future__ import annotations

import math

import numpy as np

from testbench.core.radar_beam import beam_rays_b, first_return_m, nearest_return_ne_m, ray_ranges_m
from testbench.core.rotations import euler_to_dcm


def _flat(height_m: float):
    return lambda n, e: np.full(np.broadcast(np.asarray(n), np.asarray(e)).shape, height_m)


def test_rays_are_unit_and_fill_the_cone():
    rays = beam_rays_b(math.radians(20.0), rings=2, azimuths=8)
    assert rays.shape == (17, 3)
    np.testing.assert_allclose(np.linalg.norm(rays, axis=1), 1.0)
    off_axis_deg = np.degrees(np.arccos(rays[:, 2]))
    np.testing.assert_allclose(sorted(set(np.round(off_axis_deg, 9))), [0.0, 10.0, 20.0], atol=1e-9)
    assert beam_rays_b(0.0).shape == (1, 3)


def test_pencil_beam_over_flat_ground_reads_height_over_cosine_of_tilt():
    antenna = np.array([0.0, 0.0, -300.0])  # 300 m above the origin; ground 20 m up
    for roll_deg in (0.0, 10.0, 25.0):
        R_nb = euler_to_dcm(np.radians([roll_deg, 0.0, 30.0]))
        r = first_return_m(antenna, R_nb, beam_rays_b(0.0), _flat(20.0))
        assert math.isclose(float(r), 280.0 / math.cos(math.radians(roll_deg)), rel_tol=1e-12)


def test_wide_beam_returns_the_vertical_when_a_ray_points_straight_down():
    # Rolled 10 deg: the inner ring's ray 10 deg to the other side points straight down.
    R_nb = euler_to_dcm(np.radians([10.0, 0.0, 0.0]))
    r = first_return_m(np.array([0.0, 0.0, -300.0]), R_nb, beam_rays_b(math.radians(20.0)), _flat(0.0))
    assert math.isclose(float(r), 300.0, rel_tol=1e-12)


def test_wide_beam_over_a_slope_reads_less_than_the_vertical_clearance():
    slope = 0.3  # the ground rises 0.3 m per metre north

    def ramp(n, e):
        return slope * np.asarray(n, float) + 0.0 * np.asarray(e, float)

    antenna = np.array([0.0, 0.0, -300.0])
    level = np.eye(3)
    vertical = float(first_return_m(antenna, level, beam_rays_b(0.0), ramp))
    nearest = float(first_return_m(antenna, level, beam_rays_b(math.radians(20.0)), ramp))
    assert math.isclose(vertical, 300.0, rel_tol=1e-12)
    perpendicular = 300.0 * math.cos(math.atan(slope))  # the true nearest point: 16.7 deg off vertical
    assert perpendicular - 1e-6 <= nearest < vertical - 5.0
    # The ray tilted north by 20 deg, solved exactly: 300 = t cos20 + 0.3 t sin20.
    d = np.array([[math.sin(math.radians(20.0)), 0.0, math.cos(math.radians(20.0))]])
    t = float(ray_ranges_m(antenna, d, ramp, tol_m=1e-9, max_iterations=60)[0])
    assert math.isclose(t, 300.0 / (math.cos(math.radians(20.0)) + slope * math.sin(math.radians(20.0))), rel_tol=1e-9)


def test_nearest_return_point_lies_up_the_slope_at_the_beams_edge():
    # Ground rising north at 0.3: the nearest ground in a 20 deg beam is the north-most ray's
    # (the perpendicular to the ramp lies 16.7 deg off vertical, inside the cone, but the beam
    # is sampled by its rays: the 20 deg ray north is the nearest of them), 300 m below.
    slope = 0.3

    def ramp(n, e):
        return slope * np.asarray(n, float) + 0.0 * np.asarray(e, float)

    antenna = np.array([100.0, -50.0, -300.0])
    ne = nearest_return_ne_m(antenna, np.eye(3), beam_rays_b(math.radians(20.0)), ramp)
    t = 300.0 / (math.cos(math.radians(20.0)) + slope * math.sin(math.radians(20.0))) - slope * 100.0 / (
        math.cos(math.radians(20.0)) + slope * math.sin(math.radians(20.0)))
    # The default tolerance (a step of 0.05 m at most) leaves millimetres on this slope.
    np.testing.assert_allclose(ne, [100.0 + t * math.sin(math.radians(20.0)), -50.0], atol=0.01)
    # Flat ground: the boresight's point, straight below.
    np.testing.assert_allclose(nearest_return_ne_m(antenna, np.eye(3), beam_rays_b(math.radians(20.0)), _flat(0.0)),
                               [100.0, -50.0], atol=1e-9)


def test_ground_above_the_antenna_gives_no_return():
    r = first_return_m(np.array([0.0, 0.0, -100.0]), np.eye(3), beam_rays_b(math.radians(20.0)), _flat(150.0))
    assert np.isinf(r)


def test_batched_antennas_match_one_by_one():
    rng = np.random.default_rng(3)
    pos = np.c_[rng.uniform(-50, 50, (4, 5, 2)), np.full((4, 5, 1), -250.0)]

    def hills(n, e):
        return 20.0 * np.sin(np.asarray(n) / 70.0) * np.cos(np.asarray(e) / 90.0)

    rays, R = beam_rays_b(math.radians(15.0)), euler_to_dcm(np.radians([5.0, -3.0, 40.0]))
    batch = first_return_m(pos, R, rays, hills)
    one = np.array([[first_return_m(pos[i, j], R, rays, hills) for j in range(5)] for i in range(4)])
    np.testing.assert_allclose(batch, one, rtol=0, atol=0)


def test_steep_face_is_solved_to_the_tolerance_where_a_fixed_few_steps_are_metres_off():
    """A dune face rising 1.5 m per metre north: each fixed-point step shrinks a 20 deg ray's
    error only by 1.5 tan 20 = 0.55, so three steps (what the terrain match once used) leave
    metres; iterating to the tolerance leaves centimetres, for every antenna of a grid at once
    and with the rays that have converged no longer evaluated."""
    slope = 1.5

    def face(n, e):
        return slope * np.clip(np.asarray(n, float), 0.0, None) + 0.0 * np.asarray(e, float)

    a20 = math.radians(20.0)
    d = np.array([[math.sin(a20), 0.0, math.cos(a20)], [0.0, 0.0, 1.0]])
    antennas = np.stack([np.linspace(-100.0, -20.0, 11), np.zeros(11), np.full(11, -300.0)], axis=-1)  # (11, 3)
    # Exact: below the face's foot, the ray meets the face where 300 - t cos = 1.5 (n + t sin).
    exact = (300.0 - slope * antennas[:, 0]) / (math.cos(a20) + slope * math.sin(a20))
    t = ray_ranges_m(antennas, d, face)
    assert t.shape == (11, 2)
    np.testing.assert_allclose(t[:, 1], 300.0)  # the boresight stands on the flat ground
    assert np.all(antennas[:, 0] + exact * math.sin(a20) > 0.0)  # on the face, not before it
    np.testing.assert_allclose(t[:, 0], exact, atol=0.1)
    three = ray_ranges_m(antennas, d, face, tol_m=0.0, max_iterations=3)[:, 0]
    assert np.abs(three - exact).max() > 2.0
