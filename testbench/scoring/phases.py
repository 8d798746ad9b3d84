"""Flight phases: smooth flight vs turning, from the TRUE attitude and body rates.

A sample is "turning" when |roll| > turn_bank_deg or |turn rate| > turn_rate_deg_s
(thresholds from run.json "phases"). The turn rate is the rate of the Z-Y-X Euler yaw, from
the body rates through the Euler kinematics (exact, no numerical differentiation):
    psi_dot = (q sin(phi) + r cos(phi)) / cos(theta).
When the body rates were not recorded it falls back to the time derivative of the unwrapped
truth yaw.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from testbench.scoring.record_io import RunRecord, column

SMOOTH = "smooth"
TURNING = "turning"
PHASES = (SMOOTH, TURNING)


def turn_rate_rps(tel: pd.DataFrame) -> np.ndarray:
    """Yaw (heading) rate in rad/s of one vehicle's telemetry rows (time-ordered), shape (n,)."""
    roll = column(tel, "truth_roll_rad")
    pitch = column(tel, "truth_pitch_rad")
    q = column(tel, "truth_q_rps")
    r = column(tel, "truth_r_rps")
    if np.isfinite(q).any() and np.isfinite(r).any():
        # Euler kinematics; cos(theta) is far from zero in any flight phase we score.
        return (q * np.sin(roll) + r * np.cos(roll)) / np.cos(pitch)
    yaw = column(tel, "truth_yaw_rad")
    t = column(tel, "t_s")
    ok = np.isfinite(yaw) & np.isfinite(t)
    out = np.full(len(tel), np.nan)
    if ok.sum() >= 2:
        out[ok] = np.gradient(np.unwrap(yaw[ok]), t[ok])
    return out


def is_turning(roll_rad, turn_rate_rps, phases: dict[str, float]) -> np.ndarray:
    """Boolean mask, True where |roll| or |turn rate| exceeds the phase thresholds.

    NaN inputs count as not exceeding (a NaN rate with a small bank is smooth).
    """
    bank_thr = np.deg2rad(phases["turn_bank_deg"])
    rate_thr = np.deg2rad(phases["turn_rate_deg_s"])
    roll = np.abs(np.asarray(roll_rad, float))
    rate = np.abs(np.asarray(turn_rate_rps, float))
    return (np.nan_to_num(roll, nan=0.0) > bank_thr) | (np.nan_to_num(rate, nan=0.0) > rate_thr)


def telemetry_turning(record: RunRecord) -> np.ndarray:
    """Turning mask aligned with record.telemetry rows (computed per vehicle), shape (n,)."""
    tel = record.telemetry
    mask = np.zeros(len(tel), dtype=bool)
    ids = tel["vehicle_id"].to_numpy()
    for vid in pd.unique(ids):
        sel = np.flatnonzero(ids == vid)
        sub = tel.iloc[sel]
        mask[sel] = is_turning(column(sub, "truth_roll_rad"), turn_rate_rps(sub), record.phases)
    return mask


def event_turning(record: RunRecord, events: pd.DataFrame) -> np.ndarray:
    """Turning mask for event rows (t_s, vehicle_id), shape (len(events),).

    Roll: the event's own truth_roll_rad when recorded, else telemetry interpolated to t_s.
    Turn rate: the vehicle's telemetry turn rate, linearly interpolated to each event time.
    """
    n = len(events)
    roll_ev = column(events, "truth_roll_rad")
    rate_ev = np.full(n, np.nan)
    t_ev = column(events, "t_s")
    ids_ev = events["vehicle_id"].astype(str).to_numpy() if n else np.array([], dtype=str)
    for vid in pd.unique(ids_ev):
        sel = ids_ev == vid
        tel = record.vehicle_telemetry(str(vid))
        if len(tel) == 0:
            continue
        t = column(tel, "t_s")
        rate = turn_rate_rps(tel)
        ok = np.isfinite(rate) & np.isfinite(t)
        if ok.any():
            rate_ev[sel] = np.interp(t_ev[sel], t[ok], rate[ok])
        roll = column(tel, "truth_roll_rad")
        need = sel & ~np.isfinite(roll_ev)
        okr = np.isfinite(roll) & np.isfinite(t)
        if need.any() and okr.any():
            roll_ev[need] = np.interp(t_ev[need], t[okr], roll[okr])
    return is_turning(roll_ev, rate_ev, record.phases)
