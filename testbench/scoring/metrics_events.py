"""Metrics from the event tables: scene matching (ISMN), relative navigation, formation.

Each returns None when the run did not record the table, so its keys are absent from
metrics.json (a threshold on them then fails as "missing", never silently passes).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from testbench.scoring.metrics_nav import MIN_AGL_FOR_PCT_M, horizontal_error_m, horizontal_sigma_max_m
from testbench.scoring.phases import event_turning
from testbench.scoring.record_io import RunRecord, column, has_columns
from testbench.scoring.result import (
    FormationMetrics,
    IsmnAcquisition,
    IsmnClouds,
    IsmnMapError,
    IsmnMetrics,
    IsmnPhase,
    RelnavMetrics,
    RelnavPair,
)
from testbench.scoring.stats import chi_square_stats, error_stats, rate


def fix_errors_ne_m(table: pd.DataFrame) -> np.ndarray:
    """(n, 2) fix minus truth, north and east (m), of each row of a fix table (ismn, tan: the
    columns of navigation.fix_columns and the engine's truth); NaN on rows without a fix."""
    fix = column(table, "fix", dtype=bool).astype(bool)
    e = np.stack([column(table, "fix_north_m") - column(table, "truth_north_m"),
                  column(table, "fix_east_m") - column(table, "truth_east_m")], axis=1)
    return np.where(fix[:, None], e, np.nan)


def ismn_fix_errors(ismn: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """(horizontal error (m), error as % of AGL) of each row's fix vs truth, shapes (n,): the
    truth where the frame was taken from (truth_exposure_*; a camera whose clock is off took it
    before or after its stamp), or, in records without those columns, the truth at its stamp.

    NaN on rows without a fix.
    """
    ismn = _at_exposure(ismn)
    eh = np.hypot(*fix_errors_ne_m(ismn).T)
    agl = column(ismn, "truth_height_agl_m")
    with np.errstate(divide="ignore", invalid="ignore"):
        pct = np.where(agl > MIN_AGL_FOR_PCT_M, 100.0 * eh / agl, np.nan)
    return eh, pct


def _at_exposure(ismn: pd.DataFrame) -> pd.DataFrame:
    """The table with its truth position where each frame was taken from (truth_exposure_*),
    where the record has those columns."""
    if "truth_exposure_north_m" not in ismn.columns:
        return ismn
    return ismn.assign(truth_north_m=column(ismn, "truth_exposure_north_m"),
                       truth_east_m=column(ismn, "truth_exposure_east_m"))


def _ismn_map_error(ismn: pd.DataFrame, fix: np.ndarray, tel: pd.DataFrame) -> IsmnMapError | None:
    """IsmnMapError from the rows' truth_map_error_{north,east}_m (None where the record has
    no such columns: the carried map was placed exactly), the navigator's estimate from the
    telemetry row (tel) of the same vehicle and time."""
    if not has_columns(ismn, "truth_map_error_north_m", "truth_map_error_east_m"):
        return None
    d = np.stack([column(ismn, "truth_map_error_north_m"), column(ismn, "truth_map_error_east_m")], axis=1)
    e = fix_errors_ne_m(_at_exposure(ismn))
    sel = fix & np.all(np.isfinite(d), axis=1) & np.all(np.isfinite(e), axis=1)
    if not np.any(sel):
        return IsmnMapError(fixes=0)
    est_err, nees = _map_error_estimate(ismn[sel], d[sel], tel)
    return IsmnMapError(fixes=int(sel.sum()), map_error_m=error_stats(np.hypot(*d[sel].T)),
                        matching_error_m=error_stats(np.hypot(*(e - d)[sel].T)),
                        estimate_error_m=est_err, estimate_nees=nees)


def _map_error_estimate(rows: pd.DataFrame, truth_ne_m: np.ndarray, tel: pd.DataFrame):
    """(ErrorStats of |estimate - truth|, its NEES's ChiSquareStats) of the navigator's map
    error estimate (telemetry nav_map_error_*) at the times of `rows` against truth_ne_m (n, 2);
    (None, None) when the telemetry holds no estimate."""
    if not has_columns(tel, "nav_map_error_n_m"):
        return None, None
    cols = ["nav_map_error_n_m", "nav_map_error_e_m", "nav_sigma_map_error_n_m", "nav_sigma_map_error_e_m"]
    keyed = tel.assign(_t=np.round(column(tel, "t_s"), 6))[["vehicle_id", "_t", *cols]]
    at = rows[["vehicle_id"]].assign(_t=np.round(column(rows, "t_s"), 6)).merge(keyed, on=["vehicle_id", "_t"], how="left")
    err = at[cols[:2]].to_numpy(float) - truth_ne_m
    sig = at[cols[2:]].to_numpy(float)
    ok = np.all(np.isfinite(err) & np.isfinite(sig) & (sig > 0), axis=1)
    if not ok.any():
        return None, None
    return error_stats(np.hypot(*err[ok].T)), chi_square_stats(np.sum((err[ok] / sig[ok]) ** 2, axis=1), 2)


def _ismn_phase(eh: np.ndarray, pct: np.ndarray, mask: np.ndarray) -> IsmnPhase | None:
    n = int(np.sum(mask & np.isfinite(eh)))
    if n == 0:
        return None
    return IsmnPhase(
        horizontal_error_m=error_stats(eh[mask], cep=True),
        horizontal_error_pct_agl=error_stats(pct[mask]),
        count=n,
    )


def compute_ismn(record: RunRecord) -> IsmnMetrics | None:
    """IsmnMetrics from events/ismn.parquet; phase per fix from truth bank and turn rate."""
    ismn = record.event("ismn")
    if ismn is None:
        return None
    attempted = column(ismn, "attempted", dtype=bool).astype(bool) if "attempted" in ismn.columns else np.ones(len(ismn), bool)
    fix = column(ismn, "fix", dtype=bool).astype(bool) & attempted
    accepted = column(ismn, "accepted", dtype=bool).astype(bool) & fix
    eh, pct = ismn_fix_errors(ismn)
    turning = event_turning(record, ismn)
    latency = np.where(attempted, column(ismn, "latency_ms"), np.nan)
    n_att, n_fix, n_acc = int(attempted.sum()), int(fix.sum()), int(accepted.sum())
    # A fix still in processing when the run ended never reached the filter (delivered_t_s
    # NaN): not a refusal. Records from before the column: every fix was delivered at once.
    delivered = column(ismn, "delivered_t_s") if "delivered_t_s" in ismn.columns else np.where(fix, column(ismn, "t_s"), np.nan)
    reached = fix & np.isfinite(delivered)
    delay = delivered[reached] - column(ismn, "t_s")[reached]
    false = fix & (eh > FALSE_FIX_M)
    return IsmnMetrics(
        attempts=n_att,
        fixes=n_fix,
        accepted=n_acc,
        fix_rate=rate(n_fix, n_att),
        accept_rate=rate(n_acc, int(reached.sum())),
        delivery_delay_s=float(delay.mean()) if delay.size else None,
        busy_frames=int(ismn["reason"].astype(str).str.startswith("busy").sum()) if "reason" in ismn.columns else 0,
        latency_ms=error_stats(latency),
        all=_ismn_phase(eh, pct, fix),
        smooth=_ismn_phase(eh, pct, fix & ~turning),
        turning=_ismn_phase(eh, pct, fix & turning),
        longest_gap_s=_longest_gap_per_vehicle(ismn, attempted, accepted),
        false_fixes=int(false.sum()),
        false_fixes_accepted=int((false & accepted).sum()),
        acquisition=_ismn_acquisition(ismn, accepted, record.telemetry),
        clouds=_ismn_clouds(ismn, attempted, fix, accepted, eh),
        map_error=_ismn_map_error(ismn, fix, record.telemetry),
    )


FALSE_FIX_M = 20.0
"""A fix farther than this from truth is a wrong one (a match at the wrong place, or a pose solved
wrong), not a noisy one (the matchers' own errors are 0.3-3 m from 150 m to 800 m above ground)."""
ACQUISITION_AFTER_S = 10.0


def _ismn_acquisition(ismn: pd.DataFrame, accepted: np.ndarray, tel: pd.DataFrame) -> IsmnAcquisition | None:
    """IsmnAcquisition: each vehicle's first accepted fix against its telemetry (the
    estimate's horizontal error and sigma at the last record before the fix, its error
    ACQUISITION_AFTER_S after); the latest / largest over the vehicles. None without an
    accepted fix."""
    if not accepted.any():
        return None
    ids, t = ismn["vehicle_id"].astype(str).to_numpy(), column(ismn, "t_s")
    reason = ismn["reason"].astype(str) if "reason" in ismn.columns else pd.Series([""] * len(ismn))
    first, before, sigma, after, settled = [], [], [], [], []
    for v in np.unique(ids[accepted]):
        t0 = float(t[accepted & (ids == v)].min())
        rows = tel[tel["vehicle_id"].astype(str) == v]
        tt, err = column(rows, "t_s"), horizontal_error_m(rows)
        first.append(t0)
        i = np.flatnonzero(tt < t0 - 1e-9)
        if i.size:
            before.append(float(err[i[-1]]))
            if has_columns(rows, "nav_sigma_north_m", "nav_sigma_east_m", "nav_cov_ne_m2"):
                sigma.append(float(horizontal_sigma_max_m(rows.iloc[[i[-1]]])[0]))
        j = np.flatnonzero(tt >= t0 + ACQUISITION_AFTER_S - 1e-9)
        if j.size:
            after.append(float(err[j[0]]))
            settled.append(err[j])
    return IsmnAcquisition(first_fix_s=max(first), error_before_m=max(before) if before else None,
                           sigma_before_m=max(sigma) if sigma else None, error_after_m=max(after) if after else None,
                           settled_error_m=error_stats(np.concatenate(settled), cep=True) if settled else None,
                           held=int(reason.str.startswith("held for confirmation").sum()))


CLOUDED_FRACTION = 0.5
OVERCAST_FRACTION = 0.95
SHADOWED_FRACTION = 0.2
SUNLIT_FRACTION = 0.05


def longest_gap_s(t_s: np.ndarray, attempted: np.ndarray, accepted: np.ndarray) -> float | None:
    """The longest time (s) between two accepted fixes, or from the last accepted fix to the
    last attempt, from the first accepted fix on; None without an accepted fix. t_s,
    attempted, accepted: (n,) per row, in time order."""
    t_acc = t_s[accepted]
    if t_acc.size == 0:
        return None
    ends = np.append(t_acc, t_s[attempted].max())
    return float(np.max(np.diff(ends))) if ends.size > 1 else 0.0


def _longest_gap_per_vehicle(ismn: pd.DataFrame, attempted: np.ndarray, accepted: np.ndarray) -> float | None:
    """longest_gap_s of each vehicle's own rows (their times interleave in one table), the
    longest of them; None where no vehicle had an accepted fix."""
    t = column(ismn, "t_s")
    ids = ismn["vehicle_id"].astype(str).to_numpy() if "vehicle_id" in ismn.columns else np.zeros(len(ismn), str)
    gaps = [longest_gap_s(t[ids == v], attempted[ids == v], accepted[ids == v]) for v in np.unique(ids)]
    gaps = [g for g in gaps if g is not None]
    return max(gaps) if gaps else None


def _ismn_clouds(ismn: pd.DataFrame, attempted: np.ndarray, fix: np.ndarray, accepted: np.ndarray,
                 eh: np.ndarray) -> IsmnClouds | None:
    """IsmnClouds, or None where no frame met a cloud (or the record predates clouds)."""
    if "truth_cloud_fraction" not in ismn.columns:
        return None
    share = column(ismn, "truth_cloud_fraction")
    if not np.any(share[attempted] > 0.0):
        return None
    clouded = attempted & (share >= CLOUDED_FRACTION)
    overcast = attempted & (share >= OVERCAST_FRACTION)
    shadows = {}
    if "truth_shadow_fraction" in ismn.columns and np.any(column(ismn, "truth_shadow_fraction")[attempted] > 0.0):
        shade = column(ismn, "truth_shadow_fraction")
        for name, frames in (("shadowed", shade >= SHADOWED_FRACTION), ("sunlit", shade < SUNLIT_FRACTION)):
            sel = fix & frames
            shadows[f"{name}_fixes"] = int(sel.sum())
            shadows[f"{name}_horizontal_error_m"] = error_stats(eh[sel]) if np.any(sel) else None
    return IsmnClouds(
        attempts=int(clouded.sum()), fixes=int((fix & clouded).sum()), accepted=int((accepted & clouded).sum()),
        overcast_attempts=int(overcast.sum()), overcast_accepted=int((accepted & overcast).sum()),
        horizontal_error_m=error_stats(eh[fix & clouded]) if np.any(fix & clouded) else None,
        **shadows,
    )


def relnav_errors_m(rel: pd.DataFrame) -> np.ndarray:
    """3D |estimated - true relative position| (m) per row, shape (n,)."""
    return np.sqrt(
        sum((column(rel, f"est_{a}_m") - column(rel, f"truth_{a}_m")) ** 2 for a in ("north", "east", "down"))
    )


def own_heading_error_rad(record: RunRecord, rel: pd.DataFrame) -> np.ndarray:
    """The observer's own heading error (estimated - true yaw, rad) at each relnav row's time,
    interpolated in that vehicle's telemetry; shape (n,), nan where the telemetry has no yaw to
    compare. Only its cosine and sine are used, so it need not be wrapped."""
    out = np.full(len(rel), np.nan)
    observer = rel["vehicle_id"].astype(str).to_numpy()
    t_s = column(rel, "t_s")
    for vid in np.unique(observer):
        tel = record.vehicle_telemetry(vid)
        if not has_columns(tel, "t_s", "nav_yaw_rad", "truth_yaw_rad"):
            continue
        # Unwrapped, so that an error passing +-pi (a lost heading) interpolates across it.
        err = np.unwrap(np.angle(np.exp(1j * (column(tel, "nav_yaw_rad") - column(tel, "truth_yaw_rad")))))
        sel = observer == vid
        out[sel] = np.interp(t_s[sel], column(tel, "t_s"), err)
    return out


def relnav_errors_less_own_heading_m(rel: pd.DataFrame, heading_error_rad: np.ndarray) -> np.ndarray:
    """|Rz(-d psi) est - truth| (m) per row, shape (n,): the estimate turned back about down by
    the observer's own heading error d psi (n,). An observer rotates its bearings into NED with
    its own estimated attitude, so its heading error turns every estimate about it by d psi;
    this is the error of the relative sensing and filtering alone."""
    c, s = np.cos(heading_error_rad), np.sin(heading_error_rad)
    n, e = column(rel, "est_north_m"), column(rel, "est_east_m")
    return np.sqrt((c * n + s * e - column(rel, "truth_north_m")) ** 2 + (-s * n + c * e - column(rel, "truth_east_m")) ** 2
                   + (column(rel, "est_down_m") - column(rel, "truth_down_m")) ** 2)


RELNAV_RANGE_EDGES_M = (60.0, 120.0, 180.0, 240.0)
"""Edges (m) of relnav.by_range: a swarm's rings of neighbours fall in separate bins at the
usual spacings (the paper's arrowhead: 100 m neighbours, the 173 m second ring, 200 m along a
row's line; a column 60 m apart)."""


def range_bin_keys(edges_m=RELNAV_RANGE_EDGES_M) -> list[str]:
    """Keys of the bins [0, e0), [e0, e1), ..., [e_last, inf): "0_60m", ..., "240m_up"."""
    lo = (0.0,) + tuple(edges_m)
    return [f"{a:g}_{b:g}m" for a, b in zip(lo[:-1], edges_m)] + [f"{lo[-1]:g}m_up"]


def relnav_ranges_m(rel: pd.DataFrame) -> np.ndarray:
    """True range |truth relative position| (m) per row, shape (n,)."""
    return np.sqrt(sum(column(rel, f"truth_{a}_m") ** 2 for a in ("north", "east", "down")))


def pair_key(observer_id: str, peer_id: str) -> str:
    """Key of one observer -> peer pair in relnav.pairs (no dots: keys are dotted paths)."""
    return f"{observer_id}_to_{peer_id}".replace(".", "_")


def _id_rate(rel: pd.DataFrame) -> float | None:
    """Share of the rows whose ID is known right (id_correct 1) among those scored (1 or 0);
    nan rows (no truth to check the last bearing against, or a detection of several vehicles
    alike) count neither way. None: none scored."""
    if "id_correct" not in rel.columns:
        return None
    known = rel["id_correct"].to_numpy(float)
    known = known[np.isfinite(known)]
    return float(np.mean(known == 1.0)) if len(known) else None


def _ambiguous_rate(rel: pd.DataFrame) -> float | None:
    """Share of the rows checked against truth (id_ambiguous 0 or 1) whose last bearing's
    detection imaged several vehicles alike (diagnostics.id_truth): the rows id_correct_rate
    leaves out as undecidable. None: no such column or no row checked."""
    if "id_ambiguous" not in rel.columns:
        return None
    amb = rel["id_ambiguous"].to_numpy(float)
    amb = amb[np.isfinite(amb)]
    return float(np.mean(amb == 1.0)) if len(amb) else None


def _relnav_group(rel: pd.DataFrame, err: np.ndarray, sel: np.ndarray) -> RelnavPair:
    """The figures of the rows sel (bool, (n,)) of table relnav, err its errors (n,)."""
    return RelnavPair(error_m=error_stats(err[sel]), id_correct_rate=_id_rate(rel[sel]), count=int(sel.sum()))


def compute_relnav(record: RunRecord) -> RelnavMetrics | None:
    """RelnavMetrics from events/relnav.parquet, overall and per observer -> peer pair, and the
    decoded track IDs from events/relnav_id.parquet."""
    rel = record.event("relnav")
    if rel is None:
        return None
    ids = record.event("relnav_id")  # one row per identified track per frame
    err = relnav_errors_m(rel)
    err_less_heading = relnav_errors_less_own_heading_m(rel, own_heading_error_rad(record, rel))
    sigma = column(rel, "sigma_m")
    ok_sig = np.isfinite(sigma) & np.isfinite(err)
    within = float(np.mean(err[ok_sig] <= 3.0 * sigma[ok_sig])) if ok_sig.any() else None
    pairs = {}
    obs = rel["vehicle_id"].astype(str).to_numpy()
    peer = rel["peer_id"].astype(str).to_numpy()
    for a, b in sorted(set(zip(obs, peer))):
        pairs[pair_key(a, b)] = _relnav_group(rel, err, (obs == a) & (peer == b))
    rng = relnav_ranges_m(rel)
    bin_of = np.where(np.isfinite(rng), np.digitize(rng, RELNAV_RANGE_EDGES_M), -1)  # -1: no truth, no bin
    by_range = {}
    for k, key in enumerate(range_bin_keys()):
        sel = bin_of == k
        if sel.any():
            by_range[key] = _relnav_group(rel, err, sel)
    return RelnavMetrics(
        error_m=error_stats(err),
        error_less_own_heading_m=error_stats(err_less_heading),
        id_correct_rate=_id_rate(rel),
        id_ambiguous_rate=_ambiguous_rate(rel),
        track_id_correct_rate=None if ids is None else _id_rate(ids),
        track_id_ambiguous_rate=None if ids is None else _ambiguous_rate(ids),
        within_3sigma_rate=within,
        count=int(len(rel)),
        pairs=pairs,
        by_range=by_range,
    )


def compute_formation(record: RunRecord) -> FormationMetrics | None:
    """FormationMetrics from events/formation.parquet (slot errors from TRUE positions), and
    that error's two parts from the followers' own telemetry (formation_error_parts)."""
    frm = record.event("formation")
    if frm is None:
        return None
    error_ned_m = np.stack([column(frm, f"slot_error_{a}_m") for a in ("north", "east", "down")], axis=1)
    holding, placement = formation_error_parts(frm, record.telemetry, error_ned_m)
    return FormationMetrics(
        error_m=error_stats(np.sqrt((error_ned_m * error_ned_m).sum(axis=1))),
        horizontal_error_m=error_stats(np.hypot(error_ned_m[:, 0], error_ned_m[:, 1])),
        holding_error_m=None if holding is None else error_stats(np.linalg.norm(holding, axis=1)),
        placement_error_m=None if placement is None else error_stats(np.linalg.norm(placement, axis=1)),
    )


def formation_error_parts(frm: pd.DataFrame, telemetry: pd.DataFrame,
                          error_ned_m: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Each formation row's true slot error error_ned_m (n, 3) NED m split in two, (n, 3)
    each, holding + placement = the true error:

    - holding: the follower's estimated position less the slot it places from its own
      estimates (its GuidanceStatus target, telemetry gd_target_*): what its controller has
      not closed;
    - placement: that placed slot against its true slot (the true error less the holding):
      what its estimates (its neighbours, their layout's course, its own velocity) put wrong.

    Rows are matched to the follower's telemetry row of the same record tick (times rounded
    to the microsecond: the two tables sum their times differently). (None, None) when the
    telemetry has no guidance target (a record from before it, or no follower controller);
    rows without a match are NaN."""
    cols = ["nav_north_m", "nav_east_m", "nav_down_m", "gd_target_n_m", "gd_target_e_m", "gd_target_d_m"]
    if not all(c in telemetry.columns for c in cols):
        return None, None
    key = ["vehicle_id", "t_us"]
    tel = telemetry[["vehicle_id", *cols]].assign(t_us=np.round(telemetry["t_s"].to_numpy(float) * 1e6))
    rows = frm[["vehicle_id"]].assign(t_us=np.round(frm["t_s"].to_numpy(float) * 1e6))
    joined = rows.merge(tel.drop_duplicates(key, keep="last"), on=key, how="left")
    holding = joined[cols[:3]].to_numpy(float) - joined[cols[3:]].to_numpy(float)
    return holding, error_ned_m - holding
