"""Assemble a Report (tables + figures) from a run directory; sections without data are omitted."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from testbench.reporting import figures_camera_states as fcs
from testbench.reporting import figures_events as fe
from testbench.reporting import figures_gnss as fg
from testbench.reporting import figures_map_error as fme
from testbench.reporting import figures_nav as fn
from testbench.reporting import figures_tan as ft
from testbench.reporting import figures_wind as fw
from testbench.reporting.model import FigureItem, Report, Section, Table
from testbench.scoring import MetricsResult, ThresholdResult, check_thresholds, load_run, score_record
from testbench.scoring.record_io import RunRecord
from testbench.scoring.result import flatten

log = logging.getLogger(__name__)

# The figures a reader looks for first (shown in the summary table when present).
KEY_METRICS = (
    "nav.position_error_m.rms", "nav.horizontal_error_m.mean", "nav.horizontal_error_m.rms",
    "nav.horizontal_error_m.p95", "nav.horizontal_error_m.max", "nav.horizontal_error_m.cep50",
    "nav.horizontal_error_m.cep95", "nav.horizontal_error_pct_agl.mean",
    "nav.denied.horizontal_error_m.mean", "nav.denied.horizontal_error_m.max", "nav.denied.duration_s",
    "nav.spoofed.horizontal_error_m.mean", "nav.spoofed.horizontal_error_m.max", "nav.spoofed.gnss_accept_rate",
    "nav.spoofed.gnss_captured_s",
    "nav.nees.position.mean", "nav.nees.position.frac_in_95", "nav.wind_error_mps.mean", "nav.wind_error_mps.p95",
    "nav.camera_boresight.final_error_deg", "nav.camera_boresight.final_sigma_deg",
    "nav.camera_time_offset.final_error_ms", "nav.camera_time_offset.final_sigma_ms",
    "nav.camera_intrinsics.final_principal_point_error_px", "nav.camera_intrinsics.final_principal_point_sigma_px",
    "nav.camera_intrinsics.final_focal_error_ppm", "nav.camera_intrinsics.final_focal_sigma_ppm",
    "nav.gnss_sky.satellites_visible_mean", "nav.gnss_sky.satellites_visible_min", "nav.gnss_sky.fix_share",
    "nav.gnss_sky.hdop.p95", "nav.gnss_sky.hdop_open_sky_median",
    "control.altitude_error_m.rms", "control.cross_track_error_m.rms", "control.airspeed_error_mps.rms",
    "control.bank_max_deg",
    "ismn.fix_rate", "ismn.accept_rate", "ismn.latency_ms.mean", "ismn.latency_ms.p95", "ismn.delivery_delay_s",
    "ismn.all.horizontal_error_m.mean", "ismn.smooth.horizontal_error_m.mean", "ismn.turning.horizontal_error_m.mean",
    "ismn.all.horizontal_error_pct_agl.mean", "ismn.false_fixes", "ismn.false_fixes_accepted",
    "ismn.acquisition.first_fix_s", "ismn.acquisition.error_before_m", "ismn.acquisition.error_after_m",
    "ismn.acquisition.held",
    "tan.fix_rate", "tan.window_error_m.mean", "tan.horizontal_error_m.mean", "tan.horizontal_nees.mean_per_dof",
    "relnav.error_m.mean", "relnav.error_m.max", "relnav.error_less_own_heading_m.mean", "relnav.id_correct_rate", "relnav.id_ambiguous_rate", "relnav.track_id_correct_rate", "formation.error_m.rms", "formation.error_m.max",
    "formation.holding_error_m.rms", "formation.placement_error_m.rms",
    "real_time_factor", "sim_time_s", "wall_time_s",
)


def fmt(value: Any) -> str:
    """Compact text of a metric value."""
    if value is None:
        return "—"
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if value != value:
            return "NaN"
        return f"{value:.4g}" if abs(value) < 1e5 else f"{value:.4e}"
    return str(value)


def _config_table(record: RunRecord) -> Table:
    info = record.run_info
    rows = [
        ["scenario", fmt(info.get("scenario_name"))],
        ["scenario file", fmt(info.get("scenario_file"))],
        ["seed", fmt(info.get("seed"))],
        ["status", fmt(info.get("status")) + (f" ({info['abort_reason']})" if info.get("abort_reason") else "")],
        ["simulated time (s)", fmt(info.get("sim_time_s"))],
        ["wall time (s)", fmt(info.get("wall_time_s"))],
        ["real-time factor", fmt(info.get("real_time_factor"))],
    ]
    for v in info.get("vehicles", []):
        rows.append([f"vehicle {v.get('id')}", f"{v.get('aircraft', '?')} ({v.get('kind', '?')})"])
    for vid, windows in (info.get("gnss_denied_windows") or {}).items():
        rows.append([f"GNSS denied {vid}", ", ".join(f"{a:g}–{b:g} s" for a, b in windows) or "never"])
    for vid, windows in (info.get("gnss_spoofed_windows") or {}).items():
        if windows:  # listed only where a spoofer acts
            rows.append([f"GNSS spoofed {vid}", ", ".join(f"{a:g}–{b:g} s" for a, b in windows)])
    credit = (info.get("world") or {}).get("imagery_credit")
    if credit:
        rows.append(["imagery credit", str(credit)])
    wind = (info.get("world") or {}).get("wind")
    if isinstance(wind, dict):
        turb = wind.get("turbulence")
        rows.append(["wind", f"{fmt(wind.get('speed_mps'))} m/s from {fmt(wind.get('from_deg'))}°" + (
            f", {turb.get('severity')} turbulence ({turb.get('model')})" if isinstance(turb, dict) else ", no turbulence")])
    anomaly = (info.get("world") or {}).get("magnetic_anomaly")
    if isinstance(anomaly, dict):
        field = "the run's own draw" if anomaly.get("seed") is None else f"field seed {anomaly['seed']}"
        rows.append(["magnetic anomaly", f"{fmt(anomaly.get('rms_nT'))} nT RMS at the origin's altitude, sources "
                                         f"{fmt(anomaly.get('source_depth_m'))} m deep ({field})"])
    for i, ob in enumerate((info.get("world") or {}).get("obstacles") or [], start=1):
        lo, hi = ob.get("min_ned_m"), ob.get("max_ned_m")
        if lo and hi:
            rows.append([f"obstacle {ob.get('name') or i}",
                         f"box north {fmt(lo[0])}–{fmt(hi[0])} m, east {fmt(lo[1])}–{fmt(hi[1])} m, "
                         f"{fmt(0.0 - hi[2])}–{fmt(0.0 - lo[2])} m above the origin"])  # 0.0 - x: no "-0"
    ph = record.phases
    rows.append(["turning phase", f"|bank| > {ph['turn_bank_deg']:g}° or |turn rate| > {ph['turn_rate_deg_s']:g}°/s"])
    if "same_raster" in info and record.event("ismn") is not None:
        rows.append(["camera raster = matcher raster", fmt(info.get("same_raster"))])
    if "same_dem" in info and record.event("tan") is not None:
        rows.append(["world DEM = onboard DEM", fmt(info.get("same_dem"))])
    origin = info.get("origin")
    if isinstance(origin, dict):
        rows.append(["origin", ", ".join(f"{k} {fmt(v)}" for k, v in origin.items())])
    return Table("Configuration", ["item", "value"], [r for r in rows if r[1] != "—"])


def _threshold_table(thresholds: dict, thr: ThresholdResult, flat: dict) -> Table | None:
    if not thresholds:
        return None
    failed = {}
    for f in thr.failed:
        failed.setdefault(f["key"], []).append(f)
    rows = []
    for key, bounds in thresholds.items():
        bound_txt = " and ".join(f"{'≥' if k == 'min' else '≤'} {fmt(float(v))}" for k, v in bounds.items())
        verdict = "FAIL" if key in failed else "PASS"
        value = fmt(flat.get(key)) if key in flat else "missing"
        rows.append([key, bound_txt, value, verdict])
    rows.sort(key=lambda r: r[3] != "FAIL")
    return Table("Thresholds (regression gates)", ["metric", "bound", "value", "result"], rows, status_col=3)


def _range_label(key: str) -> str:
    """'60_120m' -> '60-120 m', '240m_up' -> 'from 240 m' (relnav.by_range keys)."""
    if key.endswith("m_up"):
        return f"from {key[:-4]} m"
    return key[:-1].replace("_", "-") + " m"


def _relnav_rows(groups: dict, label) -> list[list[str]]:
    """Table rows of relnav groups (pairs or range bins: key -> RelnavPair), label(key) first."""
    return [[label(k)] + [fmt(getattr(p.error_m, s) if p.error_m else None) for s in ("mean", "rms", "p95", "max")]
            + [fmt(p.id_correct_rate), fmt(p.count)] for k, p in groups.items()]


def _metric_rows(flat: dict, keys) -> list[list[str]]:
    return [[k, fmt(flat[k])] for k in keys if k in flat]


def _vehicle_table(result: MetricsResult) -> Table | None:
    if len(result.vehicles) < 2:
        return None
    cols = [("nav horiz. RMS (m)", "nav.horizontal_error_m.rms"), ("nav horiz. max (m)", "nav.horizontal_error_m.max"),
            ("denied horiz. mean (m)", "nav.denied.horizontal_error_m.mean"), ("ISMN fix rate", "ismn.fix_rate"),
            ("ISMN smooth mean (m)", "ismn.smooth.horizontal_error_m.mean"), ("relnav max (m)", "relnav.error_m.max"),
            ("formation RMS (m)", "formation.error_m.rms"), ("cross-track RMS (m)", "control.cross_track_error_m.rms")]
    rows = []
    for vid, vm in result.vehicles.items():
        f = flatten(vm.to_dict())
        rows.append([vid] + [fmt(f.get(k)) for _, k in cols])
    keep = [i for i in range(len(cols)) if any(r[i + 1] != "—" for r in rows)]
    return Table("Per vehicle", ["vehicle"] + [cols[i][0] for i in keep], [[r[0]] + [r[i + 1] for i in keep] for r in rows])


def _nis_table(result: MetricsResult) -> Table | None:
    if result.nav is None or not (result.nav.nis or result.nav.nees):
        return None
    rows = []
    for name, s in result.nav.nees.items():
        rows.append([f"NEES {name}", fmt(s.n), "—", fmt(s.mean_per_dof), fmt(s.frac_in_95), fmt(s.frac_above_95)])
    for kind, s in result.nav.nis.items():
        c = s.chi2
        rows.append([f"NIS {kind}", fmt(s.count), fmt(s.accept_rate), fmt(c.mean_per_dof if c else None),
                     fmt(c.frac_in_95 if c else None), fmt(c.frac_above_95 if c else None)])
    return Table("Filter consistency", ["quantity", "samples", "accept rate", "mean / dof", "in 95 % band", "above band"], rows)


def _figs(*items) -> list[FigureItem]:
    out = []
    for it in items:
        if it is None:
            continue
        out.extend(it if isinstance(it, list) else [it])
    return out


def build_report(run_dir: str | Path, result: MetricsResult | None = None) -> Report:
    """Load and score the run (unless `result` is given) and assemble every section with data."""
    record = load_run(run_dir)
    if result is None:
        result = score_record(record)
    flat = result.flatten()
    thresholds = record.thresholds
    thr = check_thresholds(flat, thresholds)
    info = record.run_info
    verdict = "ABORTED" if info.get("status", "completed") != "completed" else ("FAILED" if thr.failed else "PASSED")
    warnings = []
    # Only where something matched scenes: a swarm's cameras render the imagery too, but no
    # vehicle carries a map, and the warning would speak of figures the report does not have.
    scene_matching = record.event("ismn") is not None
    if info.get("same_raster") and scene_matching:
        warnings.append("The camera was rendered from the same raster the matcher uses: scene-matching figures are optimistic.")
    if info.get("same_dem") and record.event("tan") is not None:
        warnings.append("The vehicle carried the very DEM the world is made of: terrain-aided figures meet no DEM error "
                        "but the one its dem_sigma_m assumes, and are optimistic.")
    if info.get("abort_reason"):
        warnings.append(f"Run aborted: {info['abort_reason']}")

    sections: list[Section] = []
    summary_rows = _metric_rows(flat, KEY_METRICS)
    vt = _vehicle_table(result)
    sections.append(Section("Summary", "summary", [t for t in (Table("Key metrics", ["metric", "value"], summary_rows), vt) if t]))
    nav_figs = _figs(fn.trajectory_figure(record), fn.error_time_figures(record), fn.cdf_figure(record),
                     fw.wind_figures(record), fcs.boresight_figures(record), fcs.time_offset_figures(record),
                     fcs.intrinsics_figures(record), fg.gnss_sky_figures(record))
    sections.append(Section("Navigation", "navigation", figures=nav_figs))
    control_rows = _metric_rows(flat, [k for k in flat if k.startswith("control.") and not k.endswith(".n")])
    ctrl_fig = fn.control_figure(record)
    if control_rows or ctrl_fig:
        sections.append(Section("Guidance and control", "control",
                                [Table("Control metrics", ["metric", "value"], control_rows)] if control_rows else [], _figs(ctrl_fig)))
    examples = fe.ismn_example_figures(record)
    if result.ismn is not None:
        ismn_rows = _metric_rows(flat, [k for k in flat if k.startswith("ismn.") and not k.endswith(".n")])
        sections.append(Section("Scene matching (ISMN)", "ismn", [Table("Scene-matching metrics", ["metric", "value"], ismn_rows)],
                                _figs(fe.ismn_fix_figure(record), fme.map_error_figures(record), examples)))
    elif examples:
        sections.append(Section("Scene matching (ISMN)", "ismn", figures=examples))
    if result.tan is not None:
        tan_rows = _metric_rows(flat, [k for k in flat if k.startswith("tan.") and not k.endswith(".n")])
        sections.append(Section("Terrain-aided navigation (TAN)", "tan", [Table("TAN metrics", ["metric", "value"], tan_rows)],
                                _figs(ft.tan_fix_figure(record))))
    if result.relnav is not None:
        head = ["mean (m)", "RMS (m)", "p95 (m)", "max (m)", "ID correct", "samples"]
        t_range = Table("Relative navigation by true range", ["range"] + head,
                        _relnav_rows(result.relnav.by_range, _range_label))
        t_pairs = Table("Relative navigation per pair", ["pair"] + head, _relnav_rows(result.relnav.pairs, str))
        t_all = Table("Relative navigation", ["metric", "value"], _metric_rows(
            flat, [k for k in flat if k.startswith("relnav.") and ".pairs." not in k and ".by_range." not in k and not k.endswith(".n")]))
        sections.append(Section("Relative navigation", "relnav", [t_all, t_range, t_pairs], _figs(fe.relnav_figure(record))))
    frm_fig = fe.formation_figure(record)
    if frm_fig is not None:
        rows = _metric_rows(flat, [k for k in flat if k.startswith("formation.") and not k.endswith(".n")])
        sections.append(Section("Formation", "formation", [Table("Formation metrics", ["metric", "value"], rows)] if rows else [], [frm_fig]))
    nis_t = _nis_table(result)
    nis_f = fe.nis_figure(record)
    if nis_t or nis_f:
        sections.append(Section("Sensors and filter consistency", "sensors", [nis_t] if nis_t else [], _figs(nis_f)))

    return Report(
        title=f"Run report: {info.get('scenario_name', Path(run_dir).name)}",
        verdict=verdict,
        config=_config_table(record),
        thresholds=_threshold_table(thresholds, thr, flat),
        sections=sections,
        scenario_text=record.scenario_text,
        metrics_flat=flat,
        warnings=warnings,
    )
