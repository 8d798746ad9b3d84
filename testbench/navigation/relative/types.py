"""Messages of relative navigation: detections, per-neighbour estimates and the table the
formation controller reads.

Pixel coordinates are full-frame (u right, v down, integers at pixel centres) even when a
detector ran on a region. NED is the local frame; relative position = neighbour minus self,
both at their centres of gravity.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Detection:
    """One vehicle found in a camera image.

    bbox_px: (u0, v0, u1, v1) full-frame pixels (u1, v1 exclusive edges); centre_px: (u, v) of
    the point the detector believes is the vehicle's centre (LED centroid for the LED detector,
    box centre otherwise); score in [0, 1]; label: class name.
    led_px: (n, 2) centroids of the LED blobs it resolved (may be empty); led_on: per-LED
    on/off when the detector can tell them apart (None otherwise); led_level: a scalar that
    rises with the number of lit LEDs (lit LED count, or summed LED brightness) for blink
    decoding, None when the detector does not see LEDs.
    parts_px: (k, 2) full-frame pixels of the k >= 2 vehicles the detector found merged in
    this one detection (the LED centroid of each anchor LED's share of the blobs), empty when
    it saw one vehicle or cannot tell: the detection stays one for tracking and blink
    decoding, and the caller may take the bearing of the part its estimate predicts.
    data_centre_px: (u, v) full-frame pixels of the brightness-weighted centroid of the data
    LEDs' pixels alone (the LED detector with data_hue_deg), None otherwise or when none is lit:
    in a blob of two vehicles of which the code lights one's data LEDs only, it is that one's.
    """

    bbox_px: tuple[float, float, float, float]
    centre_px: tuple[float, float]
    score: float = 1.0
    label: str = "vehicle"
    led_px: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)), repr=False)
    led_on: tuple[bool, ...] | None = None
    led_level: float | None = None
    parts_px: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)), repr=False)
    data_centre_px: tuple[float, float] | None = None

    @property
    def width_px(self) -> float:
        return self.bbox_px[2] - self.bbox_px[0]

    @property
    def height_px(self) -> float:
        return self.bbox_px[3] - self.bbox_px[1]

    def shifted(self, du: float, dv: float) -> "Detection":
        """The same detection moved by (du, dv) pixels (region -> full frame)."""
        u0, v0, u1, v1 = self.bbox_px
        return Detection((u0 + du, v0 + dv, u1 + du, v1 + dv), (self.centre_px[0] + du, self.centre_px[1] + dv),
                         self.score, self.label, np.asarray(self.led_px, float).reshape(-1, 2) + [du, dv],
                         self.led_on, self.led_level, np.asarray(self.parts_px, float).reshape(-1, 2) + [du, dv],
                         None if self.data_centre_px is None else (self.data_centre_px[0] + du, self.data_centre_px[1] + dv))


@dataclass(frozen=True)
class RelativeEstimate:
    """What a vehicle knows about one neighbour (no communication: its own sensors only).

    t_s: time of validity; peer_id; pos_ned_m (3,): neighbour minus self, NED, m;
    vel_ned_mps (3,): its rate (neighbour velocity minus own velocity); cov_pos_ned_m2,
    cov_vel_ned_m2s2 (3, 3); id_confidence: posterior of the decoded LED ID of the track that
    last gave a bearing (nan if never seen); last_bearing_t_s, last_range_t_s: when a camera
    bearing / a UWB range was last fused (-inf if never).
    """

    t_s: float
    peer_id: str
    pos_ned_m: np.ndarray
    vel_ned_mps: np.ndarray
    cov_pos_ned_m2: np.ndarray
    cov_vel_ned_m2s2: np.ndarray
    id_confidence: float = float("nan")
    last_bearing_t_s: float = float("-inf")
    last_range_t_s: float = float("-inf")

    @property
    def sigma_m(self) -> float:
        """sqrt(trace(cov_pos)): 1-sigma radial position uncertainty (m)."""
        return float(np.sqrt(max(np.trace(self.cov_pos_ned_m2), 0.0)))


# id -> estimate of that neighbour: what the formation controller receives as `reference`.
NeighbourTable = dict[str, RelativeEstimate]
