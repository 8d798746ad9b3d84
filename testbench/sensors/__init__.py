"""Sensor models: IMU, magnetometer, barometer, GNSS with denial, UWB, airspeed, the radar
altimeter, the optical-flow sensor, the ideal state sensor, and cameras (camera/). Importing
this package registers every sensor."""

from testbench.sensors import (  # noqa: F401
    airspeed,
    barometer,
    gnss,
    ideal_state,
    imu,
    magnetometer,
    optical_flow,
    radar_altimeter,
    uwb,
)
from testbench.sensors import camera  # noqa: F401
