"""Sensor models: IMU, magnetometer, barometer, GNSS with denial, UWB, airspeed, the radar
altimeter, the ideal state sensor, and cameras (camera/). Importing this package registers
every sensor."""

from testbench.sensors import (  # noqa: F401
    airspeed,
    barometer,
    gnss,
    ideal_state,
    imu,
    magnetometer,
    radar_altimeter,
    uwb,
)
from testbench.sensors import camera  # noqa: F401
