"""A rolling shutter: the rows of a frame exposed one after another while the vehicle moves.

A CMOS sensor with a rolling shutter reads its rows out in turn: row v is exposed
readout_s * ((v + 0.5) / H - 0.5) seconds after the frame's middle row (the frame's exposure
time, which its stamp and CameraParams.time_offset_s refer to). At 800 m, 25 m/s and a 30 deg
bank turn (0.23 rad/s of yaw), a 30 ms readout moves the first row's ground 0.75 m along track
and turns it 7 mrad against the last row's: a bend of about 2.6 m at the frame's ends, which a
single pose cannot explain.

The renderer takes one pose per call, so a rolling-shutter frame is rendered in horizontal
bands of rows, each at the true pose of its middle row, and stitched. Within a band the pose
is held: the seam between two bands is the pose's change over readout_s / n_bands (with 24
bands and the turn above, 0.3 mrad and 3 cm, a tenth of a 1.44 m ground pixel at 800 m).
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from testbench.core.camera_geometry import row_delay_s
from testbench.sensors.camera.types import RenderedFrame

__all__ = ["render_rolling", "row_delay_s", "split_rows"]


def split_rows(box: tuple[int, int, int, int], height_px: int, n_bands: int) -> list[tuple[int, int, int, int]]:
    """The region box (u0, v0, u1, v1) of a frame height_px rows high cut into horizontal bands
    of about height_px / n_bands rows each (at least one band; no band is empty)."""
    u0, v0, u1, v1 = box
    rows = v1 - v0
    n = int(min(max(1, round(n_bands * rows / float(height_px))), rows))
    edges = np.round(np.linspace(v0, v1, n + 1)).astype(int)
    return [(u0, int(a), u1, int(b)) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def render_rolling(box: tuple[int, int, int, int], height_px: int, readout_s: float, n_bands: int,
                   render_band: Callable[[tuple[int, int, int, int], float], RenderedFrame],
                   merge_truths: Callable[[Sequence[RenderedFrame]], tuple],
                   full_frame: bool) -> RenderedFrame:
    """One region of a rolling-shutter frame: render_band(band_box, row_delay_s) renders each
    band of `box` at the pose of the band's middle row (its delay after the frame's middle
    row, s); the bands are stacked into one RenderedFrame of the region (roi None when
    full_frame). The truths of the other vehicles are merged as the camera merges regions'
    (merge_truths); offmap, cloud and shadow shares are weighted by the bands' pixels and
    ground pixels."""
    parts = []
    for band in split_rows(box, height_px, n_bands):
        mid_row = 0.5 * (band[1] + band[3]) - 0.5  # the band's middle row (pixel centres)
        parts.append(render_band(band, float(row_delay_s(mid_row, height_px, readout_s))))
    if len(parts) == 1:
        p = parts[0]
        return RenderedFrame(p.image, p.valid, p.sky, p.offmap_fraction, p.vehicles, None if full_frame else box,
                             p.ground_points_ned_m, p.cloud_fraction, p.shadow_fraction)
    n_px = [p.valid.size for p in parts]
    n_ground = [int(p.valid.size - np.count_nonzero(p.sky)) for p in parts]
    points = None
    if all(p.ground_points_ned_m is not None for p in parts):
        points = np.concatenate([p.ground_points_ned_m for p in parts], axis=0)
    return RenderedFrame(
        np.concatenate([p.image for p in parts], axis=0),
        np.concatenate([p.valid for p in parts], axis=0),
        np.concatenate([p.sky for p in parts], axis=0),
        sum(p.offmap_fraction * n for p, n in zip(parts, n_px)) / max(sum(n_px), 1),
        merge_truths(parts),
        None if full_frame else box,
        points,
        sum(p.cloud_fraction * n for p, n in zip(parts, n_ground)) / max(sum(n_ground), 1),
        sum(p.shadow_fraction * n for p, n in zip(parts, n_ground)) / max(sum(n_ground), 1),
    )
