"""Typed results of scoring scene matching (the `ismn` section of metrics.json)."""

from __future__ import annotations

from dataclasses import dataclass

from testbench.scoring.sections import Section
from testbench.scoring.stats import ChiSquareStats, ErrorStats


@dataclass(frozen=True)
class IsmnPhase(Section):
    """Scene-matching fix error (fix - truth) over the fixes of one phase."""

    horizontal_error_m: ErrorStats | None = None
    horizontal_error_pct_agl: ErrorStats | None = None
    count: int = 0


@dataclass(frozen=True)
class IsmnClouds(Section):
    """Scene matching under the world's clouds (the frames' truth_cloud_fraction).

    attempts / fixes / accepted: over the frames that clouds covered half of or more;
    horizontal_error_m: error of the fixes made from those frames; overcast_attempts /
    overcast_accepted: over the frames clouds covered 95 % of or more, where nothing of the
    ground is left to match (a fix the filter takes from one is a false fix);
    shadowed_fixes / shadowed_horizontal_error_m: the fixes from frames a fifth or more of
    whose ground in view shows in a cloud's shadow (truth_shadow_fraction), and their error;
    sunlit_fixes / sunlit_horizontal_error_m: those from frames under 5 % in shadow (only where
    the clouds cast shadows)."""

    attempts: int
    fixes: int
    accepted: int
    overcast_attempts: int
    overcast_accepted: int
    horizontal_error_m: ErrorStats | None = None
    shadowed_fixes: int | None = None
    shadowed_horizontal_error_m: ErrorStats | None = None
    sunlit_fixes: int | None = None
    sunlit_horizontal_error_m: ErrorStats | None = None


@dataclass(frozen=True)
class IsmnMapError(Section):
    """Scene matching from a map off its georeference (world.reference_map_error; the rows'
    truth_map_error_{north,east}_m: the map's displacement over each fix's footprint).

    map_error_m: |displacement| over the fixes, what the map alone puts into them;
    matching_error_m: |fix error - displacement|, what the matching itself erred by (the
    fix's error as it would be from a map placed exactly, to first order); where the navigator
    estimates the map's error (navigation.params.map_error): estimate_error_m, |estimate -
    displacement| at the fixes' times, and estimate_nees, its NEES (2 dof, diagonal sigmas)."""

    fixes: int
    map_error_m: ErrorStats | None = None
    matching_error_m: ErrorStats | None = None
    estimate_error_m: ErrorStats | None = None
    estimate_nees: ChiSquareStats | None = None


@dataclass(frozen=True)
class IsmnAcquisition(Section):
    """How scene matching took the navigation over, from whatever the estimate was before.

    first_fix_s: the time of the first fix the filter accepted (with several vehicles, the
    latest vehicle's); error_before_m / sigma_before_m: the estimate's horizontal error and
    claimed sigma (the larger axis of its north-east ellipse) at the last record before that
    fix; error_after_m: its horizontal error ACQUISITION_AFTER_S (10 s) after it (the largest
    over the vehicles, each figure); settled_error_m: the estimate's horizontal error from then
    to the run's end (all vehicles' rows); held: fixes held back for confirmation and never delivered
    (IsmnAid acquisition)."""

    first_fix_s: float
    error_before_m: float | None = None
    sigma_before_m: float | None = None
    error_after_m: float | None = None
    settled_error_m: ErrorStats | None = None
    held: int = 0


@dataclass(frozen=True)
class IsmnMetrics(Section):
    """Inertial-aided scene matching.

    fix_rate = fixes / attempts; accept_rate = fixes accepted by the filter / fixes that
    reached it (one still in processing at the run's end did not); latency_ms: per attempt
    (the pipeline's own compute time on this machine); delivery_delay_s: the mean time from a
    frame's exposure to its fix reaching the filter (the aid's modelled onboard processing time,
    IsmnAid latency_s; 0: at once); busy_frames: frames the processor skipped because it was
    still on an earlier one (not attempts); all / smooth / turning: error of the produced fixes;
    longest_gap_s: the longest time between two accepted fixes, or from the last one to the
    last attempt (s; from the first accepted fix on); false_fixes / false_fixes_accepted: the
    fixes farther than FALSE_FIX_M (20 m) from truth, matches at the wrong place rather than
    noisy ones, and how many of them the filter took; acquisition: the first accepted fix and
    the estimate before and after it (only where one was accepted); clouds: the frames under cloud (only
    where the world has clouds); map_error: the map's share of the fixes' error (only where
    the carried map is off its georeference).
    """

    attempts: int
    fixes: int
    accepted: int
    fix_rate: float | None = None
    accept_rate: float | None = None
    latency_ms: ErrorStats | None = None
    delivery_delay_s: float | None = None
    busy_frames: int = 0
    all: IsmnPhase | None = None
    smooth: IsmnPhase | None = None
    turning: IsmnPhase | None = None
    longest_gap_s: float | None = None
    false_fixes: int = 0
    false_fixes_accepted: int = 0
    acquisition: IsmnAcquisition | None = None
    clouds: IsmnClouds | None = None
    map_error: IsmnMapError | None = None
