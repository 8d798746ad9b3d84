"""Error-free IMU data for INS tests, built from the same geodesy functions as the INS.

The truth of a moving trajectory is defined by the mechanisation itself driven by clean
increments computed from the kinematics (desired NED acceleration and body rate), so truth
and IMU are consistent by construction; static cases use closed forms.
"""

from __future__ import annotations

import numpy as np

from testbench.core import geodesy
from testbench.core.rotations import quat_to_dcm
from testbench.navigation.ins.mechanization import StrapdownINS


def static_imu(lat_rad, h_m, q_nb_wxyz):
    """Rate (rad/s) and specific force (m/s^2), body FRD, of a vehicle at rest on the Earth."""
    C_bn = quat_to_dcm(q_nb_wxyz).T  # NED -> body
    w = C_bn @ geodesy.earth_rate_ned_rps(lat_rad)
    f = C_bn @ (-geodesy.gravity_ned_mps2(lat_rad, h_m))
    return w, f


def kinematic_imu(ins: StrapdownINS, acc_ned_mps2, omega_nb_b_rps):
    """Clean rate and specific force (body FRD) that make the vehicle at the INS's state
    accelerate by acc_ned_mps2 (relative to the Earth) and turn at omega_nb_b_rps relative to NED."""
    lat, h = ins.lat_rad, ins.h_m
    v = np.array(ins.vel)
    C_nb = quat_to_dcm(np.array(ins.q))
    wie = geodesy.earth_rate_ned_rps(lat)
    wen = geodesy.transport_rate_ned_rps(lat, h, v)
    f_n = np.asarray(acc_ned_mps2, float) + np.cross(2.0 * wie + wen, v) - geodesy.gravity_ned_mps2(lat, h)
    w_b = C_nb.T @ (wie + wen) + np.asarray(omega_nb_b_rps, float)
    return w_b, C_nb.T @ f_n


def turning_flight(lat0, lon0, h0, speed_mps, dt_s, n_steps, turn_rate_rps=0.05, turn_window=(0.3, 0.7)):
    """Level flight heading north, turning at turn_rate (yaw, level body) in the middle part.

    Returns (truth states per step (list of tuples lat, lon, h, v, q), imu rates (n, 3),
    imu specific forces (n, 3)); sample k drives the interval from state k to state k+1.
    """
    ins = StrapdownINS(0.0, lat0, lon0, h0, [speed_mps, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0])
    states = [(ins.lat_rad, ins.lon_rad, ins.h_m, np.array(ins.vel), np.array(ins.q))]
    ws, fs = np.empty((n_steps, 3)), np.empty((n_steps, 3))
    for k in range(n_steps):
        turning = turn_window[0] * n_steps <= k < turn_window[1] * n_steps
        r = turn_rate_rps if turning else 0.0
        v = np.array(ins.vel)
        acc = np.array([-r * v[1], r * v[0], 0.0])  # (0, 0, r) x v: horizontal centripetal
        w, f = kinematic_imu(ins, acc, [0.0, 0.0, r])
        ins.step_increments(w * dt_s, f * dt_s, dt_s)
        ws[k], fs[k] = w, f
        states.append((ins.lat_rad, ins.lon_rad, ins.h_m, np.array(ins.vel), np.array(ins.q)))
    return states, ws, fs
