import numpy as np
import pandas as pd
import pytest

from scoring_helpers import record_of, straight_telemetry
from testbench.scoring import score_record
from testbench.scoring.metrics_control import compute_control, cross_track_m
from testbench.scoring.metrics_nav import compute_nav, position_errors_whitened, position_nees
from testbench.scoring.phases import event_turning, turn_rate_rps


def test_constant_error_gives_exact_nav_figures():
    tel = straight_telemetry(err_ned=(3.0, 4.0, 12.0))
    nav = compute_nav(record_of(tel))
    for s in (nav.position_error_m,):
        assert (s.mean, s.rms, s.p95, s.max) == pytest.approx((13.0,) * 4)
    h = nav.horizontal_error_m
    assert (h.mean, h.rms, h.max, h.cep50, h.cep95) == pytest.approx((5.0,) * 5)
    assert nav.vertical_error_m.rms == pytest.approx(12.0)
    assert nav.horizontal_error_pct_agl.mean == pytest.approx(5.0)  # 5 m at 100 m AGL
    assert nav.turning is None and nav.smooth.horizontal_error_m.n == len(tel)


def test_nan_estimate_rows_are_dropped():
    tel = straight_telemetry(n=10, err_ned=(1.0, 0.0, 0.0))
    tel.loc[:3, "nav_north_m"] = np.nan
    nav = compute_nav(record_of(tel))
    assert nav.position_error_m.n == 6 and nav.horizontal_error_m.n == 6
    assert nav.position_error_m.max == pytest.approx(1.0)


def test_denied_subset_from_gnss_column_and_from_windows():
    n = 100
    tel = straight_telemetry(n=n, err_ned=(0.0, 0.0, 0.0))
    err = np.where(np.arange(n) >= 50, 10.0, 1.0)
    tel["nav_east_m"] = tel["truth_east_m"] + err
    tel["gnss_available"] = np.arange(n) < 50
    nav = compute_nav(record_of(tel))
    assert nav.denied.horizontal_error_m.mean == pytest.approx(10.0)
    assert nav.denied.duration_s == pytest.approx(5.0)
    no_col = tel.drop(columns="gnss_available")
    nav2 = compute_nav(record_of(no_col, gnss_denied_windows={"a": [[5.0, 100.0]]}))
    assert nav2.denied.horizontal_error_m.mean == pytest.approx(10.0)


def test_spoofed_subset_and_how_long_the_spoofer_held_the_filter():
    """Rows inside gnss_spoofed_windows form nav.spoofed; its GNSS fixes give the share the
    filter fused (gate passed, or a reset to them) and the time from the window's start to the
    last fused one."""
    n = 100  # 0-9.9 s
    tel = straight_telemetry(n=n, err_ned=(0.0, 0.0, 0.0))
    tel["nav_east_m"] = tel["truth_east_m"] + np.where(tel["t_s"] >= 4.0, 2.0, 0.5)
    t_fix = np.arange(0.0, 10.0, 1.0)
    cor = pd.DataFrame({"t_s": t_fix, "vehicle_id": "a", "kind": "gnss", "dim": 6, "nis": 1.0,
                        "accepted": t_fix < 6.0})  # the spoofer (from 4 s) held it until 5 s
    cor.loc[cor.t_s == 7.0, ["kind", "accepted"]] = ["gnss:reset", False]  # a reset to it at 7 s
    cor = pd.concat([cor, pd.DataFrame({"t_s": [8.0], "vehicle_id": "a", "kind": "baro", "dim": 1, "nis": 1.0,
                                        "accepted": [True]})])
    nav = compute_nav(record_of(tel, events={"corrections": cor}, gnss_spoofed_windows={"a": [[4.0, 9.9]]}))
    s = nav.spoofed
    assert s.horizontal_error_m.mean == pytest.approx(2.0) and s.duration_s == pytest.approx(6.0)
    assert s.gnss_accept_rate == pytest.approx(3 / 6)  # 4, 5 and the reset at 7 of 4-9
    assert s.gnss_captured_s == pytest.approx(3.0)
    assert "spoofed" in nav.to_dict() and nav.to_dict()["spoofed"]["gnss_captured_s"] == pytest.approx(3.0)
    assert compute_nav(record_of(tel, events={"corrections": cor})).spoofed is None


def test_position_nees_with_correlated_covariance(rng):
    n = 40_000
    P_h = np.array([[4.0, 1.8], [1.8, 2.25]])
    L = np.linalg.cholesky(P_h)
    e_h = rng.standard_normal((n, 2)) @ L.T
    e_d = 3.0 * rng.standard_normal(n)
    tel = straight_telemetry(n=n, dt=0.01, err_ned=(0, 0, 0))
    tel["nav_north_m"] += e_h[:, 0]
    tel["nav_east_m"] += e_h[:, 1]
    tel["nav_down_m"] += e_d
    tel["nav_sigma_north_m"] = 2.0
    tel["nav_sigma_east_m"] = 1.5
    tel["nav_sigma_down_m"] = 3.0
    tel["nav_cov_ne_m2"] = 1.8
    nees = compute_nav(record_of(tel)).nees["position"]
    assert nees.mean == pytest.approx(3.0, rel=0.03)
    assert nees.frac_in_95 == pytest.approx(0.95, abs=0.006)
    # Ignoring the correlation would bias NEES: the closed form must use the full 2x2 block.
    direct = np.einsum("ni,ij,nj->n", e_h, np.linalg.inv(P_h), e_h) + (e_d / 3.0) ** 2
    assert np.allclose(position_nees(tel), direct)
    # Whitened by the same covariance, the errors are unit and uncorrelated, and z.z is the NEES.
    z = position_errors_whitened(tel)
    assert np.allclose(np.cov(z.T), np.eye(3), atol=0.03)
    assert np.allclose((z**2).sum(axis=1), direct)
    tel["nav_cov_ne_m2"] = 0.0
    assert not np.allclose(position_nees(tel), direct)
    tel.loc[5, "nav_cov_ne_m2"] = 3.5  # |cov| > sigma_n sigma_e: no covariance, no figures
    assert np.isnan(position_errors_whitened(tel)[5]).all() and np.isnan(position_nees(tel)[5])


def test_lost_navigator_is_flagged_when_its_error_outgrows_its_covariance():
    """An error that grows while the claimed sigma stays at 1 m: lost where the NEES crosses
    30.66 and stays (not at a single 6-sigma row, and not for a second vehicle that is fine)."""
    n = 500  # 50 s at 10 Hz
    lost = straight_telemetry(n=n, err_ned=(0.0, 0.0, 0.0), nav_sigma_north_m=1.0, nav_sigma_east_m=1.0,
                              nav_sigma_down_m=1.0, nav_cov_ne_m2=0.0)
    t = lost["t_s"].to_numpy()
    lost["nav_east_m"] = lost["truth_east_m"] + np.where(t > 20.0, 0.5 * (t - 20.0), 0.0)  # sqrt(30.66) m at 31.07 s
    lost.loc[50, "nav_east_m"] += 6.0  # one 6-sigma row at 5 s is not being lost
    fine = straight_telemetry(n=n, vehicle_id="b", err_ned=(0.5, 0.0, 0.0), nav_sigma_north_m=1.0,
                              nav_sigma_east_m=1.0, nav_sigma_down_m=1.0, nav_cov_ne_m2=0.0)
    nav = compute_nav(record_of(pd.concat([fine, lost], ignore_index=True)))
    assert nav.lost_at_s == pytest.approx(31.1, abs=0.05)
    assert compute_nav(record_of(fine)).lost_at_s is None
    short = lost[lost["t_s"] < 41.0].reset_index(drop=True)  # ends under 10 s after the crossing: not yet
    assert compute_nav(record_of(short)).lost_at_s is None


def test_cross_track_geometry():
    # Line from (0,0) heading north-east; a point 10 m to its right (south-east of it).
    d = 10.0 / np.sqrt(2)
    assert cross_track_m(100 - d, 100 + d, 0, 0, 200, 200) == pytest.approx(10.0)
    assert cross_track_m(100 + d, 100 - d, 0, 0, 200, 200) == pytest.approx(-10.0)
    assert cross_track_m(3.0, 4.0, 0, 0, 0, 0) == pytest.approx(5.0)  # degenerate line


def test_control_metrics():
    n = 50
    tel = straight_telemetry(n=n)
    tel["truth_east_m"] = 2.0  # 2 m right of a northbound line at east = 0
    tel["gd_on_leg"] = np.arange(n) < 40
    tel["gd_line_start_n_m"], tel["gd_line_start_e_m"] = 0.0, 0.0
    tel["gd_line_end_n_m"], tel["gd_line_end_e_m"] = 1000.0, 0.0
    tel["gd_alt_cmd_m"] = 97.0  # truth flies at 100 m
    tel["truth_airspeed_mps"] = 21.0
    tel["gd_airspeed_cmd_mps"] = 20.0
    tel["truth_roll_rad"] = np.deg2rad(np.linspace(-30, 5, n))
    c = compute_control(record_of(tel))
    assert c.cross_track_error_m.rms == pytest.approx(2.0) and c.cross_track_error_m.n == 40
    assert c.altitude_error_m.max == pytest.approx(3.0) and c.altitude_error_m.n == n
    assert c.airspeed_error_mps.rms == pytest.approx(1.0)
    assert c.bank_max_deg == pytest.approx(30.0)


def test_turn_rate_from_body_rates_matches_yaw_derivative():
    # Coordinated turn at 20 deg bank, 5 deg pitch, yaw rate 0.1 rad/s.
    t = np.arange(0, 20, 0.01)
    roll, pitch, psi_dot = np.deg2rad(20), np.deg2rad(5), 0.1
    yaw = psi_dot * t
    # Body rates of Euler rates (0, 0, psi_dot): q = psi_dot sin(phi) cos(theta), r = psi_dot cos(phi) cos(theta).
    tel = pd.DataFrame({"t_s": t, "truth_roll_rad": roll, "truth_pitch_rad": pitch, "truth_yaw_rad": np.angle(np.exp(1j * yaw)),
                        "truth_q_rps": psi_dot * np.sin(roll) * np.cos(pitch), "truth_r_rps": psi_dot * np.cos(roll) * np.cos(pitch)})
    assert np.allclose(turn_rate_rps(tel), psi_dot)
    no_rates = tel.drop(columns=["truth_q_rps", "truth_r_rps"])
    assert np.allclose(turn_rate_rps(no_rates), psi_dot, atol=1e-9)


def test_phase_of_events_uses_bank_and_turn_rate():
    tel = straight_telemetry(n=100)
    tel["truth_r_rps"] = np.where(tel["t_s"] > 5.0, np.deg2rad(5.0), 0.0)  # flat turn after 5 s
    ev = pd.DataFrame({"t_s": [1.0, 2.0, 8.0], "vehicle_id": ["a"] * 3, "truth_roll_rad": [0.0, np.deg2rad(15), 0.0]})
    rec = record_of(tel, phases={"turn_bank_deg": 10.0, "turn_rate_deg_s": 3.0})
    assert event_turning(rec, ev).tolist() == [False, True, True]


def _ismn_table():
    return pd.DataFrame({
        "t_s": [1.0, 2.0, 3.0, 4.0, 5.0], "vehicle_id": ["a"] * 5,
        "attempted": [True] * 5, "fix": [True, True, True, False, True], "accepted": [True, False, True, False, True],
        "fix_north_m": [23.0, 40.0, 60.0, np.nan, 100.0 + 30.0], "fix_east_m": [4.0, 0.0, 0.0, np.nan, 40.0],
        "truth_north_m": [20.0, 40.0, 60.0, 80.0, 100.0], "truth_east_m": [0.0] * 5,
        "latency_ms": [10.0, 20.0, 30.0, 40.0, 50.0], "truth_roll_rad": [0, 0, 0, 0, np.deg2rad(30)],
        "truth_height_agl_m": [100.0] * 5,
    })


def test_ismn_rates_and_phases():
    rec = record_of(straight_telemetry(n=100), {"ismn": _ismn_table()})
    m = score_record(rec, metrics=[]).ismn
    assert (m.attempts, m.fixes, m.accepted) == (5, 4, 3)
    assert m.fix_rate == pytest.approx(0.8) and m.accept_rate == pytest.approx(0.75)
    assert m.latency_ms.mean == pytest.approx(30.0)
    assert m.all.count == 4 and m.smooth.count == 3 and m.turning.count == 1
    assert m.smooth.horizontal_error_m.max == pytest.approx(5.0)
    assert m.turning.horizontal_error_m.mean == pytest.approx(50.0)
    assert m.turning.horizontal_error_pct_agl.mean == pytest.approx(50.0)


def test_ismn_longest_gap_and_clouds():
    table = _ismn_table()
    rec = record_of(straight_telemetry(n=100), {"ismn": table})
    m = score_record(rec, metrics=[]).ismn
    # Accepted at 1, 3, 5 s, the last attempt at 5 s: the longest gap 2 s. No cloud column.
    assert m.longest_gap_s == pytest.approx(2.0) and m.clouds is None
    table["accepted"] = [True, False, False, False, False]
    assert score_record(record_of(straight_telemetry(n=100), {"ismn": table}), metrics=[]).ismn.longest_gap_s == 4.0
    two = pd.concat([table.assign(t_s=table["t_s"] + 0.5, vehicle_id="b", accepted=True), table])
    two = two.sort_values("t_s", kind="stable")  # b fixes every second between a's: a's gap stays 4 s
    assert score_record(record_of(straight_telemetry(n=100), {"ismn": two}), metrics=[]).ismn.longest_gap_s == 4.0
    table["accepted"] = [True, False, True, False, True]
    table["truth_cloud_fraction"] = [0.0, 0.6, 0.97, 1.0, 0.2]
    m = score_record(record_of(straight_telemetry(n=100), {"ismn": table}), metrics=[]).ismn
    c = m.clouds
    # Clouded (>= 0.5): rows 2-4, fixes at 2 and 3 s, accepted at 3 s; overcast (>= 0.95): 3, 4 s.
    assert (c.attempts, c.fixes, c.accepted, c.overcast_attempts, c.overcast_accepted) == (3, 2, 1, 2, 1)
    assert c.horizontal_error_m.max == pytest.approx(0.0) and c.horizontal_error_m.n == 2
    assert c.shadowed_fixes is None  # no shadow column: a record from before the shadows
    # Shadowed (>= 0.2 of the ground in view): the fixes at 1 and 3 s (4 s made none); sunlit
    # (< 0.05): those at 2 and 5 s.
    table["truth_shadow_fraction"] = [0.3, 0.0, 0.25, 0.5, 0.01]
    c = score_record(record_of(straight_telemetry(n=100), {"ismn": table}), metrics=[]).ismn.clouds
    assert (c.shadowed_fixes, c.sunlit_fixes) == (2, 2)
    assert c.shadowed_horizontal_error_m.mean == pytest.approx(2.5) and c.sunlit_horizontal_error_m.mean == pytest.approx(25.0)
    table["truth_cloud_fraction"] = 0.0
    assert score_record(record_of(straight_telemetry(n=100), {"ismn": table}), metrics=[]).ismn.clouds is None


def test_relnav_and_formation_and_vehicles():
    tel = pd.concat([straight_telemetry(n=20, vehicle_id="a"), straight_telemetry(n=20, vehicle_id="b")]).sort_values("t_s", kind="stable")
    rel = pd.DataFrame({"t_s": [0.0, 0.0, 1.0], "vehicle_id": ["a", "b", "a"], "peer_id": ["b", "a", "b"],
                        "est_north_m": [1.0, 0.0, 0.0], "est_east_m": [0.0, 2.0, 0.0], "est_down_m": [0.0, 0.0, 0.0],
                        "truth_north_m": [0.0] * 3, "truth_east_m": [0.0] * 3, "truth_down_m": [0.0, 0.0, 3.0],
                        "sigma_m": [1.0, 0.5, 1.0], "id_correct": [True, True, False]})
    frm = pd.DataFrame({"t_s": [0.0, 1.0], "vehicle_id": ["b", "b"], "slot_error_north_m": [3.0, 0.0],
                        "slot_error_east_m": [4.0, 0.0], "slot_error_down_m": [0.0, 1.0]})
    res = score_record(record_of(tel, {"relnav": rel, "formation": frm}, vehicles=[{"id": "a"}, {"id": "b"}]), metrics=[])
    assert res.relnav.error_m.max == pytest.approx(3.0)
    assert res.relnav.id_correct_rate == pytest.approx(2 / 3)
    assert res.relnav.within_3sigma_rate == pytest.approx(2 / 3)  # 2 m > 3 * 0.5 m
    assert res.relnav.pairs["a_to_b"].error_m.rms == pytest.approx(np.sqrt(5.0))
    assert res.relnav.pairs["b_to_a"].error_m.max == pytest.approx(2.0)
    assert res.formation.error_m.max == pytest.approx(5.0)
    assert res.formation.horizontal_error_m.max == pytest.approx(5.0)
    flat = res.flatten()
    assert flat["vehicles.a.relnav.error_m.max"] == pytest.approx(3.0)
    assert "vehicles.a.formation.error_m.max" not in flat
    assert flat["vehicles.b.formation.error_m.rms"] == pytest.approx(np.sqrt(13.0))
    assert flat["nav.position_error_m.rms"] == pytest.approx(13.0)
    assert flat["real_time_factor"] == 2.0
    assert not any(k.startswith("ismn.") for k in flat)  # no table -> no keys
    assert "formation.holding_error_m.rms" not in flat  # no guidance target in this telemetry


def test_formation_error_splits_into_holding_and_placement():
    """The follower flies 1 m north of the slot it places (holding), and places that slot
    3 m east of the true one (placement): the true error (1, 3, 0) is their sum. The event
    table's times sum differently from the telemetry's (0.7000000000000001 against 0.7): the
    rows still pair up."""
    tel = straight_telemetry(n=10, vehicle_id="b", err_ned=(0.0, 0.0, 0.0))
    tel["gd_target_n_m"] = tel["nav_north_m"] - 1.0
    tel["gd_target_e_m"] = tel["nav_east_m"]
    tel["gd_target_d_m"] = tel["nav_down_m"]
    t_event = np.cumsum(np.full(10, 0.1)) - 0.1  # 0.1 added up: 0.30000000000000004, ...
    assert not np.array_equal(t_event, tel["t_s"].to_numpy())
    frm = pd.DataFrame({"t_s": t_event, "vehicle_id": "b", "slot_error_north_m": 1.0,
                        "slot_error_east_m": 3.0, "slot_error_down_m": 0.0})
    res = score_record(record_of(tel, {"formation": frm}, vehicles=[{"id": "b"}]), metrics=[]).formation
    assert res.error_m.rms == pytest.approx(np.sqrt(10.0))
    assert res.holding_error_m.n == 10 and res.holding_error_m.max == pytest.approx(1.0)
    assert res.holding_error_m.mean == pytest.approx(1.0)
    assert res.placement_error_m.n == 10 and res.placement_error_m.mean == pytest.approx(3.0)
    assert res.placement_error_m.max == pytest.approx(3.0)


def test_synthetic_run_is_consistent_and_deterministic(tmp_path):
    from testbench.scoring import score_run
    from testbench.scoring.synthetic import make_synthetic_run

    a = make_synthetic_run(tmp_path / "a", np.random.default_rng(3), n_vehicles=2, duration_s=60, with_images=False)
    b = make_synthetic_run(tmp_path / "b", np.random.default_rng(3), n_vehicles=2, duration_s=60, with_images=False)
    fa, fb = score_run(a).flatten(), score_run(b).flatten()
    assert fa == fb
    assert all(np.isfinite(v) for v in fa.values() if isinstance(v, float))
    # Errors were drawn from the reported covariance, so NEES is consistent.
    assert 0.85 < fa["nav.nees.position.frac_in_95"] < 1.0
    assert fa["ismn.turning.horizontal_error_m.mean"] > fa["ismn.smooth.horizontal_error_m.mean"]



def test_relnav_id_rate_leaves_out_rows_without_a_check():
    """id_correct nan (no truth annotation for the last bearing) is neither right nor wrong."""
    tel = straight_telemetry(n=20, vehicle_id="a")
    rel = pd.DataFrame({"t_s": [0.0, 1.0, 2.0], "vehicle_id": ["a"] * 3, "peer_id": ["b"] * 3,
                        "est_north_m": [0.0] * 3, "est_east_m": [0.0] * 3, "est_down_m": [0.0] * 3,
                        "truth_north_m": [0.0] * 3, "truth_east_m": [0.0] * 3, "truth_down_m": [0.0] * 3,
                        "sigma_m": [1.0] * 3, "id_correct": [1.0, 0.0, np.nan]})
    res = score_record(record_of(tel, {"relnav": rel}, vehicles=[{"id": "a"}]), metrics=[])
    assert res.relnav.id_correct_rate == pytest.approx(0.5)
    rel["id_correct"] = np.nan
    res = score_record(record_of(tel, {"relnav": rel}, vehicles=[{"id": "a"}]), metrics=[])
    assert res.relnav.id_correct_rate is None


def test_relnav_by_range_bins_the_rows_by_their_true_range():
    """relnav.by_range: the same error figures per bin of the pair's TRUE range (not the
    estimate's), half-open bins [lo, hi), empty bins left out, rows without truth in none."""
    tel = straight_telemetry(n=20, vehicle_id="a")
    truth_north = [50.0, 100.0, 119.9, 120.0, 300.0, np.nan]
    err_east = [0.1, 0.2, 0.4, 0.8, 1.6, 3.2]
    rel = pd.DataFrame({"t_s": np.arange(6.0), "vehicle_id": ["a"] * 6, "peer_id": ["b"] * 6,
                        # estimates 200 m off in north would land elsewhere: the bin is the truth's
                        "est_north_m": np.nan_to_num(truth_north), "est_east_m": err_east, "est_down_m": [0.0] * 6,
                        "truth_north_m": truth_north, "truth_east_m": [0.0] * 6, "truth_down_m": [0.0] * 6,
                        "sigma_m": [1.0] * 6, "id_correct": [1.0, 1.0, 0.0, 1.0, 1.0, 1.0]})
    res = score_record(record_of(tel, {"relnav": rel}, vehicles=[{"id": "a"}]), metrics=[])
    by = res.relnav.by_range
    assert list(by) == ["0_60m", "60_120m", "120_180m", "240m_up"]
    assert by["0_60m"].count == 1 and by["0_60m"].error_m.max == pytest.approx(0.1)
    assert by["60_120m"].count == 2 and by["60_120m"].error_m.mean == pytest.approx(0.3)
    assert by["60_120m"].id_correct_rate == pytest.approx(0.5)
    assert by["120_180m"].error_m.mean == pytest.approx(0.8)  # 120 m itself opens the next bin
    assert by["240m_up"].error_m.mean == pytest.approx(1.6)
    assert sum(b.count for b in by.values()) == 5  # the row without truth is in no bin
    flat = res.flatten()
    assert flat["relnav.by_range.60_120m.error_m.mean"] == pytest.approx(0.3)


def test_relnav_error_less_own_heading_takes_out_the_observers_heading_error():
    """An observer whose heading errs by d psi turns its estimates about itself by d psi:
    relnav.error_m counts that, error_less_own_heading_m does not (nor what is left)."""
    d_psi_rad = np.linspace(0.002, 0.004, 20)  # the observer's heading error, drifting
    tel = straight_telemetry(n=20, vehicle_id="a", nav_yaw_rad=d_psi_rad)  # truth yaw 0
    t_s = np.array([0.35, 1.0, 1.55])
    d_psi = np.interp(t_s, tel["t_s"], d_psi_rad)
    truth_ne = np.array([[100.0, 0.0], [0.0, 173.0], [-60.0, 80.0]])
    c, s = np.cos(d_psi), np.sin(d_psi)
    est_n = c * truth_ne[:, 0] - s * truth_ne[:, 1]
    est_e = s * truth_ne[:, 0] + c * truth_ne[:, 1]
    rel = pd.DataFrame({"t_s": t_s, "vehicle_id": ["a"] * 3, "peer_id": ["b", "c", "d"],
                        "est_north_m": est_n, "est_east_m": est_e + np.array([0.0, 0.0, 0.5]),
                        "est_down_m": [0.0] * 3, "truth_north_m": truth_ne[:, 0], "truth_east_m": truth_ne[:, 1],
                        "truth_down_m": [0.0] * 3, "sigma_m": [1.0] * 3})
    m = score_record(record_of(tel, {"relnav": rel}, vehicles=[{"id": "a"}]), metrics=[]).relnav
    heading_part_m = np.hypot(*truth_ne.T) * d_psi  # 2-4 mrad at 100-173 m
    assert m.error_m.max == pytest.approx(heading_part_m[1], rel=1e-4) and m.error_m.max > 0.5
    less = m.error_less_own_heading_m
    assert less.n == 3 and less.max == pytest.approx(0.5, abs=1e-9)  # what the heading does not explain
    assert less.mean == pytest.approx(0.5 / 3, abs=1e-9)  # the other two rows: 0
    no_yaw = straight_telemetry(n=20, vehicle_id="a")  # no estimated yaw recorded: nothing to take out
    assert score_record(record_of(no_yaw, {"relnav": rel}), metrics=[]).relnav.error_less_own_heading_m is None


def test_relnav_ambiguous_rate_counts_the_undecidable_rows():
    """Rows whose last bearing imaged several vehicles alike (id_ambiguous 1, id_correct nan)
    are left out of id_correct_rate and counted in id_ambiguous_rate; rows with no check at all
    (both nan) in neither."""
    tel = straight_telemetry(n=20, vehicle_id="a")
    rel = pd.DataFrame({"t_s": [0.0, 1.0, 2.0, 3.0], "vehicle_id": ["a"] * 4, "peer_id": ["b"] * 4,
                        "est_north_m": [0.0] * 4, "est_east_m": [0.0] * 4, "est_down_m": [0.0] * 4,
                        "truth_north_m": [0.0] * 4, "truth_east_m": [0.0] * 4, "truth_down_m": [0.0] * 4,
                        "sigma_m": [1.0] * 4, "id_correct": [1.0, 0.0, np.nan, np.nan],
                        "id_ambiguous": [0.0, 0.0, 1.0, np.nan]})
    res = score_record(record_of(tel, {"relnav": rel}, vehicles=[{"id": "a"}]), metrics=[])
    assert res.relnav.id_correct_rate == pytest.approx(0.5)
    assert res.relnav.id_ambiguous_rate == pytest.approx(1 / 3)


def test_relnav_track_id_rate_from_the_decoded_track_frames():
    """relnav_id rows (one per identified track per frame): the share of decidable track-frames
    whose decoded ID is right, and the share imaging several vehicles alike."""
    tel = straight_telemetry(n=20, vehicle_id="a")
    rel = pd.DataFrame({"t_s": [0.0], "vehicle_id": ["a"], "peer_id": ["b"],
                        "est_north_m": [0.0], "est_east_m": [0.0], "est_down_m": [0.0],
                        "truth_north_m": [0.0], "truth_east_m": [0.0], "truth_down_m": [0.0],
                        "sigma_m": [1.0], "id_correct": [1.0], "id_ambiguous": [0.0]})
    ids = pd.DataFrame({"vehicle_id": ["a"] * 5, "t_s": [0.0, 0.1, 0.2, 0.3, 0.4], "camera": ["front"] * 5,
                        "track_id": [1] * 5, "decoded_id": ["b"] * 5, "truth_id": ["b", "b", "b", "c", "b"],
                        "id_correct": [1.0, 1.0, 1.0, 0.0, np.nan], "id_ambiguous": [0.0, 0.0, 0.0, 0.0, 1.0],
                        "id_confidence": [1.0] * 5})
    res = score_record(record_of(tel, {"relnav": rel, "relnav_id": ids}, vehicles=[{"id": "a"}]), metrics=[])
    assert res.relnav.track_id_correct_rate == pytest.approx(0.75)
    assert res.relnav.track_id_ambiguous_rate == pytest.approx(0.2)


def test_camera_boresight_estimate_is_scored_against_the_cameras_truth():
    """nav.camera_boresight: the estimate (telemetry nav_boresight_*, a body-axes rotation
    vector) against the true boresight of the camera run.json names (Z-Y-X degrees, turned
    into a rotation vector), over the GNSS-denied rows; its final error and sigma; nees
    camera_boresight (3 dof). A camera without a recorded error has a zero truth."""
    from testbench.core.rotations import dcm_to_quat, euler_to_dcm, quat_to_rotvec

    n = 100
    truth_deg = [0.4, -0.3, 0.5]
    b = quat_to_rotvec(dcm_to_quat(euler_to_dcm(np.radians(truth_deg))))
    tel = straight_telemetry(n=n, err_ned=(0.0, 0.0, 0.0))
    tel["gnss_available"] = np.arange(n) < 50
    off = np.radians(0.02) * np.array([1.0, -1.0, 2.0])  # the estimate after convergence
    for i, axis in enumerate("xyz"):
        tel[f"nav_boresight_{axis}_rad"] = np.where(np.arange(n) < 10, 0.0, b[i] + off[i])
        tel[f"nav_sigma_boresight_{axis}_rad"] = np.radians(0.02)
    info = dict(camera_boresight_error_deg={"a": {"down": truth_deg}}, camera_boresight_estimated={"a": "down"})
    nav = compute_nav(record_of(tel, **info))
    c = nav.camera_boresight
    assert c.error_deg.n == 50 and c.error_deg.mean == pytest.approx(0.02 * np.sqrt(6.0), rel=1e-6)
    assert c.final_error_deg == pytest.approx(0.02 * np.sqrt(6.0), rel=1e-6)
    assert c.final_sigma_deg == pytest.approx(0.02 * np.sqrt(3.0), rel=1e-6)
    assert nav.nees["camera_boresight"].n == n
    # The exact figures above need the truth as a rotation vector: read as Euler radians it is
    # a thousandth of a degree off, a thousand times the tolerance.
    assert np.degrees(np.abs(np.radians(truth_deg) - b)).max() > 1e-3
    no_truth = compute_nav(record_of(tel, camera_boresight_estimated={"a": "down"})).camera_boresight
    assert no_truth.final_error_deg == pytest.approx(np.degrees(np.linalg.norm(b + off)), rel=1e-6)
    assert compute_nav(record_of(tel.drop(columns=[c for c in tel.columns if "boresight" in c]))).camera_boresight is None
