"""Collects a run's record and writes it in the output contract's layout.

telemetry.parquet has one row per vehicle per record tick (truth and estimate side by side,
column names carry units); events/*.parquet hold per-measurement rows (corrections, ISMN fixes,
relative navigation, formation); trajectories/<id>_{truth,nav}.tum are TUM files (local NED
metres) for evo. Column lists are kept in plain Python lists and turned into Arrow tables once,
at the end; writing is deterministic (same record -> same bytes).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from testbench.core.messages import CorrectionInfo, GuidanceStatus, NavEstimate, TruthState

TELEMETRY_FLOAT_COLUMNS = (
    "t_s",
    "truth_north_m", "truth_east_m", "truth_down_m",
    "truth_vn_mps", "truth_ve_mps", "truth_vd_mps",
    "truth_roll_rad", "truth_pitch_rad", "truth_yaw_rad",
    "truth_qw", "truth_qx", "truth_qy", "truth_qz",
    "truth_p_rps", "truth_q_rps", "truth_r_rps",
    "truth_airspeed_mps", "truth_height_agl_m", "truth_lat_deg", "truth_lon_deg", "truth_alt_m",
    "nav_north_m", "nav_east_m", "nav_down_m",
    "nav_vn_mps", "nav_ve_mps", "nav_vd_mps",
    "nav_roll_rad", "nav_pitch_rad", "nav_yaw_rad",
    "nav_qw", "nav_qx", "nav_qy", "nav_qz",
    "nav_sigma_north_m", "nav_sigma_east_m", "nav_sigma_down_m", "nav_cov_ne_m2",
    "nav_sigma_vn_mps", "nav_sigma_ve_mps", "nav_sigma_vd_mps",
    "nav_sigma_roll_rad", "nav_sigma_pitch_rad", "nav_sigma_yaw_rad",
    "cmd_0", "cmd_1", "cmd_2", "cmd_3",
    "gd_alt_cmd_m", "gd_airspeed_cmd_mps",
    "gd_line_start_n_m", "gd_line_start_e_m", "gd_line_end_n_m", "gd_line_end_e_m",
    "gd_target_n_m", "gd_target_e_m", "gd_target_d_m", "gd_bank_cmd_rad",
)

# With Recorder(wind_columns=True): the wind the vehicle met (truth, NED) and its navigator's
# estimate of the horizontal wind with its sigmas (NaN where the navigator estimates none).
TELEMETRY_WIND_COLUMNS = (
    "truth_wind_n_mps", "truth_wind_e_mps", "truth_wind_d_mps",
    "nav_wind_n_mps", "nav_wind_e_mps", "nav_sigma_wind_n_mps", "nav_sigma_wind_e_mps",
)

# With Recorder(boresight_columns=True): the navigator's estimate of its scene-matching camera's
# boresight error (body axes, rotation vector) with its sigmas (NaN where it estimates none).
TELEMETRY_BORESIGHT_COLUMNS = (
    "nav_boresight_x_rad", "nav_boresight_y_rad", "nav_boresight_z_rad",
    "nav_sigma_boresight_x_rad", "nav_sigma_boresight_y_rad", "nav_sigma_boresight_z_rad",
)

# With Recorder(time_offset_columns=True): the navigator's estimate of its scene-matching
# camera's time offset (stamp minus exposure, s) with its sigma (NaN where it estimates none).
TELEMETRY_TIME_OFFSET_COLUMNS = ("nav_camera_time_offset_s", "nav_sigma_camera_time_offset_s")

# With Recorder(intrinsics_columns=True): the navigator's estimate of its scene-matching
# camera's intrinsics error (principal point true minus calibrated, px, u and v; focal length,
# relative) with its sigmas.
_INTRINSICS = ("pp_u_px", "pp_v_px", "focal_rel")
TELEMETRY_INTRINSICS_COLUMNS = (tuple(f"nav_camera_{k}" for k in _INTRINSICS)
                                + tuple(f"nav_sigma_camera_{k}" for k in _INTRINSICS))

# With Recorder(map_error_columns=True): the navigator's estimate of its reference map's
# georeference error (north, east, m) with its sigmas.
TELEMETRY_MAP_ERROR_COLUMNS = ("nav_map_error_n_m", "nav_map_error_e_m", "nav_sigma_map_error_n_m",
                               "nav_sigma_map_error_e_m")

_NAN = float("nan")


class Recorder:
    """Accumulates telemetry rows and event rows for one run; wind_columns: add
    TELEMETRY_WIND_COLUMNS (a scenario with wind, or a navigator that estimates it);
    boresight_columns: add TELEMETRY_BORESIGHT_COLUMNS (a navigator that estimates its camera's
    boresight); time_offset_columns: add TELEMETRY_TIME_OFFSET_COLUMNS (a navigator that
    estimates its camera's time offset); intrinsics_columns: add TELEMETRY_INTRINSICS_COLUMNS
    (a navigator that estimates its camera's intrinsics error); map_error_columns: add
    TELEMETRY_MAP_ERROR_COLUMNS (a navigator that estimates its map's georeference error)."""

    def __init__(self, wind_columns: bool = False, boresight_columns: bool = False,
                 time_offset_columns: bool = False, intrinsics_columns: bool = False,
                 map_error_columns: bool = False) -> None:
        self._wind_columns = bool(wind_columns)
        self._boresight_columns = bool(boresight_columns)
        self._time_offset_columns = bool(time_offset_columns)
        self._intrinsics_columns = bool(intrinsics_columns)
        self._map_error_columns = bool(map_error_columns)
        self._float_columns = (TELEMETRY_FLOAT_COLUMNS + (TELEMETRY_WIND_COLUMNS if wind_columns else ())
                               + (TELEMETRY_BORESIGHT_COLUMNS if boresight_columns else ())
                               + (TELEMETRY_TIME_OFFSET_COLUMNS if time_offset_columns else ())
                               + (TELEMETRY_INTRINSICS_COLUMNS if intrinsics_columns else ())
                               + (TELEMETRY_MAP_ERROR_COLUMNS if map_error_columns else ()))
        self._tel: dict[str, list] = {c: [] for c in self._float_columns}
        self._vehicle: list[str] = []
        self._leg: list[int] = []
        self._on_leg: list[bool] = []
        self._gnss: list[bool] = []
        self._events: dict[str, list[dict[str, Any]]] = {}
        self._artifacts: dict[str, dict[str, np.ndarray]] = {}

    def record(self, vehicle_id: str, truth: TruthState, est: NavEstimate, command_values: tuple[float, ...], status: GuidanceStatus | None, gnss_available: bool) -> None:
        """One telemetry row (truth at the tick, the estimate the controller last saw)."""
        c = self._tel
        app = lambda k, v: c[k].append(float(v))  # noqa: E731
        app("t_s", truth.t_s)
        for k, v in zip(("truth_north_m", "truth_east_m", "truth_down_m"), truth.pos_ned_m):
            app(k, v)
        for k, v in zip(("truth_vn_mps", "truth_ve_mps", "truth_vd_mps"), truth.vel_ned_mps):
            app(k, v)
        for k, v in zip(("truth_roll_rad", "truth_pitch_rad", "truth_yaw_rad"), truth.rpy_rad):
            app(k, v)
        for k, v in zip(("truth_qw", "truth_qx", "truth_qy", "truth_qz"), truth.q_nb_wxyz):
            app(k, v)
        for k, v in zip(("truth_p_rps", "truth_q_rps", "truth_r_rps"), truth.omega_eb_b_rps):
            app(k, v)
        app("truth_airspeed_mps", truth.airspeed_mps)
        app("truth_height_agl_m", truth.height_agl_m)
        app("truth_lat_deg", math.degrees(truth.lat_rad))
        app("truth_lon_deg", math.degrees(truth.lon_rad))
        app("truth_alt_m", truth.alt_m)
        for k, v in zip(("nav_north_m", "nav_east_m", "nav_down_m"), est.pos_ned_m):
            app(k, v)
        for k, v in zip(("nav_vn_mps", "nav_ve_mps", "nav_vd_mps"), est.vel_ned_mps):
            app(k, v)
        for k, v in zip(("nav_roll_rad", "nav_pitch_rad", "nav_yaw_rad"), est.rpy_rad):
            app(k, v)
        for k, v in zip(("nav_qw", "nav_qx", "nav_qy", "nav_qz"), est.q_nb_wxyz):
            app(k, v)
        P, V, A = est.cov_pos_ned_m2, est.cov_vel_ned_m2s2, est.cov_att_rad2
        for k, i in (("nav_sigma_north_m", 0), ("nav_sigma_east_m", 1), ("nav_sigma_down_m", 2)):
            app(k, math.sqrt(max(P[i][i], 0.0)))
        app("nav_cov_ne_m2", P[0][1])
        for k, i in (("nav_sigma_vn_mps", 0), ("nav_sigma_ve_mps", 1), ("nav_sigma_vd_mps", 2)):
            app(k, math.sqrt(max(V[i][i], 0.0)))
        for k, i in (("nav_sigma_roll_rad", 0), ("nav_sigma_pitch_rad", 1), ("nav_sigma_yaw_rad", 2)):
            app(k, math.sqrt(max(A[i][i], 0.0)))
        cmd = tuple(command_values) + (_NAN,) * (4 - len(command_values))
        for i in range(4):
            app(f"cmd_{i}", cmd[i])
        s = status or GuidanceStatus(t_s=truth.t_s)
        app("gd_alt_cmd_m", s.alt_cmd_m)
        app("gd_airspeed_cmd_mps", s.airspeed_cmd_mps)
        app("gd_line_start_n_m", s.line_start_ne_m[0])
        app("gd_line_start_e_m", s.line_start_ne_m[1])
        app("gd_line_end_n_m", s.line_end_ne_m[0])
        app("gd_line_end_e_m", s.line_end_ne_m[1])
        app("gd_target_n_m", s.target_ned_m[0])
        app("gd_target_e_m", s.target_ned_m[1])
        app("gd_target_d_m", s.target_ned_m[2])
        app("gd_bank_cmd_rad", s.bank_cmd_rad)
        if self._wind_columns:
            self._record_wind(truth, est)
        if self._boresight_columns:
            self._record_boresight(est)
        if self._time_offset_columns:
            td, var = est.camera_time_offset_s, est.var_camera_time_offset_s2
            c["nav_camera_time_offset_s"].append(_NAN if td is None else float(td))
            c["nav_sigma_camera_time_offset_s"].append(_NAN if var is None else math.sqrt(max(var, 0.0)))
        if self._intrinsics_columns:
            err, cov = est.camera_intrinsics_error, est.cov_camera_intrinsics_error
            for i, k in enumerate(_INTRINSICS):
                c[f"nav_camera_{k}"].append(_NAN if err is None else float(err[i]))
                c[f"nav_sigma_camera_{k}"].append(_NAN if cov is None else math.sqrt(max(float(cov[i, i]), 0.0)))
        if self._map_error_columns:
            err, cov = est.map_error_ne_m, est.cov_map_error_ne_m2
            for i, k in enumerate(("n", "e")):
                c[f"nav_map_error_{k}_m"].append(_NAN if err is None else float(err[i]))
                c[f"nav_sigma_map_error_{k}_m"].append(_NAN if cov is None else math.sqrt(max(float(cov[i, i]), 0.0)))
        self._vehicle.append(vehicle_id)
        self._leg.append(int(s.leg_index))
        self._on_leg.append(bool(s.on_leg))
        self._gnss.append(bool(gnss_available))

    def _record_wind(self, truth: TruthState, est: NavEstimate) -> None:
        c = self._tel
        for k, v in zip(("truth_wind_n_mps", "truth_wind_e_mps", "truth_wind_d_mps"), truth.wind_ned_mps):
            c[k].append(float(v))
        w, W = est.wind_ne_mps, est.cov_wind_ne_m2s2
        c["nav_wind_n_mps"].append(_NAN if w is None else float(w[0]))
        c["nav_wind_e_mps"].append(_NAN if w is None else float(w[1]))
        c["nav_sigma_wind_n_mps"].append(_NAN if W is None else math.sqrt(max(W[0][0], 0.0)))
        c["nav_sigma_wind_e_mps"].append(_NAN if W is None else math.sqrt(max(W[1][1], 0.0)))

    def _record_boresight(self, est: NavEstimate) -> None:
        c = self._tel
        b, B = est.camera_boresight_b_rad, est.cov_camera_boresight_rad2
        for i, axis in enumerate("xyz"):
            c[f"nav_boresight_{axis}_rad"].append(_NAN if b is None else float(b[i]))
            c[f"nav_sigma_boresight_{axis}_rad"].append(_NAN if B is None else math.sqrt(max(B[i][i], 0.0)))

    def correction(self, vehicle_id: str, info: CorrectionInfo) -> None:
        """One navigator correction (what was done with one measurement)."""
        self.event(
            "corrections",
            t_s=float(info.t_s), vehicle_id=vehicle_id, kind=str(info.kind),
            dim=int(np.size(info.innovation)), nis=float(info.nis), accepted=bool(info.accepted),
        )

    def event(self, table: str, **row: Any) -> None:
        """A row of an event table (events/<table>.parquet); rows of a table share keys."""
        self._events.setdefault(table, []).append(row)

    def artifact(self, name: str, arrays: dict[str, np.ndarray]) -> None:
        """Arrays saved as DIR/<name>.npz (e.g. ISMN example images for the report)."""
        self._artifacts[name] = arrays

    @property
    def n_rows(self) -> int:
        return len(self._vehicle)

    def telemetry_table(self) -> pa.Table:
        cols: dict[str, pa.Array] = {"vehicle_id": pa.array(self._vehicle, pa.string())}
        for k in self._float_columns:
            cols[k] = pa.array(self._tel[k], pa.float64())
        cols["gd_leg_index"] = pa.array(self._leg, pa.int64())
        cols["gd_on_leg"] = pa.array(self._on_leg, pa.bool_())
        cols["gnss_available"] = pa.array(self._gnss, pa.bool_())
        return pa.table(cols)

    def event_tables(self) -> dict[str, pa.Table]:
        return {name: pa.Table.from_pylist(rows) for name, rows in self._events.items() if rows}

    def write(self, out_dir: Path) -> None:
        """Write telemetry.parquet, events/*.parquet and trajectories/*.tum into out_dir."""
        out_dir.mkdir(parents=True, exist_ok=True)
        tel = self.telemetry_table()
        _write_parquet(tel, out_dir / "telemetry.parquet")
        for name, table in self.event_tables().items():
            (out_dir / "events").mkdir(exist_ok=True)
            _write_parquet(table, out_dir / "events" / f"{name}.parquet")
        write_tum_files(tel, out_dir / "trajectories")
        for name, arrays in self._artifacts.items():
            path = out_dir / f"{name}.npz"
            path.parent.mkdir(parents=True, exist_ok=True)
            np.savez_compressed(path, **arrays)


def _write_parquet(table: pa.Table, path: Path) -> None:
    # Fixed options and no wall-clock metadata, so the same record gives the same bytes.
    tmp = path.with_suffix(path.suffix + ".part")
    pq.write_table(table, tmp, compression="zstd", use_dictionary=True, write_statistics=True)
    tmp.replace(path)


def write_tum_files(tel: pa.Table, folder: Path) -> None:
    """<id>_truth.tum and <id>_nav.tum per vehicle: `t x y z qx qy qz qw` in local NED metres.

    Both files keep only the rows where truth and estimate are finite (e.g. not before the
    navigator started), with unit quaternions (scoring.write_tum), so that `evo_ape` associates
    exactly the rows that scoring uses.
    """
    from testbench.scoring.tum import write_tum

    folder.mkdir(parents=True, exist_ok=True)
    v = np.asarray(tel.column("vehicle_id").to_pylist())
    col = {name: np.asarray(tel.column(name).to_numpy(zero_copy_only=False), float)
           for name in tel.column_names if tel.schema.field(name).type == pa.float64()}
    for vid in dict.fromkeys(v.tolist()):
        m = v == vid
        pos = {k: np.column_stack([col[f"{k}_{a}_m"][m] for a in ("north", "east", "down")]) for k in ("truth", "nav")}
        both = np.all(np.isfinite(pos["truth"]), axis=1) & np.all(np.isfinite(pos["nav"]), axis=1)
        for k in ("truth", "nav"):
            q = np.column_stack([col[f"{k}_q{c}"][m] for c in "wxyz"])
            write_tum(folder / f"{vid}_{k}.tum", col["t_s"][m][both], pos[k][both], q[both])
