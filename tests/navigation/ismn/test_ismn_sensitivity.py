"""`testbench ismn sensitivity`: central differences of a fix against its prior."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from testbench.cli import main
from testbench.core.messages import NavEstimate, PositionFix
from testbench.core.rotations import dcm_to_quat, euler_to_quat, quat_to_dcm, quat_to_rotvec
from testbench.navigation.ismn.sensitivity import (INPUTS, SWEEP_DIRECTION_NE, frame_sensitivity, frame_sweep,
                                                    summarise, summarise_sweeps)

SCENARIO = str(Path(__file__).resolve().parents[3] / "scenarios" / "paper_ismn_800m.yaml")


class _LinearFixes:
    """A stand-in with a known answer (the arithmetic under test, not a matcher): the fix is the
    true position plus M phi (phi: the prior's NED rotation from the truth) plus `follow` (3, 3) times
    the prior's position error."""

    def __init__(self, truth_pos, q_true, M, follow):
        self.truth_pos, self.R_true, self.M, self.follow = np.asarray(truth_pos), quat_to_dcm(q_true), M, follow

    def process(self, image, t_s, est):
        phi = quat_to_rotvec(dcm_to_quat(quat_to_dcm(est.q_nb_wxyz) @ self.R_true.T))
        pos = self.truth_pos + self.M @ phi + self.follow @ (np.asarray(est.pos_ned_m) - self.truth_pos)
        return PositionFix(t_s, pos, np.eye(3), 1.0, "test", att_sensitivity_m_per_rad=self.M,
                           cov_given_att_ned_m2=np.eye(3)), None


def test_central_differences_recover_a_known_linear_dependence():
    q = euler_to_quat(np.array([0.05, -0.02, 1.1]))
    pos = np.array([100.0, -50.0, -800.0])
    M = np.array([[5.0, -50.0, 2.0], [40.0, 3.0, -6.0], [-1.0, 10.0, 0.5]])
    follow = np.diag([0.25, 0.1, 0.0])
    est = NavEstimate(0.0, pos.copy(), np.zeros(3), q, np.zeros(3), np.zeros(3), np.eye(3), np.eye(3), np.eye(3) * 1e-6)
    fs = frame_sensitivity(_LinearFixes(pos, q, M, follow), None, 0.0, est, tilt_rad=1e-4, shift_m=0.3)
    assert fs.jacobian.shape == (3, len(INPUTS))
    np.testing.assert_allclose(fs.jacobian[:, :3], M, atol=1e-4)  # tilt N, tilt E, heading
    np.testing.assert_allclose(fs.jacobian[:, 3:], follow[:, :2], atol=1e-9)  # north, east
    s = summarise([fs, fs], 3)
    assert s["n_frames"] == 3 and s["n_used"] == 2
    np.testing.assert_allclose(s["excess_att_mean"], np.zeros((3, 3)), atol=1e-3)


def test_sweep_reports_the_spread_a_known_following_gives():
    """A fix that follows the prior's north by 0.25 m/m: along a sweep of 1.6 m in 8 steps the
    fix's north error is 0.25 x the prior's north offset, so its SD and largest jump are known;
    a fix that ignores the prior has no spread."""
    q = euler_to_quat(np.array([0.0, 0.0, 0.3]))
    pos = np.array([10.0, 20.0, -800.0])
    est = NavEstimate(0.0, pos.copy(), np.zeros(3), q, np.zeros(3), np.zeros(3), np.eye(3), np.eye(3), np.eye(3) * 1e-6)
    follow = np.diag([0.25, 0.0, 0.0])
    sw = frame_sweep(_LinearFixes(pos, q, np.zeros((3, 3)), follow), None, 0.0, est, pos, 1.6, 8)
    north_offsets = np.arange(8) * 0.2 * SWEEP_DIRECTION_NE[0]
    np.testing.assert_allclose(sw.fix_error_ned_m[:, 0], 0.25 * north_offsets, atol=1e-12)
    s = summarise_sweeps([sw, sw], 3, 1.6)
    assert s["n_frames"] == 3 and s["n_used"] == 2
    # Along the sweep the fix moves by 0.25 x its north part, projected back on the sweep.
    assert s["following_slope"] == pytest.approx(round(0.25 * SWEEP_DIRECTION_NE[0] ** 2, 3))
    assert s["following_slope_sd"] == 0.0
    np.testing.assert_allclose(s["sd_along_sweep_ne_m"], [round(0.25 * north_offsets.std(), 3), 0.0], atol=1e-9)
    assert s["largest_jump_median_m"] == pytest.approx(round(0.25 * 0.2 * SWEEP_DIRECTION_NE[0], 3))
    assert s["error_at_prior_rms_ne_m"] == [0.0, 0.0]
    still = summarise_sweeps([frame_sweep(_LinearFixes(pos, q, np.zeros((3, 3)), np.zeros((3, 3))), None, 0.0, est, pos, 1.6, 8)], 1, 1.6)
    assert still["sd_along_sweep_ne_m"] == [0.0, 0.0] and still["largest_jump_median_m"] == 0.0
    assert still["following_slope"] == 0.0


def test_cli_measures_a_recorded_runs_frames(tmp_path, capsys):
    run_dir = tmp_path / "run"
    assert main(["run", SCENARIO, "--set", "duration_s=2", "--no-report", "--out", str(run_dir)]) in (0, 3)
    capsys.readouterr()
    assert main(["ismn", "sensitivity", SCENARIO, str(run_dir), "--t0", "1", "--t1", "2", "--step", "1",
                 "--pipeline", '{"max_heading_sigma_deg": null}', "--frames-dir", str(tmp_path / "frames"),
                 "--sweep-steps", "3"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["n_frames"] == 2 and out["n_used"] == 2
    sweep = out["sweep"]
    assert sweep["n_used"] == 2 and len(sweep["sd_along_sweep_ne_m"]) == 2
    assert np.isfinite(sweep["largest_jump_median_m"]) and max(sweep["error_at_prior_rms_ne_m"]) < 5.0
    J = np.array(out["measured_mean"])
    assert J.shape == (3, 5) and np.isfinite(J).all()
    # The prior's north position moves the fix north by less than it moves itself (a matcher
    # that ignored the scene would follow it 1:1).
    assert abs(J[0, 3]) < 1.0


def test_cli_refuses_a_zero_step(tmp_path, capsys):
    assert main(["ismn", "sensitivity", SCENARIO, str(tmp_path), "--shift-m", "0"]) == 2
    assert "--shift-m must be > 0" in capsys.readouterr().err
    assert main(["ismn", "sensitivity", SCENARIO, str(tmp_path), "--sweep-steps", "4", "--sweep-m", "0"]) == 2
    assert "--sweep-m > 0" in capsys.readouterr().err
    assert main(["ismn", "sensitivity", SCENARIO, str(tmp_path), "--sweep-steps", "1"]) == 2
    assert "or >= 2" in capsys.readouterr().err
