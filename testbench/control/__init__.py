"""Guidance and autopilots: missions (waypoints, racetrack, orbit), L1 path following, the
fixed-wing autopilot (LQI longitudinal, roll/yaw loops) and the multirotor cascade with its
motor mixer. Importing this package registers the controllers and missions."""

from testbench.control import fixed_wing, missions, multirotor  # noqa: F401  (registration)
