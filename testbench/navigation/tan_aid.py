"""The terrain-aided navigation aid "tan": radar altimeter ranges + the INS estimate + the DEM the
vehicle carries -> position fixes for the navigator.

Ranges are gathered over a window (window_s) along the track the INS dead-reckons from the
window's start (its estimated velocity integrated, so that corrections the filter makes
meanwhile do not bend the track); a point-mass filter (tan.pmf) finds where on the onboard
DEM that track's terrain profile lies. At the window's end the density becomes one fix, at
the dead-reckoned end point moved by the density's mean offset, with its covariance, when the
terrain said enough: the profile rough enough (min_roughness_m), the density single-peaked
(min_mass) and narrow (max_fix_sigma_m), not pressed against the grid's edge. The next window
starts afresh from the filter's estimate then, so the fixes share no ranges (each is a new
look at other ground), the same contract as a scene-matching fix.

Each window is one row of events/tan.parquet (its truth columns filled by the engine: this
module never sees truth), with the fix, its velocity lag (lag_nn_s ... lag_ee_s: the 2 x 2
horizontal matrix the navigator fuses; vel_lag_s its diagonal's mean) and the window's start,
from which scoring takes the density's own error; mean_north_m, mean_east_m place the offset on
the dead-reckoned track at t_s - vel_lag_s. Over flat ground TAN cannot fix: the rows then say
"flat".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import pydantic

from testbench.core.errors import InputError
from testbench.core.interfaces import BuildContext, NavigationAid
from testbench.core.messages import NavEstimate, PositionFix, RadarAltSample
from testbench.core.registry import ParamsModel, register
from testbench.core.rotations import quat_to_dcm
from testbench.navigation.fix_columns import position_fix_columns
from testbench.navigation.tan.pmf import TerrainPmf
from testbench.world.raster import LocalRaster, sample_bilinear

_NAN = float("nan")


@dataclass
class TanAttempt:
    """One window's outcome, turned into a recorder row after the navigator has seen the fix."""

    t_s: float
    fix: PositionFix | None
    samples: int
    roughness_m: float
    reason: str = ""
    mean_ne_m: tuple[float, float] = (_NAN, _NAN)
    mass_in_ellipse: float = _NAN
    edge_mass: float = _NAN
    outliers: int = 0
    lag_s: float = _NAN
    lag_ne_s: np.ndarray | None = None  # (2, 2) the fix's velocity lag, north-east (s)
    window_start_s: float = _NAN
    misfit_per_dof: float = _NAN

    def event_rows(self, vehicle_id: str) -> list[tuple[str, dict]]:
        fix = self.fix
        cov = fix.cov_ned_m2 if fix is not None else None
        row = dict(
            t_s=self.t_s, vehicle_id=vehicle_id, fix=fix is not None, accepted=None, **position_fix_columns(fix),
            cov_ne_m2=float(cov[0, 1]) if cov is not None else _NAN,
            vel_lag_s=float(self.lag_s) if fix is not None else _NAN,
            **{f"lag_{a}{b}_s": (float(self.lag_ne_s[i, j]) if fix is not None and self.lag_ne_s is not None else _NAN)
               for i, a in enumerate("ne") for j, b in enumerate("ne")},
            window_start_s=float(self.window_start_s),
            mean_north_m=float(self.mean_ne_m[0]), mean_east_m=float(self.mean_ne_m[1]),
            samples=int(self.samples), roughness_m=float(self.roughness_m),
            mass_in_ellipse=float(self.mass_in_ellipse), edge_mass=float(self.edge_mass), outliers=int(self.outliers),
            misfit_per_dof=float(self.misfit_per_dof),
            reason=self.reason,
            truth_north_m=_NAN, truth_east_m=_NAN, truth_down_m=_NAN, truth_height_agl_m=_NAN,
        )
        return [("tan", row)]


@dataclass
class _Window:
    """The ranges gathered since the window started: the point-mass filter over the
    dead-reckoned track and the DEM under its grid, that track's end (NE, m), the estimated
    velocity last used, and each range as taken (antenna NED m, R_nb, range m, sigma m), so
    that a wider grid can search them again."""

    t0_s: float
    start_ne_m: np.ndarray
    reach_m: float  # how far from start_ne_m the track and its beam may go, besides the grid
    pmf: TerrainPmf
    dem: LocalRaster
    dr_ne_m: np.ndarray
    t_last_s: float
    v_last_ne_mps: np.ndarray
    times_s: list[float] = field(default_factory=list)
    track_ne_m: list[np.ndarray] = field(default_factory=list)
    ranges: list[tuple[np.ndarray, np.ndarray, float, float]] = field(default_factory=list)


@register("aid", "tan")
class TanAid(NavigationAid):
    """Terrain-aided position fixes from one radar altimeter and the onboard DEM.

    Params: sensor (the radar altimeter's name); window_s (ranges per fix, s); every_n (use one
    range in N); cells (grid points per horizontal axis, odd; more, up to max_cells, where the
    grid would otherwise step farther than the DEM's own sample); n_sigma and min_half_width_m
    (grid half width: n_sigma of the navigator's horizontal sigmas, at least this);
    dem_sigma_m, dem_correlation_m (the onboard DEM's error against the ground the radar sees,
    1 sigma, m, and its Gaussian correlation length, m, as world.reference_elevation_error's
    correlation_m; 0: white); outlier_sigmas (a range off the
    model by more is dropped: trees, masts, water; a window that drops more than
    max_outlier_share of its ranges gives no fix: the match explains too little of what the
    radar saw; nor does one whose best match still misses the ranges by more than max_misfit
    times the chi-square they should give (below that the fix's claim grows by the misfit),
    or whose height offset lies beyond
    max_height_sigmas of what the navigator's height, the match and the DEM allow: ground the
    DEM does not hold, such as a town's roofs in the beam); min_samples,
    min_roughness_m (the window's terrain
    profile: its standard deviation less the altimeter's noise, m), min_mass, max_edge_mass, max_fix_sigma_m (the
    density's acceptance); fix_sigma_floor_m (added per axis to the fix's claim, m);
    max_tilt_deg (ranges taken banked or pitched beyond it are skipped: the beam looks sideways);
    max_widen (a window whose density presses against its grid's edge is searched again, on
    its own ranges, on a grid twice as wide, up to this factor); velocity_lag: "model" hands the fix's velocity lag to the
    navigator (PositionFix.vel_lag_s, a 2 x 2 horizontal matrix, which ins_ekf fuses), "inflate"
    adds the lag (its largest singular value) times the navigator's velocity sigma to the fix's
    claim instead, for a navigator that ignores
    vel_lag_s (20 runs of tan_radalt_300m: see docs/measurements.md, terrain-aided navigation).
    """

    class Params(ParamsModel):
        sensor: str = "radar_altimeter"
        window_s: float = pydantic.Field(20.0, gt=0)
        every_n: int = pydantic.Field(2, ge=1)
        cells: int = pydantic.Field(61, ge=5)
        max_cells: int = pydantic.Field(121, ge=5)
        n_sigma: float = pydantic.Field(4.0, gt=0)
        min_half_width_m: float = pydantic.Field(60.0, gt=0)
        dem_sigma_m: float = pydantic.Field(1.0, ge=0)
        dem_correlation_m: float = pydantic.Field(0.0, ge=0)
        outlier_sigmas: float = pydantic.Field(4.0, gt=0)
        max_outlier_share: float = pydantic.Field(0.1, ge=0, le=1)
        max_misfit: float = pydantic.Field(6.0, gt=0)
        max_height_sigmas: float = pydantic.Field(4.0, gt=0)
        min_samples: int = pydantic.Field(20, ge=1)
        min_roughness_m: float = pydantic.Field(1.5, ge=0)
        min_mass: float = pydantic.Field(0.95, ge=0, le=1)
        max_edge_mass: float = pydantic.Field(0.01, ge=0, le=1)
        max_fix_sigma_m: float = pydantic.Field(60.0, gt=0)
        fix_sigma_floor_m: float = pydantic.Field(1.0, ge=0)
        max_tilt_deg: float = pydantic.Field(35.0, gt=0, le=90)
        max_widen: float = pydantic.Field(4.0, ge=1)
        velocity_lag: Literal["model", "inflate"] = "model"

        @pydantic.field_validator("cells", "max_cells")
        @classmethod
        def _odd(cls, v: int) -> int:
            if v % 2 == 0:
                raise ValueError(f"must be odd (the grid holds the zero offset), got {v}")
            return v

    def __init__(self, params: Params, *, ctx: BuildContext, sensors: dict, onboard: dict, **_: Any):
        self.params = params
        where = f"vehicles[{ctx.vehicle_id}].aids[tan]"
        sensor = sensors.get(params.sensor)
        if sensor is None:
            raise InputError(f"{where}.params.sensor: no sensor named {params.sensor!r} on this vehicle "
                             f"(have: {', '.join(sensors) or 'none'})")
        if getattr(sensor, "rays_b", None) is None:
            raise InputError(f"{where}.params.sensor: sensor {params.sensor!r} is not a radar altimeter")
        # The altimeter's beam and noise are its datasheet: the vehicle knows them.
        self.sensor_name = params.sensor
        self.rays_b = np.asarray(sensor.rays_b, float)
        sp = sensor.params
        self._noise_m, self._noise_fraction = float(sp.noise_m), float(sp.noise_fraction)
        self._lever_b = np.asarray(sp.lever_arm_b_m, float)
        self._beam_tan = math.tan(float(sensor.beam_half_angle_rad))
        self.dem = onboard["reference_elevation"]()
        if self.dem is None:
            raise InputError(f"{where}: terrain-aided navigation needs a DEM onboard: world.reference_elevation "
                             "or world.elevation (a GeoTIFF or a procedural: world)")
        self._dem_gsd_m = float(getattr(self.dem, "native_gsd_m", None) or 10.0)
        self._n = 0
        self._win: _Window | None = None

    def accepts(self, measurement: Any) -> bool:
        return isinstance(measurement, RadarAltSample)

    # -- the window -------------------------------------------------------------------------

    def _start(self, t_s: float, est: NavEstimate, range_m: float) -> _Window:
        p = self.params
        cov = np.asarray(est.cov_pos_ned_m2, float)
        sigma_h = math.sqrt(max(float(np.linalg.eigvalsh(cov[:2, :2]).max()), 1e-6))
        half = max(p.n_sigma * sigma_h, p.min_half_width_m)
        v_ne = np.asarray(est.vel_ned_mps, float)[:2]
        # Beyond the grid: the track ahead and the beam's footprint at this height.
        reach = float(np.hypot(*v_ne)) * p.window_s * 1.2 + range_m * (self._beam_tan + 0.2) + 3.0 * self._dem_gsd_m
        start = np.asarray(est.pos_ned_m[:2], float).copy()
        pmf, dem = self._grid(half, start, reach)
        return _Window(t_s, start, reach, pmf, dem, start.copy(), t_s, v_ne.copy())

    def _grid(self, half_m: float, start_ne_m: np.ndarray, reach_m: float) -> tuple[TerrainPmf, LocalRaster]:
        """An empty point-mass grid of half width half_m and the onboard DEM under all it can
        see from a window starting at start_ne_m."""
        p = self.params
        # A grid coarser than the DEM would step over the likelihood's peaks (their width is the
        # terrain's, about a DEM sample) and could land a node on a false one: finer, up to max_cells.
        cells = min(max(p.cells, 2 * math.ceil(half_m / self._dem_gsd_m) + 1), max(p.max_cells, p.cells))
        n0, e0 = (float(x) for x in start_ne_m)
        r = half_m + reach_m
        # On the DEM's own posting (edges at whole samples from the origin, as the terrain's
        # tiles are): a window cut anywhere else is resampled, which smooths the ridges by up to
        # 3.7 m (desert) and gives the onboard DEM an error the likelihood does not model.
        g = self._dem_gsd_m
        dem = self.dem.read_local(math.floor((n0 - r) / g) * g, math.ceil((n0 + r) / g) * g,
                                  math.floor((e0 - r) / g) * g, math.ceil((e0 + r) / g) * g, g)
        return TerrainPmf(half_m, cells, p.dem_sigma_m, p.dem_correlation_m), dem

    def _fold(self, pmf: TerrainPmf, dem: LocalRaster, antenna, R_nb, range_m: float, sigma_m: float) -> None:
        """One range into the grid, over the DEM raster under it (NaN off the DEM)."""
        def height_m(north_m, east_m):
            v, ok = sample_bilinear(dem, north_m, east_m)
            return np.where(ok, v, np.nan)

        pmf.update(antenna, R_nb, self.rays_b, range_m, sigma_m, height_m)

    def process(self, measurement: Any, estimate: NavEstimate) -> tuple[list, TanAttempt | None]:
        self._n += 1
        if (self._n - 1) % self.params.every_n:
            return [], None
        p = self.params
        t = float(measurement.t_s)
        r = float(measurement.range_m)
        roll, pitch = (abs(float(x)) for x in estimate.rpy_rad[:2])
        if max(roll, pitch) > math.radians(p.max_tilt_deg):
            return [], None
        if self._win is None:
            self._win = self._start(t, estimate, r)
        w = self._win
        v_ne = np.asarray(estimate.vel_ned_mps, float)[:2]
        # Dead reckoning on the estimated velocity (trapezoid): a position correction inside the
        # window moves the filter, not this track.
        w.dr_ne_m = w.dr_ne_m + 0.5 * (w.v_last_ne_mps + v_ne) * (t - w.t_last_s)
        w.t_last_s, w.v_last_ne_mps = t, v_ne
        R_nb = quat_to_dcm(estimate.q_nb_wxyz)
        d_m = float(estimate.pos_ned_m[2])
        antenna = np.array([w.dr_ne_m[0], w.dr_ne_m[1], d_m]) + R_nb @ self._lever_b
        sigma = math.hypot(self._noise_m, self._noise_fraction * r)  # the altimeter's own; the DEM's is the pmf's
        self._fold(w.pmf, w.dem, antenna, R_nb, r, sigma)
        w.ranges.append((antenna, R_nb, r, sigma))
        w.times_s.append(t)
        w.track_ne_m.append(w.dr_ne_m.copy())
        if t - w.t0_s + 1e-9 < p.window_s:
            return [], None
        self._win = None
        fix, attempt = self._finish(w, t, d_m, estimate)
        return ([fix] if fix is not None else []), attempt

    def _finish(self, w: _Window, t_s: float, d_m: float, est: NavEstimate) -> tuple[PositionFix | None, TanAttempt]:
        """The window's fix (or None) and its attempt row; d_m, est: the estimate at t_s."""
        p = self.params
        n = w.pmf.updates
        # The terrain profile's own spread: its SD as ranged, less the altimeter's noise in it
        # (flat ground ranged with 1.5 m of noise is no rougher than flat ground).
        # (The terrain's height under the track, as ranged: the antenna's height less the range.)
        profile_m = [-antenna[2] - r for antenna, _, r, _ in w.ranges]
        noise_var = float(np.mean([sig**2 for *_, sig in w.ranges])) if w.ranges else 0.0
        roughness = math.sqrt(max(float(np.var(profile_m)) - noise_var, 0.0)) if profile_m else 0.0
        try:
            post = w.pmf.posterior(p.outlier_sigmas)
            half0, widen = float(w.pmf.offsets_m[-1]), 2.0
            # Pressed against the grid's edge: the navigator claimed less than it errs by, and
            # the same ranges are searched again on a grid twice as wide (and again).
            while post.edge_mass > p.max_edge_mass and widen <= p.max_widen:
                w.pmf, w.dem = self._grid(half0 * widen, w.start_ne_m, w.reach_m)
                for antenna, R_nb, r, sigma in w.ranges:
                    self._fold(w.pmf, w.dem, antenna, R_nb, r, sigma)
                post = w.pmf.posterior(p.outlier_sigmas)
                widen *= 2.0
        except ValueError:  # the whole search region off the onboard DEM
            return None, TanAttempt(t_s, None, n, roughness, "off the DEM")
        sig = math.sqrt(max(float(np.linalg.eigvalsh(post.cov_ne_m2).max()), 0.0))
        reason = ""
        if n < p.min_samples:
            reason = "few ranges"
        elif roughness < p.min_roughness_m:
            reason = "flat"
        elif post.edge_mass > p.max_edge_mass:  # (first: a grid that misses the truth fits badly too)
            reason = "at grid edge"
        elif post.outliers > p.max_outlier_share * n:
            reason = "outliers"
        elif post.misfit_per_dof > p.max_misfit:
            reason = "misfit"
        elif post.mean_dh_m**2 > p.max_height_sigmas**2 * (float(est.cov_pos_ned_m2[2, 2]) + post.var_dh_m2 + p.dem_sigma_m**2):
            reason = "height"
        elif post.mass_in_ellipse < p.min_mass:
            reason = "ambiguous"
        elif sig > p.max_fix_sigma_m:
            reason = "wide"
        if reason:
            return None, TanAttempt(t_s, None, n, roughness, reason, mass_in_ellipse=post.mass_in_ellipse,
                                    edge_mass=post.edge_mass, outliers=post.outliers, misfit_per_dof=post.misfit_per_dof)
        # The offset found is the track's over the window, which a velocity error e_v tilts:
        # the true offset drifts as o(t) = o(t_s) + (t_s - t) e_v, and the match weighs each
        # range by the slopes it saw (PmfPosterior.lag_weights), so the offset found is
        # o(t_s) + L e_v with L = sum_k W_k (t_s - t_k), a 2 x 2 lag (s): where the terrain spoke
        # and along which axis, not the ranges' mean epoch for both (t_s - mean where the grid
        # cannot give the slopes). The fix carries it to t_s on the dead-reckoned track, so it
        # errs by L e_v: the navigator fuses that (PositionFix.vel_lag_s, horizontal; the heights
        # are the navigator's own, not dead-reckoned, so the vertical has no lag).
        times = np.asarray(w.times_s)
        if post.lag_weights is None:
            lag_ne = np.eye(2) * (t_s - float(times.mean()))
        else:
            lag_ne = np.einsum("kij,k->ij", post.lag_weights, t_s - times)
        lag_s = 0.5 * float(np.trace(lag_ne))  # the two axes' mean lag: for the row and "inflate"
        floor = p.fix_sigma_floor_m**2
        cov = np.zeros((3, 3))
        if p.velocity_lag == "model":
            # The navigator takes the drift's whole effect on the fix through the lag (H_v = -L).
            shape = lag_var = 0.0
        else:
            # A navigator blind to the lag: its term as noise, and the track's bend about the
            # window's middle (the ranges up to sigma_v T / 2 off a constant offset: a spread of
            # sigma_v T / sqrt(12)).
            var_v = float(np.linalg.eigvalsh(np.asarray(est.cov_vel_ned_m2s2, float)[:2, :2]).max())
            lag_var = var_v * float(np.linalg.norm(lag_ne, 2)) ** 2
            shape = var_v * (t_s - w.t0_s) ** 2 / 12.0
        # A match that fits worse than its model says (misfit above 1: the dead-reckoned track
        # bent by a velocity error, a DEM error unlike the assumed one) is less sure than its
        # density: its spread is scaled by the misfit (the Birge ratio).
        inflate = max(post.misfit_per_dof, 1.0)
        cov[:2, :2] = post.cov_ne_m2 * inflate + np.eye(2) * (shape + floor + lag_var)
        cov[2, 2] = post.var_dh_m2 * inflate + floor
        pos = np.array([w.dr_ne_m[0] + post.mean_ne_m[0], w.dr_ne_m[1] + post.mean_ne_m[1], d_m - post.mean_dh_m])
        quality = float(post.mass_in_ellipse)
        lag_ned = np.zeros((3, 3))
        lag_ned[:2, :2] = lag_ne
        fix = PositionFix(t_s, pos, cov, quality, source="tan", vel_lag_s=lag_ned if p.velocity_lag == "model" else None)
        # For the table: the same offset on the track at the axes' mean lag (interpolated: the
        # ranges come every 0.2 s, 5 m apart at 25 m/s); scoring uses the full lag (metrics_tan).
        track = np.asarray(w.track_ne_m)
        mean_ne = np.array([np.interp(t_s - lag_s, times, track[:, 0]), np.interp(t_s - lag_s, times, track[:, 1])]) \
            + post.mean_ne_m
        return fix, TanAttempt(t_s, fix, n, roughness, mean_ne_m=(float(mean_ne[0]), float(mean_ne[1])),
                               mass_in_ellipse=quality, edge_mass=post.edge_mass, outliers=post.outliers, lag_s=lag_s,
                               lag_ne_s=lag_ne, window_start_s=float(w.t0_s),
                               misfit_per_dof=post.misfit_per_dof)
