"""Navigation metrics: the estimate (nav_*) against truth (truth_*), local NED metres.

Errors are e = nav - truth. NEES uses the covariance the navigator reported with each row:
position P = [[sN^2, cNE, 0], [cNE, sE^2, 0], [0, 0, sD^2]] (the recorder keeps the
north-east covariance, not the cross terms with down), velocity and attitude with diagonal
sigmas. Rows whose covariance is missing or not positive definite are left out of NEES.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from testbench.core.rotations import dcm_to_quat, euler_to_dcm, quat_to_rotvec, wrap_pi
from testbench.scoring.phases import telemetry_turning
from testbench.scoring.record_io import RunRecord, column
from testbench.scoring.result import (
    CameraBoresightStats, CameraIntrinsicsStats, CameraTimeOffsetStats, GnssSkyStats, NavMetrics, NavSubset,
    NisStats, SpoofedNav,
)
from testbench.scoring.stats import ChiSquareStats, chi_square_stats, error_stats

MIN_AGL_FOR_PCT_M = 1.0  # below this the vehicle is on the ground: % of AGL is meaningless

# A navigator is "lost" when its position error stays beyond anything its own covariance
# allows: position NEES above the chi-square(3) quantile at 1 - 1e-6 (30.66: a 5.5-sigma
# error) on every record row for LOST_HOLD_S. A consistent filter spends ~1e-6 of its time
# there, and not 10 s in a row; a filter that lost its fixes and kept its confidence (the error
# grows, the claimed sigma does not) is there for good.
LOST_NEES = 30.66
LOST_HOLD_S = 10.0


def position_errors_ned_m(tel: pd.DataFrame) -> np.ndarray:
    """nav - truth position (m), shape (n, 3), NED."""
    return np.stack(
        [column(tel, f"nav_{a}_m") - column(tel, f"truth_{a}_m") for a in ("north", "east", "down")], axis=1
    )


def horizontal_error_m(tel: pd.DataFrame) -> np.ndarray:
    """|nav - truth| in the north-east plane (m), shape (n,)."""
    e = position_errors_ned_m(tel)
    return np.hypot(e[:, 0], e[:, 1])


def horizontal_sigma_max_m(tel: pd.DataFrame) -> np.ndarray:
    """The claimed horizontal sigma in its worst direction (m), shape (n,): the square root of
    the larger eigenvalue of each row's north-east covariance (closed form for 2 x 2)."""
    sn2, se2 = column(tel, "nav_sigma_north_m") ** 2, column(tel, "nav_sigma_east_m") ** 2
    cne = np.nan_to_num(column(tel, "nav_cov_ne_m2"), nan=0.0)
    tr, det = sn2 + se2, sn2 * se2 - cne * cne
    return np.sqrt(0.5 * tr + np.sqrt(np.maximum(0.25 * tr * tr - det, 0.0)))


def row_durations_s(tel: pd.DataFrame) -> np.ndarray:
    """Time each row stands for (s): the step to the vehicle's next row (last: median step)."""
    t = column(tel, "t_s")
    ids = tel["vehicle_id"].to_numpy()
    out = np.zeros(len(tel))
    for vid in pd.unique(ids):
        sel = np.flatnonzero(ids == vid)
        tv = t[sel]
        if tv.size < 2:
            continue
        dt = np.diff(tv)
        out[sel[:-1]] = dt
        out[sel[-1]] = float(np.median(dt))
    return out


def _position_covariance(tel: pd.DataFrame):
    """The estimate's position covariance per row as (sn2, se2, sd2, cne, det, ok): the north,
    east and down variances (m^2), the north-east covariance (m^2), the north-east block's
    determinant (m^4; 1 where unusable) and whether the row's covariance is usable, each (n,)."""
    sn2 = column(tel, "nav_sigma_north_m") ** 2
    se2 = column(tel, "nav_sigma_east_m") ** 2
    sd2 = column(tel, "nav_sigma_down_m") ** 2
    cne = np.nan_to_num(column(tel, "nav_cov_ne_m2"), nan=0.0)
    det = sn2 * se2 - cne * cne
    ok = (det > 0) & (sn2 > 0) & (sd2 > 0) & np.isfinite(det) & np.isfinite(sd2)
    return sn2, se2, sd2, cne, np.where(ok, det, 1.0), ok


def ne_quadratic_form(en, ee, sn2, se2, cne, det):
    """e^T P^-1 e of north-east errors (en, ee, m) against P = [[sn2, cne], [cne, se2]] (m^2)
    of determinant det (m^4), by the closed-form 2x2 inverse; arrays broadcast together."""
    return (se2 * en * en - 2.0 * cne * en * ee + sn2 * ee * ee) / det


def position_nees(tel: pd.DataFrame) -> np.ndarray:
    """Position NEES per row (3 dof), NaN where the covariance is unusable, shape (n,)."""
    e = position_errors_ned_m(tel)
    sn2, se2, sd2, cne, det, ok = _position_covariance(tel)
    en, ee, ed = e[:, 0], e[:, 1], e[:, 2]
    # The north-east block's NEES plus the independent down term.
    horiz = ne_quadratic_form(en, ee, sn2, se2, cne, det)
    nees = horiz + ed * ed / np.where(ok, sd2, 1.0)
    return np.where(ok, nees, np.nan)


def position_errors_whitened(tel: pd.DataFrame) -> np.ndarray:
    """nav - truth position whitened by the estimate's own covariance, z = L^-1 e with
    P = L L^T (north-east block with its covariance, down apart), shape (n, 3), unitless; NaN
    where the covariance is unusable. A consistent filter's z has unit variance per component
    and z.z is the position NEES."""
    e = position_errors_ned_m(tel)
    sn2, _, sd2, cne, det, ok = _position_covariance(tel)
    l11 = np.sqrt(np.where(ok, sn2, 1.0))
    l21 = np.where(ok, cne, 0.0) / l11
    l22 = np.sqrt(det / np.where(ok, sn2, 1.0))
    z1 = e[:, 0] / l11
    z = np.stack([z1, (e[:, 1] - l21 * z1) / l22, e[:, 2] / np.sqrt(np.where(ok, sd2, 1.0))], axis=1)
    return np.where(ok[:, None], z, np.nan)


def lost_at_s(tel: pd.DataFrame) -> float | None:
    """Earliest time (s) from which some vehicle's position NEES stays above LOST_NEES for at
    least LOST_HOLD_S (rows without a covariance break a streak); None if it never does."""
    nees = position_nees(tel)
    t_all = column(tel, "t_s")
    ids = tel["vehicle_id"].to_numpy() if "vehicle_id" in tel else np.zeros(len(tel))
    first: float | None = None
    for vid in pd.unique(ids):
        sel = ids == vid
        t = t_all[sel]
        above = np.nan_to_num(nees[sel], nan=0.0) > LOST_NEES
        # Streaks of consecutive rows above: starts where above begins, ends where it stops.
        edges = np.diff(np.r_[0, above.astype(np.int8), 0])
        for i0, i1 in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)):
            if t[i1 - 1] - t[i0] >= LOST_HOLD_S:
                first = float(t[i0]) if first is None else min(first, float(t[i0]))
                break
    return first


def _diag_nees(err: np.ndarray, sig: np.ndarray) -> np.ndarray:
    ok = np.all(np.isfinite(sig) & (sig > 0), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.sum((err / sig) ** 2, axis=1)
    return np.where(ok, v, np.nan)


def velocity_nees(tel: pd.DataFrame) -> np.ndarray:
    """Velocity NEES per row (3 dof, diagonal sigmas), shape (n,)."""
    axes = ("vn", "ve", "vd")
    err = np.stack([column(tel, f"nav_{a}_mps") - column(tel, f"truth_{a}_mps") for a in axes], axis=1)
    sig = np.stack([column(tel, f"nav_sigma_{a}_mps") for a in axes], axis=1)
    return _diag_nees(err, sig)


def attitude_nees(tel: pd.DataFrame) -> np.ndarray:
    """Attitude NEES per row (3 dof) on wrapped Euler-angle errors and Euler sigmas, shape (n,)."""
    axes = ("roll", "pitch", "yaw")
    err = np.stack([wrap_pi(column(tel, f"nav_{a}_rad") - column(tel, f"truth_{a}_rad")) for a in axes], axis=1)
    sig = np.stack([column(tel, f"nav_sigma_{a}_rad") for a in axes], axis=1)
    return _diag_nees(err, sig)


def wind_errors_ne_mps(tel: pd.DataFrame) -> np.ndarray | None:
    """(n, 2) estimated minus true horizontal wind (north, east, m/s), NaN on rows without an
    estimate; None when the record has no wind columns or no row with an estimate."""
    if "nav_wind_n_mps" not in tel.columns:
        return None
    err = np.stack([column(tel, f"nav_wind_{a}_mps") - column(tel, f"truth_wind_{a}_mps") for a in ("n", "e")], axis=1)
    return err if np.isfinite(err).all(axis=1).any() else None


def wind_nees(tel: pd.DataFrame, err: np.ndarray) -> np.ndarray:
    """Horizontal wind NEES per row (2 dof, diagonal sigmas), shape (n,), of the wind errors
    err (n, 2) (wind_errors_ne_mps)."""
    sig = np.stack([column(tel, f"nav_sigma_wind_{a}_mps") for a in ("n", "e")], axis=1)
    return _diag_nees(err, sig)


def boresight_errors_rad(record: RunRecord) -> tuple[np.ndarray, np.ndarray] | None:
    """((n, 3) estimated minus true boresight, (n, 3) claimed sigmas), rotation vectors in body
    axes (rad), NaN on rows without an estimate; None when the record has no boresight columns
    or no row with an estimate. The truth: run.json camera_boresight_error_deg (Z-Y-X angles)
    of the camera camera_boresight_estimated names, zero when that camera has none."""
    tel = record.telemetry
    if "nav_boresight_x_rad" not in tel.columns:
        return None
    est = np.stack([column(tel, f"nav_boresight_{a}_rad") for a in "xyz"], axis=1)
    sig = np.stack([column(tel, f"nav_sigma_boresight_{a}_rad") for a in "xyz"], axis=1)
    truth = np.zeros_like(est)
    errors = record.run_info.get("camera_boresight_error_deg") or {}
    vehicles = tel["vehicle_id"].to_numpy()
    for vid, camera in (record.run_info.get("camera_boresight_estimated") or {}).items():
        rpy_deg = (errors.get(vid) or {}).get(camera)
        if rpy_deg is not None:
            truth[vehicles == vid] = quat_to_rotvec(dcm_to_quat(euler_to_dcm(np.radians(rpy_deg))))
    err = est - truth
    return (err, sig) if np.isfinite(err).all(axis=1).any() else None


def camera_boresight_stats(record: RunRecord, err: np.ndarray, sig: np.ndarray) -> CameraBoresightStats:
    """CameraBoresightStats of the boresight errors err (n, 3) and sigmas sig (n, 3) (rad,
    boresight_errors_rad)."""
    norm_deg = np.degrees(np.linalg.norm(err, axis=1))
    denied = denied_mask(record) & np.isfinite(norm_deg)
    finals, sigmas = [], []
    vehicles = record.telemetry["vehicle_id"].to_numpy()
    for vid in np.unique(vehicles):
        rows = np.flatnonzero((vehicles == vid) & np.isfinite(norm_deg))
        if len(rows):
            finals.append(norm_deg[rows[-1]])
            sigmas.append(float(np.degrees(np.linalg.norm(sig[rows[-1]]))))
    return CameraBoresightStats(error_deg=error_stats(norm_deg[denied] if denied.any() else norm_deg),
                                final_error_deg=max(finals) if finals else None,
                                final_sigma_deg=max(sigmas) if sigmas else None)


def time_offset_errors_s(record: RunRecord) -> tuple[np.ndarray, np.ndarray] | None:
    """((n,) estimated minus true camera time offset, (n,) claimed sigma), s, NaN on rows
    without an estimate; None when the record has no time offset columns or no estimate. The
    truth: run.json camera_time_offset_s of the camera camera_time_offset_estimated names."""
    tel = record.telemetry
    if "nav_camera_time_offset_s" not in tel.columns:
        return None
    est, sig = column(tel, "nav_camera_time_offset_s"), column(tel, "nav_sigma_camera_time_offset_s")
    truth = np.zeros_like(est)
    offsets = record.run_info.get("camera_time_offset_s") or {}
    vehicles = tel["vehicle_id"].to_numpy()
    for vid, camera in (record.run_info.get("camera_time_offset_estimated") or {}).items():
        truth[vehicles == vid] = float((offsets.get(vid) or {}).get(camera, 0.0))
    err = est - truth
    return (err, sig) if np.isfinite(err).any() else None


def camera_time_offset_stats(record: RunRecord, err: np.ndarray, sig: np.ndarray) -> CameraTimeOffsetStats:
    """CameraTimeOffsetStats of the time offset errors err (n,) and sigmas sig (n,) (s)."""
    err_ms, sig_ms = 1e3 * np.abs(err), 1e3 * sig
    ok = np.isfinite(err_ms)
    denied = denied_mask(record) & ok
    vehicles = record.telemetry["vehicle_id"].to_numpy()
    last = [np.flatnonzero((vehicles == vid) & ok)[-1] for vid in np.unique(vehicles[ok])]
    return CameraTimeOffsetStats(error_ms=error_stats(err_ms[denied] if denied.any() else err_ms[ok]),
                                 final_error_ms=max(float(err_ms[i]) for i in last) if last else None,
                                 final_sigma_ms=max(float(sig_ms[i]) for i in last) if last else None)


_INTRINSICS = ("pp_u_px", "pp_v_px", "focal_rel")


def intrinsics_errors(record: RunRecord) -> tuple[np.ndarray, np.ndarray] | None:
    """((n, 3) estimated minus true intrinsics error, (n, 3) claimed sigmas): principal point
    u, v (px), focal length (relative); NaN on rows without an estimate; None when the record
    has no intrinsics columns or no estimate. The truth: run.json camera_intrinsics_error of
    the camera camera_intrinsics_estimated names (zero when it has none)."""
    tel = record.telemetry
    if "nav_camera_pp_u_px" not in tel.columns:
        return None
    est = np.stack([column(tel, f"nav_camera_{k}") for k in _INTRINSICS], axis=1)
    sig = np.stack([column(tel, f"nav_sigma_camera_{k}") for k in _INTRINSICS], axis=1)
    truth = np.zeros_like(est)
    errors = record.run_info.get("camera_intrinsics_error") or {}
    vehicles = tel["vehicle_id"].to_numpy()
    for vid, camera in (record.run_info.get("camera_intrinsics_estimated") or {}).items():
        e = (errors.get(vid) or {}).get(camera)
        if e is not None:
            truth[vehicles == vid] = [*e["principal_point_error_px"], e["focal_error_rel"]]
    err = est - truth
    return (err, sig) if np.isfinite(err).all(axis=1).any() else None


def camera_intrinsics_stats(record: RunRecord, err: np.ndarray, sig: np.ndarray) -> CameraIntrinsicsStats:
    """CameraIntrinsicsStats of the intrinsics errors err (n, 3) and sigmas sig (n, 3)
    (intrinsics_errors)."""
    pp_px = np.linalg.norm(err[:, :2], axis=1)
    ok = np.isfinite(pp_px) & np.isfinite(err[:, 2])
    denied = denied_mask(record) & ok
    vehicles = record.telemetry["vehicle_id"].to_numpy()
    last = [np.flatnonzero((vehicles == vid) & ok)[-1] for vid in np.unique(vehicles[ok])]

    def worst(values):
        return max(float(x) for x in values) if last else None

    return CameraIntrinsicsStats(
        principal_point_error_px=error_stats(pp_px[denied] if denied.any() else pp_px[ok]),
        final_principal_point_error_px=worst(pp_px[i] for i in last),
        final_principal_point_sigma_px=worst(np.linalg.norm(sig[i, :2]) for i in last),
        final_focal_error_ppm=worst(1e6 * abs(err[i, 2]) for i in last),
        final_focal_sigma_ppm=worst(1e6 * sig[i, 2] for i in last))


def _subset(e3: np.ndarray, eh: np.ndarray, pct: np.ndarray, dur: np.ndarray, mask: np.ndarray) -> NavSubset | None:
    if not mask.any():
        return None
    return NavSubset(
        position_error_m=error_stats(np.linalg.norm(e3[mask], axis=1)),
        horizontal_error_m=error_stats(eh[mask], cep=True),
        horizontal_error_pct_agl=error_stats(pct[mask]),
        duration_s=float(np.sum(dur[mask])),
    )


def _windows_mask(record: RunRecord, key: str) -> np.ndarray:
    """True on telemetry rows inside run.json's per-vehicle windows `key` (vehicle id ->
    [[start_s, end_s], ...]), shape (n,)."""
    tel = record.telemetry
    mask = np.zeros(len(tel), dtype=bool)
    t = column(tel, "t_s")
    ids = tel["vehicle_id"].to_numpy()
    for vid, windows in (record.run_info.get(key) or {}).items():
        for start, end in windows:
            mask |= (ids == str(vid)) & (t >= float(start)) & (t <= float(end))
    return mask


def spoofed_subset(record: RunRecord, e3: np.ndarray, eh: np.ndarray, pct: np.ndarray, dur: np.ndarray,
                   valid: np.ndarray) -> SpoofedNav | None:
    """SpoofedNav over the rows inside run.json gnss_spoofed_windows (None without such rows):
    the error figures as for any subset, and from events/corrections.parquet the GNSS fixes
    of those windows (kinds "gnss", "gnss:reset", and "gnss:excluded" while the spoofing monitor
    held GNSS out): how many the filter fused ("gnss" accepted, or "gnss:reset") and how long
    after each window's start it fused the last of them."""
    base = _subset(e3, eh, pct, dur, _windows_mask(record, "gnss_spoofed_windows") & valid)
    if base is None:
        return None
    cor = record.event("corrections")
    fused: list[bool] = []
    captured_s: list[float] = []
    if cor is not None and len(cor):
        kinds = cor["kind"].astype(str).to_numpy()
        is_gnss = (kinds == "gnss") | (kinds == "gnss:reset") | (kinds == "gnss:excluded")
        took = is_gnss & (column(cor, "accepted", dtype=bool).astype(bool) | (kinds == "gnss:reset"))
        t = column(cor, "t_s")
        ids = cor["vehicle_id"].astype(str).to_numpy()
        for vid, windows in (record.run_info.get("gnss_spoofed_windows") or {}).items():
            for start, end in windows:
                inside = is_gnss & (ids == str(vid)) & (t >= float(start)) & (t <= float(end))
                if not inside.any():
                    continue
                fused.extend(took[inside].tolist())
                taken_t = t[inside & took]
                captured_s.append(float(taken_t.max()) - float(start) if len(taken_t) else 0.0)
    return SpoofedNav(**{f.name: getattr(base, f.name) for f in dataclasses.fields(base)},
                      gnss_accept_rate=float(np.mean(fused)) if fused else None,
                      gnss_captured_s=max(captured_s) if captured_s else None)


def denied_mask(record: RunRecord) -> np.ndarray:
    """True on telemetry rows where GNSS was not available to the navigator, shape (n,).

    From the gnss_available column; when it was not recorded, from run.json
    gnss_denied_windows (vehicle id -> [[start_s, end_s], ...]).
    """
    tel = record.telemetry
    if "gnss_available" in tel.columns:
        return ~tel["gnss_available"].to_numpy().astype(bool)
    return _windows_mask(record, "gnss_denied_windows")


def compute_nis(record: RunRecord) -> dict[str, NisStats]:
    """Correction kind -> NisStats from events/corrections.parquet (empty when absent)."""
    cor = record.event("corrections")
    if cor is None:
        return {}
    out = {}
    kinds = cor["kind"].astype(str).to_numpy()
    for kind in sorted(pd.unique(kinds)):
        sub = cor[kinds == kind]
        accepted = column(sub, "accepted", dtype=bool).astype(bool)
        out[str(kind)] = NisStats(
            count=int(len(sub)),
            accept_rate=float(np.mean(accepted)),
            chi2=chi_square_stats(column(sub, "nis"), column(sub, "dim")),
        )
    return out


def compute_nav(record: RunRecord) -> NavMetrics | None:
    """NavMetrics of the record's telemetry (all vehicles it holds); None without rows."""
    tel = record.telemetry
    if len(tel) == 0:
        return None
    e3 = position_errors_ned_m(tel)
    # Rows where the navigator had no estimate yet (NaN) are dropped by error_stats; the 3D
    # and horizontal samples are taken on the same rows so that they stay comparable.
    valid = np.all(np.isfinite(e3), axis=1)
    e3 = np.where(valid[:, None], e3, np.nan)
    eh = np.hypot(e3[:, 0], e3[:, 1])
    agl = column(tel, "truth_height_agl_m")
    with np.errstate(divide="ignore", invalid="ignore"):
        pct = np.where(agl > MIN_AGL_FOR_PCT_M, 100.0 * eh / agl, np.nan)
    dur = row_durations_s(tel)
    turning = telemetry_turning(record)

    nees: dict[str, ChiSquareStats] = {}
    for name, fn in (("position", position_nees), ("velocity", velocity_nees), ("attitude", attitude_nees)):
        s = chi_square_stats(fn(tel), 3)
        if s is not None:
            nees[name] = s
    wind_err = wind_errors_ne_mps(tel)
    if wind_err is not None:
        s = chi_square_stats(wind_nees(tel, wind_err), 2)
        if s is not None:
            nees["wind"] = s
    # The camera states' estimates against the camera's truth (diagonal sigmas).
    boresight = boresight_errors_rad(record)
    time_offset = time_offset_errors_s(record)
    intrinsics = intrinsics_errors(record)
    for name, errors, dof in (("camera_boresight", boresight, 3), ("camera_time_offset", time_offset, 1),
                              ("camera_intrinsics", intrinsics, 3)):
        if errors is not None:
            err, sig = (np.asarray(x, float).reshape(len(x), -1) for x in errors)
            s = chi_square_stats(_diag_nees(err, sig), dof)
            if s is not None:
                nees[name] = s

    return NavMetrics(
        position_error_m=error_stats(np.linalg.norm(e3, axis=1)),
        horizontal_error_m=error_stats(eh, cep=True),
        vertical_error_m=error_stats(e3[:, 2]),
        horizontal_error_pct_agl=error_stats(pct),
        denied=_subset(e3, eh, pct, dur, denied_mask(record) & valid),
        spoofed=spoofed_subset(record, e3, eh, pct, dur, valid),
        smooth=_subset(e3, eh, pct, dur, ~turning & valid),
        turning=_subset(e3, eh, pct, dur, turning & valid),
        nees=nees,
        nis=compute_nis(record),
        lost_at_s=lost_at_s(tel),
        wind_error_mps=None if wind_err is None else error_stats(np.hypot(wind_err[:, 0], wind_err[:, 1])),
        gnss_sky=gnss_sky_stats(record),
        camera_boresight=None if boresight is None else camera_boresight_stats(record, *boresight),
        camera_time_offset=None if time_offset is None else camera_time_offset_stats(record, *time_offset),
        camera_intrinsics=None if intrinsics is None else camera_intrinsics_stats(record, *intrinsics),
    )


def gnss_sky_stats(record: RunRecord) -> GnssSkyStats | None:
    """GnssSkyStats of the record's gnss_sky table (all vehicles it holds), None without one."""
    sky = record.event("gnss_sky")
    if sky is None:
        return None
    seen = column(sky, "satellites_visible")
    fix = sky["fix"].to_numpy().astype(bool)
    hdop = column(sky, "hdop")[fix]
    return GnssSkyStats(
        satellites_visible_mean=float(np.mean(seen)),
        satellites_visible_min=int(np.min(seen)),
        satellites_above_mask_mean=float(np.mean(column(sky, "satellites_above_mask"))),
        fix_share=float(np.mean(fix)),
        hdop=error_stats(hdop) if len(hdop) else None,
        hdop_open_sky_median=float(np.nanmedian(column(sky, "hdop_open_sky"))),
        samples=int(len(sky)),
    )
