"""Strapdown IMU model: 3-axis gyroscope and accelerometer from datasheet parameters.

Measured rate and specific force (body FRD, the IMU axes are the body axes):
    w_meas = Q_g(sat_g((I + S_g + M_g) w + NL_g(w) + b_g + G f + n_g(t)))
    f_meas = Q_a(sat_a((I + S_a + M_a) f_imu + NL_a(f_imu) + b_a + n_a(t)))
S diagonal scale factor, M off-diagonal misalignment, NL(x) = k x^2 / full_scale per axis,
b turn-on bias, G gyro g-sensitivity, n(t) the random processes of `noise.TriadNoise` (white,
flicker bank, rate random walk), sat clipping at the range, Q rounding to the LSB.
f_imu = f_cg + dw/dt x r + w x (w x r): the accelerometer at lever arm r from the CG.

`ImuErrorModel.apply` is vectorised over samples; the in-loop `Imu` sensor calls it with one
sample, the static record (`imu_static`) with blocks of many: same code, same draws.
"""

from __future__ import annotations

import numpy as np

from testbench.core.interfaces import BuildContext, WorldView
from testbench.core.messages import ImuSample, TruthState
from testbench.core.registry import register
from testbench.sensors.base import CachedSensor, check_rate
from testbench.sensors.imu_params import ImuParams, ImuSpec, TriadSpec
from testbench.sensors.noise import TriadNoise


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

    def apply(self, x: np.ndarray, extra: np.ndarray | float = 0.0) -> np.ndarray:
        """Sensed values (n, 3) for true values x (n, 3); `extra` is added before saturation."""
        y = x @ self.matrix.T + self.nl * x * x + self.bias + extra
        y = y + self.noise.sample_block(x.shape[0], self.rng)
        y = np.clip(y, -self.spec.range_q, self.spec.range_q)
        if self.spec.lsb > 0:
            y = np.round(y / self.spec.lsb) * self.spec.lsb
        return y


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

    @property
    def gyro_bias_rps(self) -> np.ndarray:
        """Current total gyro bias (turn-on + slow processes), shape (3,) rad/s (for tests)."""
        return self._gyro.bias + self._gyro.noise.bias_b

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
        self._prev_t = 0.0

    def _sample(self, truth: TruthState, world: WorldView, rng: np.random.Generator) -> ImuSample:
        w = np.asarray(truth.omega_ib_b_rps, float)
        f = np.asarray(truth.f_b_mps2, float)
        r = self.spec.lever_arm_b_m
        if np.any(r):
            # Angular acceleration by a backward difference of the sampled rates.
            dt = truth.t_s - self._prev_t
            wdot = (w - self._prev_w) / dt if self._prev_w is not None and dt > 0 else np.zeros(3)
            f = f + np.cross(wdot, r) + np.cross(w, np.cross(w, r))
        self._prev_w, self._prev_t = w, truth.t_s
        w_meas, f_meas = self.model.apply(w[None, :], f[None, :], rng)
        return ImuSample(truth.t_s, w_meas[0], f_meas[0])
