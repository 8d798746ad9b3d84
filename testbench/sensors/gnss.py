"""GNSS receiver: position and velocity with noise, latency and rate, and the denial cases.

Position error = white noise + a first-order Gauss-Markov part (multipath, atmosphere; time
constant pos_corr_s); velocity error white. Per axis (N, E, D) sigmas.

Denial windows (scenario time, start_s <= t < end_s):
- jamming: no fix at all;
- degraded: every sigma (true error and the receiver's claim) times sigma_scale;
- spoofing: the fix is dragged off by offset_ned_m plus a drift whose velocity is
  drift_ned_mps, at once, or (accel_mps2) ramped up at that acceleration as a carry-off attack
  does so that the receiver's tracking loops and the navigator's velocity gate see no step
  (`spoof_offset`); the receiver reports its usual sigmas (it does not know).
Obstructions (`sky`, off unless given): the satellites in view (gnss_sky.py) decide whether
there is a fix at all (at least four, their PDOP within the receiver's mask) and scale its
errors by their geometry (DOP); each sample's view is recorded (`event_rows`, table gnss_sky).
Latency: a fix valid at t is delivered at the first sample tick at or after t + latency_s.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Annotated, Literal, Union

import numpy as np
from pydantic import Field, model_validator

from testbench.core.geodesy import ned_to_geodetic
from testbench.core.interfaces import BuildContext, WorldView
from testbench.core.messages import GnssFix, TruthState
from testbench.core.registry import ParamsModel, register
from testbench.sensors.base import CachedSensor, check_rate
from testbench.sensors.gnss_sky import SkyModel, dop


class Jamming(ParamsModel):
    type: Literal["jamming"]
    start_s: float
    end_s: float = math.inf


class Degraded(ParamsModel):
    type: Literal["degraded"]
    start_s: float
    end_s: float = math.inf
    sigma_scale: float = Field(5.0, gt=0)


class Spoofing(ParamsModel):
    """A spoofer that has captured the receiver at start_s (its signals aligned with the true
    ones) and drags its fix: offset_ned_m (m) at once, plus a drift at drift_ned_mps (NED m/s),
    reached at once (accel_mps2 None) or ramped up at accel_mps2 (m/s^2, the carry-off of
    Humphreys et al. 2008 and Kerns et al. 2014: slow enough that neither the receiver's
    tracking loops nor a velocity gate see a step)."""

    type: Literal["spoofing"]
    start_s: float
    end_s: float = math.inf
    drift_ned_mps: tuple[float, float, float] = (1.0, 0.0, 0.0)
    offset_ned_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    accel_mps2: float | None = Field(None, gt=0)


def spoof_offset(w: Spoofing, t_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The spoofer's drag at time t_s (>= w.start_s): (position offset (3,) NED m, velocity
    offset (3,) NED m/s). With accel_mps2 the drift speed grows as accel tau (tau = t_s -
    start_s) until it reaches |drift_ned_mps| at tau_r = |drift| / accel, so the offset is
    accel tau^2 / 2 along the drift until then and |drift| (tau - tau_r / 2) after."""
    drift = np.asarray(w.drift_ned_mps, float)
    tau = max(t_s - w.start_s, 0.0)
    speed = float(np.linalg.norm(drift))
    if w.accel_mps2 is None or speed == 0.0:
        return np.asarray(w.offset_ned_m, float) + drift * tau, drift
    u = drift / speed
    tau_r = speed / w.accel_mps2
    if tau < tau_r:
        return np.asarray(w.offset_ned_m, float) + u * (0.5 * w.accel_mps2 * tau * tau), u * (w.accel_mps2 * tau)
    return np.asarray(w.offset_ned_m, float) + u * (speed * (tau - 0.5 * tau_r)), drift


DenialWindow = Annotated[Union[Jamming, Degraded, Spoofing], Field(discriminator="type")]


class SkyParams(ParamsModel):
    """The satellites the receiver sees (gnss_sky.py): a Walker n_sats / n_planes / phasing
    constellation at GPS's orbit and inclination_deg, above mask_deg elevation, not cut by
    world.obstacles or the terrain within ray_m (terrain sampled every terrain_step_m);
    epoch_s: constellation time at the run's start. Fewer than min_satellites, or a geometry
    whose PDOP exceeds max_pdop (a receiver's PDOP mask; 25 is a common default): no fix. Else
    the position and velocity errors and the receiver's claims scale, axis by axis
    (north, east, down), by the DOP over the open sky's at that place and time: the
    configured sigmas are the open-sky figures."""

    n_sats: int = Field(30, ge=4, le=200)
    n_planes: int = Field(5, ge=1)
    phasing: int = Field(2, ge=0)
    inclination_deg: float = Field(55.0, ge=0, le=180)
    mask_deg: float = Field(10.0, ge=0, lt=90)
    min_satellites: int = Field(4, ge=4)
    max_pdop: float = Field(25.0, gt=0)
    epoch_s: float = 0.0
    ray_m: float = Field(3000.0, gt=0)
    terrain_step_m: float = Field(10.0, gt=0)

    @model_validator(mode="after")
    def _planes_divide(self):
        if self.n_sats % self.n_planes:
            raise ValueError(f"{self.n_sats} satellites do not split evenly into {self.n_planes} planes "
                             "(expected n_sats a multiple of n_planes)")
        return self


class GnssParams(ParamsModel):
    """Sigmas are 1-sigma per axis; defaults are of a single-frequency SPS receiver."""

    rate_hz: float = Field(5.0, gt=0)
    latency_s: float = Field(0.0, ge=0)
    pos_sigma_ne_m: float = Field(1.5, ge=0)
    pos_sigma_d_m: float = Field(3.0, ge=0)
    pos_corr_sigma_m: float = Field(1.0, ge=0)
    pos_corr_s: float = Field(60.0, gt=0)
    vel_sigma_mps: float = Field(0.1, ge=0)
    denial: list[DenialWindow] = []
    sky: SkyParams | None = None


def _active(windows, t_s: float):
    return [w for w in windows if w.start_s <= t_s < w.end_s]


@register("sensor", "gnss")
class Gnss(CachedSensor):
    """Returns GnssFix, or None while jammed or before the first fix is due."""

    Params = GnssParams

    def __init__(self, params: GnssParams, *, ctx: BuildContext):
        super().__init__()
        self.params = params
        self.name = "gnss"
        self.rate_hz = check_rate(params.rate_hz, ctx, "gnss")
        self.dt_s = 1.0 / self.rate_hz
        self.origin = ctx.origin
        self._corr: np.ndarray | None = None
        self._queue: deque[GnssFix] = deque()
        sky = params.sky
        self._sky = None if sky is None else SkyModel(sky.n_sats, sky.n_planes, sky.phasing, sky.inclination_deg,
                                                      sky.mask_deg, sky.epoch_s, sky.ray_m, sky.terrain_step_m)
        self.last_satellites: tuple[int, int] | None = None  # (visible, above the mask) at the last sample
        self._sky_rows: list[dict] = []  # this sample's row for the record (event_rows)

    def _sample(self, truth: TruthState, world: WorldView, rng: np.random.Generator) -> GnssFix | None:
        p = self.params
        t = truth.t_s
        z = rng.standard_normal(9)  # always drawn: the stream does not depend on the windows
        a = math.exp(-self.dt_s / p.pos_corr_s)
        if self._corr is None:
            self._corr = p.pos_corr_sigma_m * z[:3]
        else:
            self._corr = a * self._corr + p.pos_corr_sigma_m * math.sqrt(1.0 - a * a) * z[:3]
        active = _active(p.denial, t)
        sky_scale = self._sky_scale(truth, world) if self._sky is not None else 1.0
        if not any(w.type == "jamming" for w in active) and sky_scale is not None:
            scale = math.prod(w.sigma_scale for w in active if w.type == "degraded") * sky_scale
            pos_sigma = np.array([p.pos_sigma_ne_m, p.pos_sigma_ne_m, p.pos_sigma_d_m])
            err = scale * (pos_sigma * z[3:6] + self._corr)
            vel_err = scale * p.vel_sigma_mps * z[6:9]
            for w in active:
                if w.type == "spoofing":
                    d_pos, d_vel = spoof_offset(w, t)
                    err = err + d_pos
                    vel_err = vel_err + d_vel
            lat, lon, alt = ned_to_geodetic(
                np.asarray(truth.pos_ned_m, float) + err, self.origin.lat_rad, self.origin.lon_rad, self.origin.alt_m
            )
            claim = scale * np.sqrt(pos_sigma**2 + p.pos_corr_sigma_m**2)
            self._queue.append(
                GnssFix(t, float(lat), float(lon), float(alt), np.asarray(truth.vel_ned_mps, float) + vel_err,
                        claim, scale * np.full(3, p.vel_sigma_mps))
            )
        out = None
        while self._queue and self._queue[0].t_s + p.latency_s <= t + 1e-9:
            out = self._queue.popleft()  # the newest fix that is due
        return out

    def _sky_scale(self, truth: TruthState, world: WorldView) -> np.ndarray | None:
        """(3,) error scale (N, E, D) from the satellites in view: each axis's DOP over the open
        sky's, or None when fewer than params.sky.min_satellites are in view or their PDOP is
        beyond params.sky.max_pdop (no fix)."""
        los = self._sky.lines_of_sight(truth.t_s, truth.lat_rad, truth.lon_rad, truth.alt_m)
        seen = self._sky.visible(los, truth.pos_ned_m, world)
        self.last_satellites = (int(seen.sum()), len(los))
        open_sky = dop(los)
        here = dop(los[seen]) if seen.sum() >= self.params.sky.min_satellites else None
        if here is not None and here.pdop > self.params.sky.max_pdop:
            here = None  # the receiver's PDOP mask: four satellites nearly in one plane
        nan = float("nan")
        self._sky_rows = [dict(t_s=float(truth.t_s), satellites_visible=int(seen.sum()), satellites_above_mask=len(los),
                               hdop=here.hdop if here else nan, vdop=here.vdop if here else nan,
                               hdop_open_sky=open_sky.hdop if open_sky else nan, fix=here is not None and open_sky is not None)]
        if open_sky is None or here is None:
            return None
        return np.asarray(here.ned) / np.asarray(open_sky.ned)

    def event_rows(self, vehicle_id: str) -> list[tuple[str, dict]]:
        """The record's rows of the sample just taken, once: table "gnss_sky" (satellites in
        view, above the mask, the DOP there and in the open sky, whether they made a fix),
        with `sky` only; [] otherwise."""
        rows, self._sky_rows = self._sky_rows, []
        return [("gnss_sky", dict(vehicle_id=vehicle_id, **r)) for r in rows]
