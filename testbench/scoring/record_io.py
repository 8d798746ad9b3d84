"""Loading a run record (the files `testbench run` writes into a run directory).

A run directory DIR holds (see DESIGN.md, output contract, and the lead's recorder):
- DIR/telemetry.parquet: one row per vehicle per record tick, sorted by t_s then vehicle order;
  truth_*, nav_*, cmd_*, gd_* (guidance) and gnss_available columns, SI units, local NED.
- DIR/events/{corrections,ismn,tan,relnav,relnav_id,formation,gnss_sky}.parquet: event tables (all but
  corrections may be absent; gnss_sky: the satellites a GNSS receiver with a sky model saw).
- DIR/ismn_examples/*.npz, DIR/frames/*.png: optional images for reports.
- DIR/run.json: scenario name, seed, timing, status, vehicles, GNSS-denied windows, phase
  thresholds, optional map preview, metric thresholds.
- DIR/scenario.yaml: the resolved scenario (text, shown in reports).

Scoring reads only what is here: it never imports the engine.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from testbench.core.errors import InputError

log = logging.getLogger(__name__)

#: What `testbench run` writes into a run directory (globs relative to DIR). A run removes them
#: before it writes its own, so that no file of an earlier run into the same directory (a
#: vehicle's trajectory, an event table, an ISMN example that run had and this one has not)
#: is read as this run's.
RUN_OUTPUT_GLOBS = ("metrics.json", "run.json", "report.html", "report.pdf", "map_preview.png", "scenario.yaml",
                    "telemetry.parquet", "events/*.parquet", "trajectories/*.tum", "ismn_examples/*.npz",
                    "frames/*.png")


def remove_run_outputs(run_dir: str | Path) -> int:
    """Delete the files of RUN_OUTPUT_GLOBS in run_dir (nothing else); returns how many."""
    removed = 0
    for pattern in RUN_OUTPUT_GLOBS:
        for path in Path(run_dir).glob(pattern):
            if path.is_file():
                path.unlink()
                removed += 1
    return removed


#: Columns without which no metric can be computed.
REQUIRED_TELEMETRY_COLUMNS = (
    "vehicle_id",
    "t_s",
    "truth_north_m",
    "truth_east_m",
    "truth_down_m",
    "nav_north_m",
    "nav_east_m",
    "nav_down_m",
)

EVENT_TABLES = ("corrections", "ismn", "tan", "relnav", "relnav_id", "formation", "gnss_sky")

# Default phase thresholds (run.json "phases"): a sample is "turning" when |bank| exceeds
# turn_bank_deg or |turn rate| exceeds turn_rate_deg_s.
DEFAULT_PHASES = {"turn_bank_deg": 10.0, "turn_rate_deg_s": 3.0}


@dataclass(frozen=True)
class RunRecord:
    """Everything scoring and reporting need from one run directory.

    telemetry: pandas DataFrame, one row per vehicle per record tick (columns as recorded).
    events: name -> DataFrame for each event table present ("corrections", "ismn", "relnav",
    "formation"); absent tables are absent keys.
    run_info: the parsed run.json dict.
    scenario_text: DIR/scenario.yaml as text ("" when absent).
    run_dir: the directory it was loaded from (None for a record built in memory).
    """

    telemetry: pd.DataFrame
    run_info: dict[str, Any]
    events: dict[str, pd.DataFrame] = field(default_factory=dict)
    scenario_text: str = ""
    run_dir: Path | None = None

    # ------------------------------------------------------------------ helpers
    @property
    def vehicle_ids(self) -> list[str]:
        """Vehicle ids in scenario order (run.json "vehicles"), else in telemetry order."""
        listed = [str(v["id"]) for v in self.run_info.get("vehicles", []) if "id" in v]
        seen = list(pd.unique(self.telemetry["vehicle_id"].astype(str)))
        if listed:
            return listed + [v for v in seen if v not in listed]
        return seen

    @property
    def phases(self) -> dict[str, float]:
        """Phase thresholds: {"turn_bank_deg", "turn_rate_deg_s"} (defaults filled in)."""
        out = dict(DEFAULT_PHASES)
        out.update({k: float(v) for k, v in (self.run_info.get("phases") or {}).items()})
        return out

    @property
    def thresholds(self) -> dict[str, dict[str, float]]:
        """The scenario's metric thresholds ("dotted.key" -> {"min"/"max": value})."""
        return dict(self.run_info.get("thresholds") or {})

    def event(self, name: str) -> pd.DataFrame | None:
        """The event table `name`, or None when the run did not record it (or it is empty)."""
        df = self.events.get(name)
        if df is None or len(df) == 0:
            return None
        return df

    def vehicle_telemetry(self, vehicle_id: str) -> pd.DataFrame:
        """Telemetry rows of one vehicle, in time order."""
        tel = self.telemetry
        return tel[tel["vehicle_id"].astype(str) == vehicle_id]

    def subset(self, vehicle_id: str) -> "RunRecord":
        """The record restricted to one vehicle (its telemetry and the events it owns)."""
        events = {}
        for name, df in self.events.items():
            if "vehicle_id" in df.columns:
                events[name] = df[df["vehicle_id"].astype(str) == vehicle_id]
            else:
                events[name] = df
        return RunRecord(
            telemetry=self.vehicle_telemetry(vehicle_id),
            run_info=self.run_info,
            events=events,
            scenario_text=self.scenario_text,
            run_dir=self.run_dir,
        )


def column(df: pd.DataFrame, name: str, dtype=float) -> np.ndarray:
    """Column `name` as a numpy array; NaN-filled (float) when the recorder did not write it."""
    if name in df.columns:
        values = df[name].to_numpy()
        if dtype is float:
            return np.asarray(values, dtype=float)
        return np.asarray(values)
    if dtype is bool:
        return np.zeros(len(df), dtype=bool)
    return np.full(len(df), np.nan)


def has_columns(df: pd.DataFrame, *names: str) -> bool:
    """True when every one of `names` is a column of `df` with at least one finite value."""
    for n in names:
        if n not in df.columns:
            return False
        v = df[n].to_numpy()
        if v.dtype.kind == "f" and not np.isfinite(v).any():
            return False
    return True


def _read_parquet(path: Path) -> pd.DataFrame:
    try:
        return pq.read_table(path).to_pandas()
    except Exception as exc:  # pyarrow raises several types for a damaged file
        raise InputError(f"{path}: cannot read parquet table ({exc})") from None


def load_run(run_dir: str | Path) -> RunRecord:
    """Load the run record in `run_dir` (see module docstring).

    Raises InputError naming the file when run.json or telemetry.parquet is missing or
    unreadable, or when telemetry lacks a required column.
    """
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise InputError(f"{run_dir}: not a run directory (expected a folder written by `testbench run`)")
    info_path = run_dir / "run.json"
    if not info_path.is_file():
        raise InputError(f"{info_path}: missing (expected the run.json of a run directory)")
    try:
        run_info = json.loads(info_path.read_text())
    except json.JSONDecodeError as exc:
        raise InputError(f"{info_path}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
    if not isinstance(run_info, dict):
        raise InputError(f"{info_path}: expected a JSON object at the top level")

    tel_path = run_dir / "telemetry.parquet"
    if not tel_path.is_file():
        raise InputError(f"{tel_path}: missing (expected the telemetry of the run)")
    telemetry = _read_parquet(tel_path)
    missing = [c for c in REQUIRED_TELEMETRY_COLUMNS if c not in telemetry.columns]
    if missing:
        raise InputError(f"{tel_path}: missing column(s) {', '.join(missing)}")
    telemetry["vehicle_id"] = telemetry["vehicle_id"].astype(str)

    events: dict[str, pd.DataFrame] = {}
    for name in EVENT_TABLES:
        p = run_dir / "events" / f"{name}.parquet"
        if p.is_file():
            df = _read_parquet(p)
            if "vehicle_id" in df.columns:
                df["vehicle_id"] = df["vehicle_id"].astype(str)
            if "peer_id" in df.columns:
                df["peer_id"] = df["peer_id"].astype(str)
            events[name] = df

    scen = run_dir / "scenario.yaml"
    scenario_text = scen.read_text(errors="replace") if scen.is_file() else ""
    log.debug("loaded run %s: %d telemetry rows, events %s", run_dir, len(telemetry), sorted(events))
    return RunRecord(
        telemetry=telemetry, run_info=run_info, events=events, scenario_text=scenario_text, run_dir=run_dir
    )
