"""Benchmarks of the sensor package (wired into `testbench bench` by the lead)."""

from __future__ import annotations

import time

import numpy as np

from testbench.core.interfaces import BuildContext
from testbench.sensors.fakes import ORIGIN, FakeWorld, make_truth


def _imu_record_2h_s() -> float:
    from testbench.sensors.imu_params import ImuParams
    from testbench.sensors.imu_static import static_record

    spec = ImuParams(preset="paper").spec()
    t0 = time.perf_counter()
    static_record(spec, 7200.0, 100.0, np.random.default_rng(0))
    return time.perf_counter() - t0


def _suite_ms_per_s(n_vehicles: int = 10, seconds: float = 2.0, physics_hz: float = 100.0) -> float:
    """Wall ms per simulated second of the full non-camera suite on n vehicles (fake truth)."""
    from testbench.sensors.airspeed import Airspeed, AirspeedParams
    from testbench.sensors.barometer import Barometer, BarometerParams
    from testbench.sensors.gnss import Gnss, GnssParams
    from testbench.sensors.imu import Imu, ImuParams
    from testbench.sensors.magnetometer import Magnetometer, MagnetometerParams
    from testbench.sensors.uwb import Uwb, UwbParams

    ids = tuple(f"uav{i}" for i in range(n_vehicles))
    suites = {}
    for v in ids:
        ctx = BuildContext(v, ids, ORIGIN, physics_rate_hz=physics_hz)
        suites[v] = [
            Imu(ImuParams(), ctx=ctx), Magnetometer(MagnetometerParams(), ctx=ctx), Barometer(BarometerParams(), ctx=ctx),
            Gnss(GnssParams(), ctx=ctx), Airspeed(AirspeedParams(), ctx=ctx), Uwb(UwbParams(), ctx=ctx),
        ]
    rngs = {v: [np.random.default_rng(i * 10 + j) for j in range(6)] for i, v in enumerate(ids)}
    n_ticks = int(seconds * physics_hz)
    # Truth is prepared outside the timed loop: the engine produces it anyway.
    truths = [
        {v: make_truth(k / physics_hz, pos_ned_m=(20.0 * k / physics_hz, 100.0 * i, -300.0), vel_ned_mps=(20.0, 0, 0),
                       airspeed_mps=20.0) for i, v in enumerate(ids)}
        for k in range(n_ticks)
    ]
    t0 = time.perf_counter()
    for k in range(n_ticks):
        t = k / physics_hz
        for v in ids:
            world = FakeWorld(t, v, truths[k])
            for s, rng in zip(suites[v], rngs[v]):
                if k % int(round(physics_hz / s.rate_hz)) == 0:
                    s.measure(truths[k][v], world, rng)
    return (time.perf_counter() - t0) * 1000.0 / seconds


def run_benchmarks() -> dict[str, float]:
    """sensors.imu_record_2h_s: seconds to generate the 2 h 100 Hz paper-preset static record;
    sensors.suite_10_vehicles_ms_per_s: wall ms per simulated second of IMU 100 Hz, magnetometer
    50, barometer 50, GNSS 5, airspeed 20 and UWB 100 Hz (10-node TDMA) on 10 vehicles."""
    return {
        "sensors.imu_record_2h_s": _imu_record_2h_s(),
        "sensors.suite_10_vehicles_ms_per_s": _suite_ms_per_s(),
    }
