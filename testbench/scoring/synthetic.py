"""Synthetic run records with known statistics, for tests, demos and report previews.

`write_record` writes a run directory in the recorder's layout from in-memory tables;
`make_synthetic_run` fabricates a plausible one (racetrack flight, GNSS-denied window,
navigation errors drawn from the covariance the "navigator" reports, ISMN fixes, relative
navigation and formation events) so that scoring and reports can be exercised without the
engine. Errors are drawn from N(0, P) exactly, so NEES/NIS statistics are consistent by
construction. Randomness only from the injected numpy Generator.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pandas as pd

from testbench.core.rotations import euler_to_quat

G_MPS2 = 9.80665


def write_record(
    run_dir: str | Path,
    telemetry: pd.DataFrame,
    run_info: Mapping[str, Any],
    events: Mapping[str, pd.DataFrame] | None = None,
    scenario_text: str = "",
) -> Path:
    """Write a run directory (telemetry.parquet, events/*.parquet, run.json, scenario.yaml)."""
    run_dir = Path(run_dir)
    (run_dir / "events").mkdir(parents=True, exist_ok=True)
    telemetry.to_parquet(run_dir / "telemetry.parquet", index=False)
    for name, df in (events or {}).items():
        df.to_parquet(run_dir / "events" / f"{name}.parquet", index=False)
    (run_dir / "run.json").write_text(json.dumps(dict(run_info), indent=2))
    if scenario_text:
        (run_dir / "scenario.yaml").write_text(scenario_text)
    return run_dir


def _racetrack(t: np.ndarray, speed_mps: float, leg_s: float, bank_rad: float):
    """Heading, turn rate and roll of a racetrack: straight legs joined by 180 deg turns."""
    omega = G_MPS2 * np.tan(bank_rad) / speed_mps
    turn_s = np.pi / omega
    period = 2.0 * (leg_s + turn_s)
    phase = np.mod(t, period)
    seg = np.floor(t / period)
    in_turn1 = (phase >= leg_s) & (phase < leg_s + turn_s)
    in_turn2 = phase >= 2 * leg_s + turn_s
    # Heading: 0 on leg 1, pi on leg 2; grows by omega through each turn (continuous, unwrapped).
    yaw = np.where(phase < leg_s, 0.0, 0.0)
    yaw = np.where(in_turn1, omega * (phase - leg_s), yaw)
    yaw = np.where((phase >= leg_s + turn_s) & ~in_turn2, np.pi, yaw)
    yaw = np.where(in_turn2, np.pi + omega * (phase - 2 * leg_s - turn_s), yaw)
    yaw = yaw + 2 * np.pi * seg
    turning = in_turn1 | in_turn2
    rate = np.where(turning, omega, 0.0)
    roll = np.where(turning, bank_rad, 0.0)
    on_leg = ~turning
    leg_id = (2 * seg + (phase >= leg_s + turn_s)).astype(np.int64)
    return yaw, rate, roll, on_leg, leg_id


def _correlated_normal(rng: np.random.Generator, n: int, dim: int, corr: float) -> np.ndarray:
    """AR(1) standard normals (marginally N(0, 1) exactly), shape (n, dim)."""
    z = np.empty((n, dim))
    z[0] = rng.standard_normal(dim)
    k = np.sqrt(1.0 - corr * corr)
    w = rng.standard_normal((n, dim))
    for i in range(1, n):
        z[i] = corr * z[i - 1] + k * w[i]
    return z


def synthetic_vehicle_telemetry(
    rng: np.random.Generator,
    vehicle_id: str,
    t: np.ndarray,
    *,
    offset_ne_m=(0.0, 0.0),
    altitude_m: float = 300.0,
    speed_mps: float = 25.0,
    leg_s: float = 30.0,
    bank_deg: float = 25.0,
    denied=(40.0, 90.0),
) -> pd.DataFrame:
    """Telemetry of one vehicle flying a racetrack with nav errors drawn from N(0, P)."""
    n = t.size
    dt = float(t[1] - t[0]) if n > 1 else 0.1
    yaw, rate, roll, on_leg, leg_id = _racetrack(t, speed_mps, leg_s, np.deg2rad(bank_deg))
    vn, ve = speed_mps * np.cos(yaw), speed_mps * np.sin(yaw)
    north = offset_ne_m[0] + np.concatenate([[0.0], np.cumsum(vn[:-1] * dt)])
    east = offset_ne_m[1] + np.concatenate([[0.0], np.cumsum(ve[:-1] * dt)])
    # A slow altitude wobble and lateral wander so that control errors are not zero.
    down = -(altitude_m + 2.0 * np.sin(0.2 * t))
    lateral = 3.0 * np.sin(0.13 * t)
    north = north - lateral * np.sin(yaw)
    east = east + lateral * np.cos(yaw)
    gnss = ~((t >= denied[0]) & (t <= denied[1])) if denied else np.ones(n, bool)

    # Reported position sigma: 2 m with GNSS, growing 0.2 m/s while denied.
    since = np.where(gnss, 0.0, t - (denied[0] if denied else 0.0))
    s_n = 2.0 + 0.2 * since
    s_e = 1.5 + 0.15 * since
    s_d = 3.0 + 0.05 * since
    rho = 0.3
    z = _correlated_normal(rng, n, 3, 0.8)
    e_n = s_n * z[:, 0]
    e_e = s_e * (rho * z[:, 0] + np.sqrt(1 - rho * rho) * z[:, 1])
    e_d = s_d * z[:, 2]
    s_v = np.array([0.2, 0.2, 0.3])
    ev = s_v * _correlated_normal(rng, n, 3, 0.8)
    s_att = np.deg2rad([0.5, 0.5, 2.0])
    eatt = s_att * _correlated_normal(rng, n, 3, 0.8)

    pitch = np.full(n, np.deg2rad(2.0))
    q_true = euler_to_quat(np.stack([roll, pitch, yaw], axis=1))
    nav_rpy = np.stack([roll, pitch, yaw], axis=1) + eatt
    q_nav = euler_to_quat(nav_rpy)
    # Guidance lines: leg k runs along the track centre line x = offset at heading 0 or pi.
    leg_len = speed_mps * leg_s
    northbound = np.mod(leg_id, 2) == 0
    line_e = offset_ne_m[1] + np.where(northbound, 0.0, 2 * speed_mps / (G_MPS2 * np.tan(np.deg2rad(bank_deg))) * speed_mps)
    line_sn = offset_ne_m[0] + np.where(northbound, 0.0, leg_len)
    line_en = offset_ne_m[0] + np.where(northbound, leg_len, 0.0)
    p_rps = np.zeros(n)
    # Body rates that give the wanted Euler yaw rate: psi_dot = (q sin(phi) + r cos(phi)) / cos(theta).
    q_rps = rate * np.cos(pitch) * np.sin(roll)
    r_rps = rate * np.cos(pitch) * np.cos(roll)
    cols = {
        "vehicle_id": [vehicle_id] * n,
        "t_s": t,
        "truth_north_m": north, "truth_east_m": east, "truth_down_m": down,
        "truth_vn_mps": vn, "truth_ve_mps": ve, "truth_vd_mps": np.zeros(n),
        "truth_roll_rad": roll, "truth_pitch_rad": pitch, "truth_yaw_rad": np.mod(yaw + np.pi, 2 * np.pi) - np.pi,
        "truth_qw": q_true[:, 0], "truth_qx": q_true[:, 1], "truth_qy": q_true[:, 2], "truth_qz": q_true[:, 3],
        "truth_p_rps": p_rps, "truth_q_rps": q_rps, "truth_r_rps": r_rps,
        "truth_airspeed_mps": speed_mps + 0.5 * np.sin(0.3 * t),
        "truth_height_agl_m": -down,
        "truth_lat_deg": 47.0 + north / 111_000.0, "truth_lon_deg": -99.0 + east / 76_000.0, "truth_alt_m": 500.0 - down,
        "nav_north_m": north + e_n, "nav_east_m": east + e_e, "nav_down_m": down + e_d,
        "nav_vn_mps": vn + ev[:, 0], "nav_ve_mps": ve + ev[:, 1], "nav_vd_mps": ev[:, 2],
        "nav_roll_rad": nav_rpy[:, 0], "nav_pitch_rad": nav_rpy[:, 1], "nav_yaw_rad": np.mod(nav_rpy[:, 2] + np.pi, 2 * np.pi) - np.pi,
        "nav_qw": q_nav[:, 0], "nav_qx": q_nav[:, 1], "nav_qy": q_nav[:, 2], "nav_qz": q_nav[:, 3],
        "nav_sigma_north_m": s_n, "nav_sigma_east_m": s_e, "nav_sigma_down_m": s_d,
        "nav_cov_ne_m2": rho * s_n * s_e,
        "nav_sigma_vn_mps": np.full(n, s_v[0]), "nav_sigma_ve_mps": np.full(n, s_v[1]), "nav_sigma_vd_mps": np.full(n, s_v[2]),
        "nav_sigma_roll_rad": np.full(n, s_att[0]), "nav_sigma_pitch_rad": np.full(n, s_att[1]), "nav_sigma_yaw_rad": np.full(n, s_att[2]),
        "cmd_0": -0.1 * roll, "cmd_1": np.full(n, -0.05), "cmd_2": np.zeros(n), "cmd_3": np.full(n, 0.7),
        "gd_leg_index": leg_id, "gd_on_leg": on_leg, "gd_alt_cmd_m": np.full(n, altitude_m),
        "gd_airspeed_cmd_mps": np.full(n, speed_mps),
        "gd_line_start_n_m": line_sn, "gd_line_start_e_m": line_e,
        "gd_line_end_n_m": line_en, "gd_line_end_e_m": line_e,
        "gd_target_n_m": line_en, "gd_target_e_m": line_e, "gd_target_d_m": np.full(n, -altitude_m),
        "gd_bank_cmd_rad": roll,
        "gnss_available": gnss,
    }
    return pd.DataFrame(cols)


def _texture(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """A smooth random RGB texture (uint8, (h, w, 3)): fields and blobs, for fake imagery."""
    small = rng.random((max(h // 16, 2), max(w // 16, 2), 3))
    yi = np.linspace(0, small.shape[0] - 1, h)
    xi = np.linspace(0, small.shape[1] - 1, w)
    y0 = np.floor(yi).astype(int).clip(0, small.shape[0] - 2)
    x0 = np.floor(xi).astype(int).clip(0, small.shape[1] - 2)
    fy = (yi - y0)[:, None, None]
    fx = (xi - x0)[None, :, None]
    a = small[y0][:, x0]
    b = small[y0][:, x0 + 1]
    c = small[y0 + 1][:, x0]
    d = small[y0 + 1][:, x0 + 1]
    img = (a * (1 - fx) + b * fx) * (1 - fy) + (c * (1 - fx) + d * fx) * fy
    img = 0.25 + 0.5 * img + 0.05 * rng.standard_normal((h, w, 3))
    return (255 * img.clip(0, 1)).astype(np.uint8)


def _ismn_events(rng, tel: pd.DataFrame, rate_hz: float) -> pd.DataFrame:
    t = tel["t_s"].to_numpy()
    step = max(int(round(1.0 / (rate_hz * (t[1] - t[0])))), 1)
    sub = tel.iloc[::step]
    sub = sub[~sub["gnss_available"].to_numpy()]
    n = len(sub)
    turning = np.abs(sub["truth_roll_rad"].to_numpy()) > np.deg2rad(10)
    fix = rng.random(n) < np.where(turning, 0.7, 0.95)
    sig = np.where(turning, 10.0, 3.0)
    en, ee = sig * rng.standard_normal(n), sig * rng.standard_normal(n)
    tn, te, td = (sub[f"truth_{a}_m"].to_numpy() for a in ("north", "east", "down"))
    return pd.DataFrame({
        "t_s": sub["t_s"].to_numpy(), "vehicle_id": sub["vehicle_id"].to_numpy(),
        "attempted": np.ones(n, bool), "fix": fix, "accepted": fix & (rng.random(n) < 0.95),
        "fix_north_m": np.where(fix, tn + en, np.nan), "fix_east_m": np.where(fix, te + ee, np.nan),
        "fix_down_m": np.where(fix, td, np.nan),
        "truth_north_m": tn, "truth_east_m": te, "truth_down_m": td,
        "sigma_north_m": sig, "sigma_east_m": sig, "sigma_down_m": sig, "quality": rng.random(n),
        "latency_ms": 40.0 + 10.0 * rng.gamma(2.0, 1.0, n),
        "truth_roll_rad": sub["truth_roll_rad"].to_numpy(), "truth_height_agl_m": sub["truth_height_agl_m"].to_numpy(),
        "same_raster": np.zeros(n, bool),
    })


def _corrections(rng, tel: pd.DataFrame) -> pd.DataFrame:
    rows = []
    t = tel["t_s"].to_numpy()
    ids = tel["vehicle_id"].to_numpy()
    gnss = tel["gnss_available"].to_numpy()
    whole = np.isclose(np.mod(t, 1.0), 0.0, atol=1e-6)
    for kind, dim, mask in (("gnss", 3, whole & gnss), ("baro", 1, whole), ("mag", 1, whole)):
        k = int(mask.sum())
        nis = rng.chisquare(dim, k)
        rows.append(pd.DataFrame({"t_s": t[mask], "vehicle_id": ids[mask], "kind": kind, "dim": np.full(k, dim, np.int64),
                                  "nis": nis, "accepted": nis < 16.0}))
    return pd.concat(rows, ignore_index=True).sort_values("t_s", kind="stable").reset_index(drop=True)


def make_synthetic_run(
    run_dir: str | Path,
    rng: np.random.Generator,
    *,
    n_vehicles: int = 1,
    duration_s: float = 120.0,
    rate_hz: float = 10.0,
    with_events: bool = True,
    with_images: bool = True,
    thresholds: Mapping[str, Any] | None = None,
) -> Path:
    """Fabricate a complete run directory; returns it. Vehicles fly side by side 100 m apart."""
    run_dir = Path(run_dir)
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    ids = [f"uav{i}" for i in range(n_vehicles)]
    denied = (0.35 * duration_s, 0.8 * duration_s)
    per = [synthetic_vehicle_telemetry(rng, vid, t, offset_ne_m=(0.0, 100.0 * i), denied=denied) for i, vid in enumerate(ids)]
    tel = pd.concat(per, ignore_index=True)
    order = np.lexsort((np.repeat(np.arange(n_vehicles), t.size), tel["t_s"].to_numpy()))
    tel = tel.iloc[order].reset_index(drop=True)

    events: dict[str, pd.DataFrame] = {"corrections": _corrections(rng, tel)}
    if with_events:
        events["ismn"] = pd.concat([_ismn_events(rng, p, 1.0) for p in per], ignore_index=True).sort_values("t_s", kind="stable")
        if n_vehicles > 1:
            rel = []
            for i, a in enumerate(per):
                for j, b in enumerate(per):
                    if i == j:
                        continue
                    sa, sb = a.iloc[::5], b.iloc[::5]
                    d = np.stack([sb[f"truth_{x}_m"].to_numpy() - sa[f"truth_{x}_m"].to_numpy() for x in ("north", "east", "down")], 1)
                    est = d + 0.3 * rng.standard_normal(d.shape)
                    rel.append(pd.DataFrame({
                        "t_s": sa["t_s"].to_numpy(), "vehicle_id": ids[i], "peer_id": ids[j],
                        "est_north_m": est[:, 0], "est_east_m": est[:, 1], "est_down_m": est[:, 2],
                        "truth_north_m": d[:, 0], "truth_east_m": d[:, 1], "truth_down_m": d[:, 2],
                        "sigma_m": np.full(len(sa), 0.3 * np.sqrt(3)), "id_correct": rng.random(len(sa)) < 0.98}))
            events["relnav"] = pd.concat(rel, ignore_index=True).sort_values("t_s", kind="stable")
            fr = tel[tel["vehicle_id"] != ids[0]].iloc[::5]
            m = len(fr)
            events["formation"] = pd.DataFrame({
                "t_s": fr["t_s"].to_numpy(), "vehicle_id": fr["vehicle_id"].to_numpy(),
                "slot_error_north_m": 2.0 * rng.standard_normal(m), "slot_error_east_m": 2.0 * rng.standard_normal(m),
                "slot_error_down_m": 1.0 * rng.standard_normal(m)})

    info: dict[str, Any] = {
        "scenario_name": "synthetic", "seed": 0, "sim_time_s": float(duration_s), "wall_time_s": float(duration_s) / 20.0,
        "real_time_factor": 20.0, "status": "completed", "abort_reason": None,
        "vehicles": [{"id": vid, "aircraft": "synthetic", "kind": "fixed_wing"} for vid in ids],
        "gnss_denied_windows": {vid: [list(denied)] for vid in ids},
        "phases": {"turn_bank_deg": 10.0, "turn_rate_deg_s": 3.0},
        "origin": {"lat_deg": 47.0, "lon_deg": -99.0, "alt_m": 500.0},
        "same_raster": False,
        "thresholds": dict(thresholds or {}),
    }
    if with_images:
        import cv2  # only for the synthetic images

        (run_dir / "ismn_examples").mkdir(parents=True, exist_ok=True)
        for k in range(2):
            np.savez(run_dir / "ismn_examples" / f"example_{k}.npz",
                     camera=_texture(rng, 90, 160), ortho=_texture(rng, 96, 96), map_window=_texture(rng, 128, 128),
                     t_s=np.float64(50.0 + 10 * k), vehicle_id=np.str_(ids[0]))
        n_min, n_max = float(tel["truth_north_m"].min()) - 200, float(tel["truth_north_m"].max()) + 200
        e_min, e_max = float(tel["truth_east_m"].min()) - 200, float(tel["truth_east_m"].max()) + 200
        cv2.imwrite(str(run_dir / "map.png"), _texture(rng, 256, 256))
        info["map_image"] = {"path": "map.png", "bounds_ne_m": [n_min, n_max, e_min, e_max]}
    scenario_text = f"name: synthetic\nseed: 0\nvehicles: {ids}\nduration_s: {duration_s}\n"
    return write_record(run_dir, tel, info, events, scenario_text)
