"""Allan-deviation analysis of a static IMU record (IEEE Std 952 / 1293 noise terms).

Overlapping Allan deviation from allantools; from its log-log curve:
- white noise N (ARW / VRW): the slope -1/2 line fitted where the curve falls with slope
  <= -0.4 at short tau, read at tau = 1 s;
- rate random walk K: the slope +1/2 line K sqrt(tau / 3), read at tau = 3 s, from a relative
  least-squares fit of N^2/tau + C + K^2 tau/3 to the Allan variance up to a fifth of the record
  (None unless that line rises to twice the floor within the record);
- bias instability B: the flat floor / 0.664, where the floor is the median, over the taus
  where white noise is under 3/4 of the variance and tau is at most a tenth of the record, of the Allan deviation with the
  fitted white and random-walk parts removed in variance (so the floor is not read off the
  shoulders of the neighbouring slopes). `floor_min` is also given: the curve's minimum / 0.664.
All values in the record's SI units (rad/s or m/s^2 based).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import allantools
import numpy as np

FLICKER_FLOOR = 0.664  # ADEV floor of 1/f noise per unit bias instability: sqrt(2 ln 2 / pi)


@dataclass(frozen=True)
class AllanFit:
    """Fitted noise terms of one channel and the curve they came from."""

    white_density: float  # q*sqrt(s)  (N: ADEV at tau = 1 s of the -1/2 line)
    bias_instability: float  # q      (floor / 0.664)
    bias_instability_min: float  # q  (curve minimum / 0.664)
    rate_random_walk: float | None  # q/sqrt(s) (K: ADEV at tau = 3 s of the +1/2 line)
    taus_s: np.ndarray
    adev: np.ndarray

    def as_dict(self) -> dict:
        d = asdict(self)
        d["taus_s"] = self.taus_s.tolist()
        d["adev"] = self.adev.tolist()
        return d


def allan_curve(y: np.ndarray, rate_hz: float, per_decade: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Overlapping ADEV of rate samples y (n,) at log-spaced taus up to a third of the record."""
    n = len(y)
    dt = 1.0 / rate_hz
    m = np.unique(np.round(np.logspace(0, np.log10(n / 3), int(per_decade * np.log10(n / 3)) + 1)).astype(int))
    taus, adev, _, _ = allantools.oadev(np.asarray(y, float), rate=rate_hz, data_type="freq", taus=m * dt)
    return np.asarray(taus), np.asarray(adev)


def fit_allan(taus: np.ndarray, adev: np.ndarray, record_s: float) -> AllanFit:
    """Fit N, B, K (see module doc) to one ADEV curve."""
    lt, la = np.log10(taus), np.log10(adev)
    slope = np.gradient(la, lt)
    # White noise: leading run of points falling at about -1/2 (steeper than -0.45, so the
    # flicker shoulder does not lift the line).
    run = np.flatnonzero(slope > -0.45)
    end = max(run[0] if len(run) else len(taus), 2)
    white = 10 ** np.mean(la[:end] + 0.5 * lt[:end])
    # Rate random walk: least squares of AVAR = c0/tau + c1 + c2 tau (relative weights) over
    # tau <= a fifth of the record; the +1/2 line K sqrt(tau/3) is kept only when it rises
    # to twice the floor within that span (otherwise the record shows no rate random walk).
    k = None
    use = taus <= record_s / 5.0
    if use.sum() >= 5:
        t_u, v_u = taus[use], adev[use] ** 2
        design = np.column_stack([1.0 / t_u, np.ones_like(t_u), t_u]) / v_u[:, None]
        c0, c1, c2 = np.linalg.lstsq(design, np.ones_like(t_u), rcond=None)[0]
        if c2 > 0 and c2 * t_u[-1] > 2.0 * max(c1, 0.0):
            k = float(np.sqrt(3.0 * c2))
    b_min = float(adev.min() / FLICKER_FLOOR)
    var = adev**2 - white**2 / taus - ((k or 0.0) ** 2) * taus / 3.0
    # Floor region: white noise below 3/4 of the variance (its fitted part is removed anyway)
    # and tau at most a tenth of the record (enough averages for a stable reading).
    sel = (white**2 / taus < 0.75 * adev**2) & (taus <= record_s / 10.0) & (var > 0)
    if k is not None:
        sel &= k**2 * taus / 3.0 < 0.75 * adev**2
    b = float(np.sqrt(np.median(var[sel])) / FLICKER_FLOOR) if sel.any() else b_min
    return AllanFit(float(white), b, b_min, k, taus, adev)


def analyse_record(record: dict[str, np.ndarray], channels: list[str] | None = None) -> dict[str, AllanFit]:
    """Fit every gyro_/accel_ channel of a static record (columns as in imu_static.COLUMNS)."""
    t = np.asarray(record["t_s"], float)
    rate = (len(t) - 1) / (t[-1] - t[0])
    names = channels or [c for c in record if c.startswith(("gyro_", "accel_"))]
    out = {}
    for c in names:
        taus, adev = allan_curve(record[c], rate)
        out[c] = fit_allan(taus, adev, len(t) / rate)
    return out
