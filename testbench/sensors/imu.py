"""Strapdown IMU model: 3-axis gyroscope and accelerometer from datasheet parameters.

Measured rate and specific force (body FRD, the IMU axes are the body axes):
    w_meas = Q_g(sat_g((I + S_g + M_g) w + NL_g(w) + b_g + G f + n_g(t)))
    f_meas = Q_a(sat_a((I + S_a + M_a) f_imu + NL_a(f_imu) + b_a + n_a(t)))
S diagonal scale factor, M off-diagonal misalignment, NL(x) = k x^2 / full_scale per axis,
b turn-on bias, G gyro g-sensitivity, n(t) the random processes of `noise.TriadNoise` (white,
flicker bank, rate random walk), sat clipping at the range, Q rounding to the LSB.
f_imu = f_cg + dw/dt x r + w x (w x r): the accelerometer at lever arm r from the CG.

The true rate w is the MEAN inertial rate over the sample interval, from the truth attitudes at
this sample and the previous one (`mean_rate_ib_b`), as a real IMU's integrated angle increments
are. Not the instantaneous rate read after the step: JSBSim's integrator moves the attitude over
a step with a rate other than the one it reports at the step's end, so a perfect gyro sampling
that rate put the INS 1.9 mrad ahead in heading through a 30 deg bank turn (the heading rate
times one physics step) and 1.2 mrad ahead in roll at roll-in; the filter then took these for
gyro biases, the same way in every run (measured on paper_ismn_800m with a noiseless IMU).

`ImuErrorModel.apply` is vectorised over samples (the static record, `imu_static`, calls it with
blocks of many); the in-loop `Imu` sensor calls its scalar twin `apply_one` sample by sample,
which draws the random errors in blocks ahead: the same draws and recursions.
"""

from __future__ import annotations

import math

import numpy as np

from testbench.core.geodesy import nav_frame_rate_ned_scalar
from testbench.core.interfaces import BuildContext, WorldView
from testbench.core.messages import ImuSample, TruthState
from testbench.core.registry import register
from testbench.sensors.base import CachedSensor, check_rate
from testbench.sensors.imu_params import ImuParams, ImuSpec, TriadSpec
from testbench.sensors.noise import TriadNoise


# In-loop samples whose random errors are drawn in one block.
_AHEAD_SAMPLES = 128


class _TriadErrors:
    """Per-run constants and random processes of one triad."""

    def __init__(self, spec: TriadSpec, dt_s: float, rng: np.random.Generator):
        self.spec = spec
        self.bias = spec.turn_on_bias * rng.standard_normal(3)
        m = np.eye(3) + np.diag(spec.scale_factor * rng.standard_normal(3))
        off = spec.misalignment * rng.standard_normal((3, 3))
        np.fill_diagonal(off, 0.0)
        self.matrix = m + off  # (3, 3): true axes -> sensed axes
        self.nl = spec.nonlinearity * rng.choice([-1.0, 1.0], size=3) / spec.range_q
        self.noise = TriadNoise(spec.white_density, spec.bias_instability, spec.rate_random_walk, dt_s)
        self.rng = rng.spawn(1)[0]  # own stream: block and per-sample draws coincide
        # apply_one's copies as Python floats, and its block of noise drawn ahead.
        self._rows = self.matrix.tolist()
        self._nl, self._bias = self.nl.tolist(), self.bias.tolist()
        self._range_q, self._lsb = float(spec.range_q), float(spec.lsb)
        self._ahead: list[list[float]] = []
        self._ahead_i = 0

    def apply(self, x: np.ndarray, extra: np.ndarray | float = 0.0) -> np.ndarray:
        """Sensed values (n, 3) for true values x (n, 3); `extra` is added before saturation."""
        y = x @ self.matrix.T + self.nl * x * x + self.bias + extra
        y = y + self.noise.sample_block(x.shape[0], self.rng)
        y = np.clip(y, -self.spec.range_q, self.spec.range_q)
        if self.spec.lsb > 0:
            y = np.round(y / self.spec.lsb) * self.spec.lsb
        return y

    def apply_one(self, x, extra=(0.0, 0.0, 0.0)) -> list[float]:
        """Scalar twin of `apply` for one sample: x, extra 3 floats -> 3 sensed floats.

        The random error comes from a block drawn ahead: it does not depend on the sensed
        values, so the in-loop IMU draws it _AHEAD_SAMPLES at a time (the same stream and
        recursions as `apply` on a block) and the rest is 3 x 3 arithmetic on Python floats,
        where numpy's per-call overhead would be most of the cost (~15 calls per sample).
        """
        if self._ahead_i >= len(self._ahead):
            self._ahead = self.noise.sample_block(_AHEAD_SAMPLES, self.rng).tolist()
            self._ahead_i = 0
        z = self._ahead[self._ahead_i]
        self._ahead_i += 1
        lim, lsb = self._range_q, self._lsb
        out = []
        for i in range(3):
            m = self._rows[i]
            y = m[0] * x[0] + m[1] * x[1] + m[2] * x[2] + self._nl[i] * x[i] * x[i] + self._bias[i] + extra[i] + z[i]
            y = lim if y > lim else (-lim if y < -lim else y)
            out.append(round(y / lsb) * lsb if lsb > 0 else y)
        return out


class ImuErrorModel:
    """The IMU's error model for one run; constants are drawn on the first `apply`."""

    def __init__(self, spec: ImuSpec, dt_s: float):
        self.spec = spec
        self.dt_s = float(dt_s)
        self._gyro: _TriadErrors | None = None
        self._accel: _TriadErrors | None = None

    def _init(self, rng: np.random.Generator) -> None:
        g_rng, a_rng = rng.spawn(2)
        self._gyro = _TriadErrors(self.spec.gyro, self.dt_s, g_rng)
        self._accel = _TriadErrors(self.spec.accel, self.dt_s, a_rng)

    def apply(self, omega_b_rps: np.ndarray, f_b_mps2: np.ndarray, rng: np.random.Generator):
        """Sensed (omega (n, 3) rad/s, f (n, 3) m/s^2) for true ones of the same shape.

        Advances the random processes by n samples of dt_s.
        """
        if self._gyro is None:
            self._init(rng)
        w = np.atleast_2d(np.asarray(omega_b_rps, float))
        f = np.atleast_2d(np.asarray(f_b_mps2, float))
        w_meas = self._gyro.apply(w, self.spec.g_sensitivity * f)
        f_meas = self._accel.apply(f)
        return w_meas, f_meas

    def apply_one(self, omega_b_rps, f_b_mps2, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Sensed (omega (3,) rad/s, f (3,) m/s^2) of one sample (_TriadErrors.apply_one): equal
        to `apply` on a block of the same samples up to rounding (~1e-16 relative)."""
        if self._gyro is None:
            self._init(rng)
        w = [float(v) for v in omega_b_rps]
        f = [float(v) for v in f_b_mps2]
        k = self.spec.g_sensitivity
        w_meas = self._gyro.apply_one(w, (k * f[0], k * f[1], k * f[2]))
        f_meas = self._accel.apply_one(f)
        return np.array(w_meas), np.array(f_meas)


def mean_rate_ib_b(q0_nb, q1_nb, dt_s: float, lat_rad: float, h_m: float, vel_ned_mps) -> tuple[float, float, float]:
    """Mean body rate relative to inertial space (rad/s, body FRD) over an interval of dt_s
    that turned the attitude q_nb (w, x, y, z; body -> NED) from q0_nb to q1_nb.

    C_ib(t1) = C_in(t1) C_nb(t1): the body's increment is the rotation vector of q0* q1 (relative
    to NED) plus NED's own rotation w_in = w_ie + w_en (Earth rate and transport rate at the end
    point) resolved in the body; the neglected terms are products of two increments (w_in dt is
    below 1e-6 rad per step). Scalar floats: it runs per sample for every vehicle."""
    aw, ax, ay, az = (float(v) for v in q0_nb)
    bw, bx, by, bz = (float(v) for v in q1_nb)
    # q0* q1 (Hamilton, scalar first)
    w = aw * bw + ax * bx + ay * by + az * bz
    x = aw * bx - ax * bw - ay * bz + az * by
    y = aw * by + ax * bz - ay * bw - az * bx
    z = aw * bz - ax * by + ay * bx - az * bw
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    s = math.sqrt(x * x + y * y + z * z)
    k = 2.0 * math.atan2(s, w) / s if s > 1e-12 else 2.0
    # NED's rotation rate w_in (NED axes), then into the body with C_bn = C_nb(q1)^T.
    wn, we, wd = nav_frame_rate_ned_scalar(lat_rad, h_m, float(vel_ned_mps[0]), float(vel_ned_mps[1]))
    c00, c01, c02 = 1 - 2 * (by * by + bz * bz), 2 * (bx * by - bw * bz), 2 * (bx * bz + bw * by)
    c10, c11, c12 = 2 * (bx * by + bw * bz), 1 - 2 * (bx * bx + bz * bz), 2 * (by * bz - bw * bx)
    c20, c21, c22 = 2 * (bx * bz - bw * by), 2 * (by * bz + bw * bx), 1 - 2 * (bx * bx + by * by)
    inv_dt = 1.0 / dt_s
    return (k * x * inv_dt + c00 * wn + c10 * we + c20 * wd,
            k * y * inv_dt + c01 * wn + c11 * we + c21 * wd,
            k * z * inv_dt + c02 * wn + c12 * we + c22 * wd)


@register("sensor", "imu")
class Imu(CachedSensor):
    """In-loop IMU sampling the truth at rate_hz; returns ImuSample."""

    Params = ImuParams

    def __init__(self, params: ImuParams, *, ctx: BuildContext):
        super().__init__()
        self.params = params
        self.name = "imu"
        self.rate_hz = check_rate(params.rate_hz, ctx, "imu")
        self.spec = params.spec()
        self.model = ImuErrorModel(self.spec, 1.0 / self.rate_hz)
        self._prev_w: np.ndarray | None = None
        self._has_lever_arm = bool(np.any(self.spec.lever_arm_b_m))
        self._prev_t = 0.0
        self._prev_q: np.ndarray | None = None

    def _sample(self, truth: TruthState, world: WorldView, rng: np.random.Generator) -> ImuSample:
        # The mean rate since the previous sample (the first sample has none: the instantaneous).
        if self._prev_q is not None and truth.t_s > self._prev_t:
            w = mean_rate_ib_b(self._prev_q, truth.q_nb_wxyz, truth.t_s - self._prev_t, truth.lat_rad,
                               truth.alt_m, truth.vel_ned_mps)
        else:
            w = truth.omega_ib_b_rps
        self._prev_q = truth.q_nb_wxyz
        f = truth.f_b_mps2
        r = self.spec.lever_arm_b_m
        if self._has_lever_arm:
            w = np.asarray(w, float)
            # Angular acceleration by a backward difference of the sampled rates.
            dt = truth.t_s - self._prev_t
            wdot = (w - self._prev_w) / dt if self._prev_w is not None and dt > 0 else np.zeros(3)
            f = f + np.cross(wdot, r) + np.cross(w, np.cross(w, r))
        self._prev_w, self._prev_t = w, truth.t_s
        w_meas, f_meas = self.model.apply_one(w, f, rng)
        return ImuSample(truth.t_s, w_meas, f_meas)
