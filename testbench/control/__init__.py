"""Guidance and autopilots: missions (waypoints, racetrack, orbit), L1 path following, the
fixed-wing autopilot (LQI longitudinal, roll/yaw loops), the multirotor cascade with its
motor mixer, and formation followers (rigid slots, or a column along the path of the vehicle
ahead). Importing this package registers the controllers and
missions."""

from testbench.control import fixed_wing, formation, formation_followers, missions, multirotor, trail  # noqa: F401  (registration)
