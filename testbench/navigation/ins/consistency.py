"""Filter consistency: the true error of an estimate in the filter's error convention, and
NEES / NIS statistics with their chi-square bounds (Bar-Shalom, Li & Kirubarajan, ch. 5)."""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from testbench.core.messages import TruthState
from testbench.navigation.ins.error_model import IBA, IBG, N_CORE, nav_error


def error_state(ekf, truth: TruthState, gyro_bias_rps=None, accel_bias_mps2=None) -> np.ndarray:
    """True error (15,) = truth (-) estimate of an ErrorStateEKF: [dp_ned_m, dv_ned_mps,
    phi_rad, dbg_rps, dba_mps2]. Unknown true biases (None) give zeros there; use only the
    first 9 states for NEES then."""
    ekf.flush()
    ins = ekf.ins
    e = np.zeros(N_CORE)
    e[:9] = nav_error(truth.lat_rad, truth.lon_rad, truth.alt_m, truth.vel_ned_mps, truth.q_nb_wxyz,
                      ins.lat_rad, ins.lon_rad, ins.h_m, ins.vel, ins.q)
    if gyro_bias_rps is not None:
        e[IBG] = np.asarray(gyro_bias_rps, float) - ekf.b_g
    if accel_bias_mps2 is not None:
        e[IBA] = np.asarray(accel_bias_mps2, float) - ekf.b_a
    return e


def nees(error, cov, states=None) -> float:
    """Normalised estimation error squared e^T P^-1 e over the chosen state indices."""
    e = np.asarray(error, float)
    P = np.asarray(cov, float)
    if states is not None:
        idx = np.asarray(states)
        e, P = e[idx], P[np.ix_(idx, idx)]
    return float(e @ np.linalg.solve(P, e))


def nees_from_truth(ekf, truth_lat_rad, truth_lon_rad, truth_h_m, truth_vel_ned_mps, truth_q_nb_wxyz,
                    truth_gyro_bias_rps=None, truth_accel_bias_mps2=None) -> float:
    """NEES of an ErrorStateEKF against a truth state: over 15 states when both true biases
    are given, else over position, velocity and attitude (9)."""
    ekf.flush()
    ins = ekf.ins
    e = np.zeros(N_CORE)
    e[:9] = nav_error(truth_lat_rad, truth_lon_rad, truth_h_m, truth_vel_ned_mps, truth_q_nb_wxyz,
                      ins.lat_rad, ins.lon_rad, ins.h_m, ins.vel, ins.q)
    if truth_gyro_bias_rps is None or truth_accel_bias_mps2 is None:
        return nees(e[:9], ekf.P[:9, :9])
    e[IBG] = np.asarray(truth_gyro_bias_rps, float) - ekf.b_g
    e[IBA] = np.asarray(truth_accel_bias_mps2, float) - ekf.b_a
    return nees(e, ekf.P[:N_CORE, :N_CORE])


def average_nees_bounds(dof: int, runs: int, probability: float = 0.95) -> tuple[float, float]:
    """Two-sided bounds of the average NEES over `runs` independent runs: runs * mean ~
    chi2(runs * dof)."""
    lo = chi2.ppf(0.5 * (1.0 - probability), runs * dof) / runs
    hi = chi2.ppf(0.5 * (1.0 + probability), runs * dof) / runs
    return float(lo), float(hi)
