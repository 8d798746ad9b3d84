"""The formation layout's start check (navigation/relative/layout.py)."""

import math

import numpy as np

from testbench.navigation.relative.layout import LayoutParams, expected_relative_ned_m, own_course_rad, start_fits_layout

# The paper's arrowhead (forward, right, down): uav3 and uav5 stand 200 m from uav0, mirrored.
SLOTS = {"uav0": (0.0, 0.0, 0.0), "uav3": (-173.205, -100.0, 0.0), "uav5": (-173.205, 100.0, 0.0)}


def test_expected_relative_position_rotates_with_the_course():
    p = LayoutParams(slots=SLOTS)
    # Course north: forward = north, right = east.
    assert np.allclose(expected_relative_ned_m(p, "uav0", "uav5", 0.0), [-173.205, 100.0, 0.0])
    # Course east: forward = east, right = south.
    assert np.allclose(expected_relative_ned_m(p, "uav0", "uav5", math.pi / 2), [-100.0, -173.205, 0.0], atol=1e-9)
    assert expected_relative_ned_m(p, "uav0", "uav9", 0.0) is None


def test_course_from_velocity_or_yaw_when_hovering():
    assert math.isclose(own_course_rad([0.0, 4.0, 0.0], 0.3, 1.0), math.pi / 2)
    assert own_course_rad([0.2, 0.1, 0.0], 0.3, 1.0) == 0.3


def test_a_start_on_the_mirrored_vehicle_is_refused_and_near_its_slot_accepted():
    p = LayoutParams(slots=SLOTS)
    vel = np.array([4.0, 0.0, 0.0])  # flying north
    uav3_where = np.array([-173.2, -100.0, 0.0])
    # A track of uav3 decoded as uav5: the range agrees (200 m both), the side does not.
    assert not start_fits_layout(p, "uav0", "uav5", uav3_where, vel, 0.0)
    assert start_fits_layout(p, "uav0", "uav3", uav3_where, vel, 0.0)
    # uav5 25 m off its slot and the layout turned by 8 deg: still a plausible start.
    c, s = math.cos(math.radians(8)), math.sin(math.radians(8))
    turned = np.array([c * -173.205 - s * 100.0, s * -173.205 + c * 100.0, 0.0]) + [15.0, 20.0, 0.0]
    assert start_fits_layout(p, "uav0", "uav5", turned, vel, 0.0)
    # A vehicle the layout does not name is never refused.
    assert start_fits_layout(p, "uav0", "uav9", uav3_where, vel, 0.0)


def test_the_layout_turns_with_the_nose_not_with_a_sideways_slide():
    """swarm_cnn, uav7 at 5.7 s: sliding at 1.05 m/s on a -52 deg ground course, nose 0.2 deg.
    A track of uav2 (173 m ahead, 100 m right) decoded as uav9 (200 m right, same row; both
    200 m away, so the UWB range agrees) is refused by the nose's layout; turned by the ground
    course the layout put uav9 where uav2 is."""
    slots = {"uav2": (-86.603, 50.0, 0.0), "uav7": (-259.808, -50.0, 0.0), "uav9": (-259.808, 150.0, 0.0)}
    vel = np.array([0.65, -0.82, 0.0])
    uav2_where = np.array([173.2, 100.0, 0.0])
    assert not start_fits_layout(LayoutParams(slots=slots), "uav7", "uav9", uav2_where, vel, math.radians(0.2))
    assert start_fits_layout(LayoutParams(slots=slots), "uav7", "uav2", uav2_where, vel, math.radians(0.2))
    assert start_fits_layout(LayoutParams(slots=slots, course_from="velocity"), "uav7", "uav9", uav2_where, vel,
                             math.radians(0.2))


def test_the_leader_turns_its_layout_by_its_ground_course():
    """swarm_cnn, the leader at 295 s: nose 0.5 deg (a multirotor flying waypoints keeps it),
    ground course 62 deg. Turned by the nose, the layout put uav1's slot where uav2 flew (the
    arrowhead is symmetric under 60 deg turns) and passed a track of uav2 decoded as uav1; the
    leader's layout turns by its ground course, whatever course_from says."""
    slots = {"uav0": (0.0, 0.0, 0.0), "uav1": (-86.603, -50.0, 0.0), "uav2": (-86.603, 50.0, 0.0)}
    course = math.radians(62.0)
    vel = 4.0 * np.array([math.cos(course), math.sin(course), 0.0])
    p = LayoutParams(slots=slots)
    uav2_where = expected_relative_ned_m(p, "uav0", "uav2", course)
    uav1_where = expected_relative_ned_m(p, "uav0", "uav1", course)
    nose = math.radians(0.5)
    assert start_fits_layout(p, "uav0", "uav1", uav2_where, vel, nose)  # no leader named: by the nose
    led = LayoutParams(slots=slots, leader="uav0")
    assert not start_fits_layout(led, "uav0", "uav1", uav2_where, vel, nose)
    assert start_fits_layout(led, "uav0", "uav1", uav1_where, vel, nose)
    # A follower of that layout still turns it by its nose.
    assert start_fits_layout(led, "uav1", "uav0", -expected_relative_ned_m(p, "uav0", "uav1", 0.0), vel, 0.0)
