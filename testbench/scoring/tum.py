"""TUM trajectory files, so that `evo_ape` can check our position-error numbers.

Format (one pose per line): `t x y z qx qy qz qw`, here in local NED metres (x north,
y east, z down) and the body-to-NED attitude quaternion q_nb. evo's APE on the translation
part with no alignment, `evo_ape tum truth.tum nav.tum`, then reproduces
nav.position_error_m.rms.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from testbench.scoring.record_io import RunRecord, column


def write_tum(path: str | Path, t_s, pos_ned_m, q_nb_wxyz=None) -> int:
    """Write one trajectory as a TUM file; returns the number of poses written.

    t_s: (n,) seconds; pos_ned_m: (n, 3) local NED metres; q_nb_wxyz: (n, 4) body-to-NED
    quaternion, scalar first (None or non-finite rows -> identity: the attitude does not
    enter a translation APE, but evo needs a valid unit quaternion on every line).
    Rows with a non-finite time or position are skipped (e.g. before the navigator started).
    Timestamps are written with 9 decimals so that evo associates poses exactly.
    """
    t = np.asarray(t_s, float).ravel()
    p = np.asarray(pos_ned_m, float).reshape(-1, 3)
    if q_nb_wxyz is None:
        q = np.tile([1.0, 0.0, 0.0, 0.0], (t.size, 1))
    else:
        q = np.asarray(q_nb_wxyz, float).reshape(-1, 4).copy()
    if not (p.shape[0] == t.size == q.shape[0]):
        raise ValueError(f"write_tum: lengths differ (t {t.size}, pos {p.shape[0]}, q {q.shape[0]})")
    norm = np.linalg.norm(q, axis=1)
    bad_q = ~np.isfinite(norm) | (norm < 1e-9)
    q[bad_q] = [1.0, 0.0, 0.0, 0.0]
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    keep = np.isfinite(t) & np.all(np.isfinite(p), axis=1)
    rows = np.column_stack([t, p, q[:, 1], q[:, 2], q[:, 3], q[:, 0]])[keep]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, rows, fmt=["%.9f"] + ["%.6f"] * 3 + ["%.9f"] * 4)
    return int(rows.shape[0])


def _quat(tel: pd.DataFrame, prefix: str) -> np.ndarray:
    return np.stack([column(tel, f"{prefix}_q{c}") for c in "wxyz"], axis=1)


def write_run_tums(record: RunRecord, out_dir: str | Path) -> list[Path]:
    """Write <id>_truth.tum and <id>_nav.tum for each vehicle into out_dir; returns the paths.

    The nav file keeps only rows where both estimate and truth are finite, so evo associates
    exactly the rows that scoring uses.
    """
    out_dir = Path(out_dir)
    paths = []
    for vid in record.vehicle_ids:
        tel = record.vehicle_telemetry(vid)
        if len(tel) == 0:
            continue
        t = column(tel, "t_s")
        truth = np.stack([column(tel, f"truth_{a}_m") for a in ("north", "east", "down")], axis=1)
        nav = np.stack([column(tel, f"nav_{a}_m") for a in ("north", "east", "down")], axis=1)
        both = np.all(np.isfinite(truth), axis=1) & np.all(np.isfinite(nav), axis=1)
        for kind, pos in (("truth", truth), ("nav", nav)):
            p = out_dir / f"{vid}_{kind}.tum"
            write_tum(p, t[both], pos[both], _quat(tel, kind)[both])
            paths.append(p)
    return paths
