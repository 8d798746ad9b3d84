"""Allan-deviation analysis of a static IMU record (IEEE Std 952 / 1293 noise terms).

Overlapping Allan deviation from allantools; from its log-log curve:
- white noise N (ARW / VRW): the slope -1/2 line fitted where the curve falls with slope
  <= -0.4 at short tau, read at tau = 1 s;
- rate random walk K: the slope +1/2 line fitted where the curve rises with slope >= +0.3 at
  long tau, read at tau = 3 s (None when the record shows no such region);
- bias instability B: the flat floor / 0.664, where the floor is the median, over the taus
  between the white-noise crossover and a tenth of the record, of the Allan deviation with the
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
    # Rate random walk: a rise at about +1/2 over at least 0.4 decade, read below a fifth of
    # the record (beyond it the curve has too few averages to show a slope).
    k = None
    usable = np.flatnonzero(taus <= record_s / 5.0)
    if len(usable) >= 3:
        last = usable[-1]
        start = last
        while start > 0 and slope[start - 1] >= 0.3:
            start -= 1
        if slope[last] >= 0.3 and lt[last] - lt[start] >= 0.4:
            sl = slice(start, last + 1)
            k = float(10 ** np.mean(la[sl] - 0.5 * (lt[sl] - np.log10(3.0))))
    b_min = float(adev.min() / FLICKER_FLOOR)
    var = adev**2 - white**2 / taus - ((k or 0.0) ** 2) * taus / 3.0
    sel = (white / np.sqrt(taus) < adev.min()) & (taus <= record_s / 10.0) & (var > 0)
    if k is not None:
        sel &= k * np.sqrt(taus / 3.0) < adev.min()
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
