"""Typed results of scoring: a tree of frozen dataclasses that reports and batches consume.

`MetricsResult.to_dict()` gives the nested dict written to metrics.json (DESIGN.md output
contract); `flatten()` turns any nested dict into dotted keys ("nav.horizontal_error_m.rms")
for thresholds and Monte Carlo tables. Fields that are None (no data for them in the run)
are left out of the dicts, so an absent capability leaves no key behind.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Mapping

from testbench.scoring.result_ismn import IsmnAcquisition, IsmnClouds, IsmnMapError, IsmnMetrics, IsmnPhase  # noqa: F401 -- re-exported
from testbench.scoring.sections import Section as _Section
from testbench.scoring.sections import _convert, section_dict
from testbench.scoring.stats import ChiSquareStats, ErrorStats


@dataclass(frozen=True)
class ControlMetrics(_Section):
    """Guidance/control tracking on truth.

    altitude_error_m: |truth altitude - commanded altitude| (m), every row with a command;
    cross_track_error_m: distance of the true position from the commanded leg line (m), rows
    on a leg; airspeed_error_mps: |true airspeed - commanded| (m/s), rows on a leg;
    bank_max_deg: largest |true roll| (deg);
    waypoint_miss_m: per waypoint reached, the closest true 3-D approach to it while it was the
    active target (m); waypoint_overshoot_m: per waypoint, the largest true distance from the
    path through it (the incoming and outgoing legs) while flying to the next one (m).
    """

    altitude_error_m: ErrorStats | None = None
    cross_track_error_m: ErrorStats | None = None
    airspeed_error_mps: ErrorStats | None = None
    bank_max_deg: float | None = None
    waypoint_miss_m: ErrorStats | None = None
    waypoint_overshoot_m: ErrorStats | None = None


@dataclass(frozen=True)
class GnssSkyStats(_Section):
    """The GNSS receivers' view of the sky (event table gnss_sky, receivers with `sky` only),
    over their samples: satellites_visible / satellites_above_mask: mean and min counts;
    fix_share: share of samples with enough satellites for a fix; hdop: ErrorStats of the HDOP
    over those; hdop_open_sky_median: the open sky's HDOP at the same places and times."""

    satellites_visible_mean: float | None = None
    satellites_visible_min: int | None = None
    satellites_above_mask_mean: float | None = None
    fix_share: float | None = None
    hdop: ErrorStats | None = None
    hdop_open_sky_median: float | None = None
    samples: int = 0


@dataclass(frozen=True)
class CameraBoresightStats(_Section):
    """A navigator's estimate of its scene-matching camera's boresight error against the true
    one (run.json camera_boresight_error_deg of the camera in camera_boresight_estimated), as
    rotation vectors in body axes: error_deg, ErrorStats of |estimate - truth| (deg) over the
    GNSS-denied rows (all rows without any); final_error_deg / final_sigma_deg, |estimate -
    truth| and the root-sum-square of the claimed sigmas at each vehicle's last row (the
    largest over vehicles)."""

    error_deg: ErrorStats | None = None
    final_error_deg: float | None = None
    final_sigma_deg: float | None = None


@dataclass(frozen=True)
class CameraTimeOffsetStats(_Section):
    """A navigator's estimate of its scene-matching camera's time offset (the frames' stamp
    minus their exposure) against the true one (run.json camera_time_offset_s of the camera in
    camera_time_offset_estimated, 0 where its clock is right), in milliseconds: error_ms,
    ErrorStats of |estimate - truth| over the GNSS-denied rows (all rows without any);
    final_error_ms / final_sigma_ms at each vehicle's last row (the largest over vehicles)."""

    error_ms: ErrorStats | None = None
    final_error_ms: float | None = None
    final_sigma_ms: float | None = None


@dataclass(frozen=True)
class CameraIntrinsicsStats(_Section):
    """A navigator's estimate of its scene-matching camera's intrinsics error against the true
    one (run.json camera_intrinsics_error of the camera in camera_intrinsics_estimated):
    principal_point_error_px, ErrorStats of |estimate - truth| of the principal point (px)
    over the GNSS-denied rows (all rows without any); at each vehicle's last row (the largest
    over vehicles) the principal point's error and sigma (norms, px) and the focal length's (ppm)."""

    principal_point_error_px: ErrorStats | None = None
    final_principal_point_error_px: float | None = None
    final_principal_point_sigma_px: float | None = None
    final_focal_error_ppm: float | None = None
    final_focal_sigma_ppm: float | None = None


@dataclass(frozen=True)
class NavSubset(_Section):
    """Navigation error over a subset of time (GNSS-denied, smooth, turning).

    duration_s: time covered by the subset (sum of record intervals of its rows, summed over
    vehicles when the record holds several).
    """

    position_error_m: ErrorStats | None = None
    horizontal_error_m: ErrorStats | None = None
    horizontal_error_pct_agl: ErrorStats | None = None
    duration_s: float | None = None


@dataclass(frozen=True)
class SpoofedNav(NavSubset):
    """Navigation error while a vehicle's GNSS receiver was spoofed (run.json
    gnss_spoofed_windows: its fixes dragged off by a spoofer, sensors.gnss Spoofing), and how
    its navigator took those fixes.

    gnss_accept_rate: share of the GNSS fixes in those windows that the filter fused (passed
    its gate, or reset to: kind "gnss:reset"); gnss_captured_s: the longest, over vehicles and
    windows, time from a window's start to the last fix in it that the filter fused (how long
    the spoofer held the navigator: near 0 when its first dragged fixes were refused, the
    window's length when it held it to the end). None where no GNSS fix was attempted.
    """

    gnss_accept_rate: float | None = None
    gnss_captured_s: float | None = None


@dataclass(frozen=True)
class NisStats(_Section):
    """NIS of one correction kind: chi-square consistency plus acceptance.

    count: corrections attempted; accept_rate: fraction accepted by the filter's gate.
    The chi-square figures (mean, mean_per_dof, frac_in_95, ...) are over all attempts.
    """

    count: int
    accept_rate: float
    chi2: ChiSquareStats | None = None

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"count": self.count, "accept_rate": self.accept_rate}
        if self.chi2 is not None:
            out.update(self.chi2.to_dict())
            out["n"] = self.chi2.n
        return out


@dataclass(frozen=True)
class NavMetrics(_Section):
    """Navigation estimate vs truth.

    position_error_m: 3D |nav - truth| (m); horizontal_error_m: north-east (m, with CEP);
    vertical_error_m: |down error| (m); horizontal_error_pct_agl: horizontal error as a
    percentage of the true height above ground (rows with AGL > 1 m);
    denied / smooth / turning: the same over GNSS-denied rows and per flight phase;
    spoofed: the same over the rows inside GNSS spoofing windows, with the share of the
    spoofed fixes the filter took (SpoofedNav);
    nees: "position" (3 dof, with the recorded north-east covariance), "velocity" and
    "attitude" (3 dof, diagonal sigmas) -> ChiSquareStats; nis: correction kind -> NisStats;
    lost_at_s: when the navigator was lost (metrics_nav.lost_at_s: its position error stayed
    beyond a 5.5-sigma bound of its own covariance for 10 s), None if never;
    wind_error_mps: |estimated - true| horizontal wind (m/s; the truth with its turbulence)
    over the rows where the navigator estimates the wind (with nees "wind", 2 dof), else None;
    gnss_sky: the satellites the receivers saw (GnssSkyStats), None without a sky model;
    camera_boresight: the estimate of the scene-matching camera's boresight against its truth
    (CameraBoresightStats, with nees "camera_boresight", 3 dof), None where no navigator
    estimates one; camera_time_offset: the same of the camera's time offset
    (CameraTimeOffsetStats, nees "camera_time_offset", 1 dof);
    camera_intrinsics: the same of its intrinsics error (CameraIntrinsicsStats, nees
    "camera_intrinsics", 3 dof: principal point u, v and focal length).
    """

    position_error_m: ErrorStats | None = None
    horizontal_error_m: ErrorStats | None = None
    vertical_error_m: ErrorStats | None = None
    horizontal_error_pct_agl: ErrorStats | None = None
    denied: NavSubset | None = None
    spoofed: SpoofedNav | None = None
    smooth: NavSubset | None = None
    turning: NavSubset | None = None
    nees: Mapping[str, ChiSquareStats] = field(default_factory=dict)
    nis: Mapping[str, NisStats] = field(default_factory=dict)
    lost_at_s: float | None = None
    wind_error_mps: ErrorStats | None = None
    gnss_sky: GnssSkyStats | None = None
    camera_boresight: CameraBoresightStats | None = None
    camera_time_offset: CameraTimeOffsetStats | None = None
    camera_intrinsics: CameraIntrinsicsStats | None = None


@dataclass(frozen=True)
class TanMetrics(_Section):
    """Terrain-aided navigation (events/tan.parquet: one row per window of radar ranges).

    fix_rate = fixes / windows; accept_rate = fixes the filter accepted / fixes;
    horizontal_error_m: |fix - truth| north-east (m, with CEP) over the fixes as the navigator
    got them, at the window's end (they hold the velocity lag the navigator models,
    PositionFix.vel_lag_s); window_error_m: the fix less that lag's term (the lag matrix times
    the window's mean velocity error), against the truth (the point-mass filter's own error;
    metrics_tan.tan_window_errors_ne_m); vertical_error_m:
    |fix - truth| down (m); horizontal_nees: window_error's NEES against the fixes' horizontal
    claims (2 dof: mean 2 when they claim what they err by); rejected: reason -> windows
    without a fix ("flat", "ambiguous", "wide", "at grid edge", "few ranges")."""

    windows: int
    fixes: int
    accepted: int
    fix_rate: float | None = None
    accept_rate: float | None = None
    horizontal_error_m: ErrorStats | None = None
    window_error_m: ErrorStats | None = None
    vertical_error_m: ErrorStats | None = None
    horizontal_nees: ChiSquareStats | None = None
    rejected: Mapping[str, int] = field(default_factory=dict)


@dataclass(frozen=True)
class RelnavPair(_Section):
    """Relative-navigation error of one observer -> peer pair."""

    error_m: ErrorStats | None = None
    id_correct_rate: float | None = None
    count: int = 0


@dataclass(frozen=True)
class RelnavMetrics(_Section):
    """Relative navigation: |estimated - true relative position| (m), 3D.

    error_less_own_heading_m: the same with each estimate turned back about down by its
    observer's own heading error at that time (metrics_events.relnav_errors_less_own_heading_m):
    what the relative sensing and filtering err by, apart from the observer's heading, which a
    field bias common to the swarm (a magnetic anomaly) sets for every vehicle alike;
    id_correct_rate: fraction of estimates whose last bearing came from that peer, among those
    whose detection imaged one vehicle (the truth can decide);
    id_ambiguous_rate: fraction of the checked estimates whose last bearing's detection imaged
    several vehicles alike (merged on one line of sight: counted neither right nor wrong);
    track_id_correct_rate: fraction of the track-frames carrying a decoded ID (every camera
    frame, every identified track) whose ID names the vehicle the track's detection images,
    among those that image one vehicle: the IDs' correctness over track-time;
    track_id_ambiguous_rate: fraction of those track-frames whose detection imaged several
    vehicles alike;
    within_3sigma_rate: fraction with error <= 3 sigma_m (a calibration check);
    pairs: "<observer>_to_<peer>" -> RelnavPair;
    by_range: the same figures by the pair's TRUE range, "<lo>_<hi>m" (or "<lo>m_up") ->
    RelnavPair over metrics_events.RELNAV_RANGE_EDGES_M; empty bins left out. An observer's own
    attitude error moves an estimate across the line of sight in proportion to the range, so a
    swarm's overall figure depends on how far apart its vehicles fly: the paper's "0.75 m at
    100 m spacing" compares with the bin that holds the nearest neighbours.
    """

    error_m: ErrorStats | None = None
    error_less_own_heading_m: ErrorStats | None = None
    id_correct_rate: float | None = None
    id_ambiguous_rate: float | None = None
    track_id_correct_rate: float | None = None
    track_id_ambiguous_rate: float | None = None
    within_3sigma_rate: float | None = None
    count: int = 0
    pairs: Mapping[str, RelnavPair] = field(default_factory=dict)
    by_range: Mapping[str, RelnavPair] = field(default_factory=dict)


@dataclass(frozen=True)
class FormationMetrics(_Section):
    """Formation keeping: |true position - assigned slot| (m), 3D and horizontal; and its two
    parts (3D, m; their vectors sum to the error): holding_error_m, the follower's estimated
    position against the slot it places from its own estimates (what its control has not
    closed), and placement_error_m, that placed slot against the true one (what its estimates
    put wrong). See metrics_events.formation_error_parts."""

    error_m: ErrorStats | None = None
    horizontal_error_m: ErrorStats | None = None
    holding_error_m: ErrorStats | None = None
    placement_error_m: ErrorStats | None = None


@dataclass(frozen=True)
class VehicleMetrics(_Section):
    """Every per-vehicle section (the same figures as the top level, for one vehicle)."""

    control: ControlMetrics | None = None
    nav: NavMetrics | None = None
    ismn: IsmnMetrics | None = None
    tan: TanMetrics | None = None
    relnav: RelnavMetrics | None = None
    formation: FormationMetrics | None = None


@dataclass(frozen=True)
class MetricsResult(_Section):
    """The scores of one run. Top-level sections are over all vehicles.

    custom: metric name -> nested dict of floats from user metrics (written at the top level
    under their own name).
    """

    real_time_factor: float | None = None
    sim_time_s: float | None = None
    wall_time_s: float | None = None
    status: str | None = None
    control: ControlMetrics | None = None
    nav: NavMetrics | None = None
    ismn: IsmnMetrics | None = None
    tan: TanMetrics | None = None
    relnav: RelnavMetrics | None = None
    formation: FormationMetrics | None = None
    vehicles: Mapping[str, VehicleMetrics] = field(default_factory=dict)
    custom: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        out = section_dict(dataclasses.replace(self, custom={}))
        for name, values in self.custom.items():
            out[name] = _convert(values)
        return out

    def flatten(self) -> dict[str, Any]:
        """Dotted-key view of to_dict(): {"nav.horizontal_error_m.rms": 3.2, ...}."""
        return flatten(self.to_dict())

    flat = flatten


def flatten(nested: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """{"a": {"b": 1}} -> {"a.b": 1}. Lists and scalars are leaves."""
    out: dict[str, Any] = {}
    for k, v in nested.items():
        key = f"{prefix}{k}"
        if isinstance(v, Mapping):
            out.update(flatten(v, key + "."))
        else:
            out[key] = v
    return out


def unflatten(flat: Mapping[str, Any]) -> dict[str, Any]:
    """Inverse of flatten: {"a.b": 1} -> {"a": {"b": 1}}."""
    out: dict[str, Any] = {}
    for key, v in flat.items():
        node = out
        parts = key.split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = v
    return out


def json_safe(value: Any) -> Any:
    """Replace non-finite floats by None (strict JSON has no NaN) throughout a nested value."""
    if isinstance(value, Mapping):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if hasattr(value, "item") and callable(value.item):  # numpy scalar
        return json_safe(value.item())
    return value
