"""Static (level, at rest) IMU record generated in vectorised blocks with the in-loop model.

A level IMU at rest on the ground, body FRD aligned with NED (heading north), senses
    omega_ib_b = Earth rate in NED = (W cos L, 0, -W sin L) rad/s,
    f_b = -gravity = (0, 0, -g(L, h)) m/s^2,
plus the errors of `imu.ImuErrorModel` (the same class and draws as the in-loop IMU).
"""

from __future__ import annotations

import numpy as np

from testbench.core.geodesy import earth_rate_ned_rps, normal_gravity_mps2
from testbench.sensors.imu import ImuErrorModel
from testbench.sensors.imu_params import ImuSpec

COLUMNS = ("t_s", "gyro_x_rad_s", "gyro_y_rad_s", "gyro_z_rad_s", "accel_x_m_s2", "accel_y_m_s2", "accel_z_m_s2")
_BLOCK = 65536  # samples per block: bounds memory, changes nothing in the draws


def static_truth(lat_rad: float, alt_m: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(omega_ib_b (3,) rad/s, f_b (3,) m/s^2) of a level IMU at rest facing north."""
    return earth_rate_ned_rps(lat_rad), np.array([0.0, 0.0, -float(normal_gravity_mps2(lat_rad, alt_m))])


def static_record(
    spec: ImuSpec, duration_s: float, rate_hz: float, rng: np.random.Generator, lat_rad: float = np.deg2rad(45.0)
) -> dict[str, np.ndarray]:
    """A static record as columns (see COLUMNS), each of shape (n,), n = round(duration * rate).

    t_s = k / rate_hz for k = 1..n (the first sample closes the first interval).
    """
    n = int(round(duration_s * rate_hz))
    model = ImuErrorModel(spec, 1.0 / rate_hz)
    w0, f0 = static_truth(lat_rad)
    gyro = np.empty((n, 3))
    accel = np.empty((n, 3))
    for start in range(0, n, _BLOCK):
        m = min(_BLOCK, n - start)
        gyro[start : start + m], accel[start : start + m] = model.apply(
            np.broadcast_to(w0, (m, 3)), np.broadcast_to(f0, (m, 3)), rng
        )
    out = {"t_s": np.arange(1, n + 1) / rate_hz}
    for i, ax in enumerate("xyz"):
        out[f"gyro_{ax}_rad_s"] = gyro[:, i]
    for i, ax in enumerate("xyz"):
        out[f"accel_{ax}_m_s2"] = accel[:, i]
    return out


def write_parquet(record: dict[str, np.ndarray], path: str, metadata: dict[str, str] | None = None) -> None:
    """Write a record (COLUMNS) to a parquet file, with optional string metadata."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.table({c: record[c] for c in COLUMNS})
    if metadata:
        table = table.replace_schema_metadata({k: str(v) for k, v in metadata.items()})
    pq.write_table(table, path)
