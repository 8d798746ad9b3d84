"""Settings of the relative-navigation aid "relnav" (aid.py), as a scenario gives them: which
cameras and UWB node it uses, the detector, where the detected point lies on a neighbour, when
neighbour estimates start, restart and are forgotten, and the image-tracker, region-of-interest
and neighbour-filter settings. Each field's meaning, with the measurements behind its default
or the swarm scenarios' values, is in RelnavParams' docstring.
"""

from __future__ import annotations

from typing import Literal

import pydantic

from testbench.core import led_code
from testbench.core.registry import ParamsModel
from testbench.navigation.relative.layout import LayoutParams


class DetectorSpec(ParamsModel):
    type: str = "led"
    params: dict = {}


class RoiParams(ParamsModel):
    """enabled: detect/render only around predicted tracks between full frames;
    full_frame_every: a full frame every N camera frames (finds new vehicles);
    search_every: a camera that tracks nothing and knows of no neighbour in its view renders a
    full frame every N frames (acquisition at start-up and after losing everything);
    margin_px: region margin around a predicted box (grows by margin_per_miss_px per miss);
    min_size_px: smallest region side."""

    enabled: bool = True
    full_frame_every: int = pydantic.Field(10, ge=1)
    search_every: int = pydantic.Field(10, ge=1)
    margin_px: float = pydantic.Field(24.0, ge=0)
    margin_per_miss_px: float = pydantic.Field(12.0, ge=0)
    min_size_px: int = pydantic.Field(48, ge=8)


class FilterParams(ParamsModel):
    """The neighbour filters' settings (relnav.filter): neighbour_filter.FilterSettings says
    what each one means."""

    sigma_accel_mps2: float = pydantic.Field(1.0, gt=0)
    range_sigma_m: float = pydantic.Field(0.10, gt=0)
    bearing_sigma_px: float = pydantic.Field(1.0, gt=0)
    bearing_sigma_model: Literal["pixel", "angle"] = "pixel"
    robust: bool = True
    gate_prob: float = pydantic.Field(0.999, gt=0, lt=1)
    max_consecutive_rejects: int = pydantic.Field(10, ge=0)
    init_vel_sigma_mps: float = pydantic.Field(3.0, gt=0)


class TrackerParams(ParamsModel):
    """The image tracker's settings (relnav.tracker): tracking.TrackerSettings says what each
    one means."""

    n_init: int = pydantic.Field(3, ge=1)
    max_misses: int = pydantic.Field(5, ge=0)
    gate_prob: float = pydantic.Field(0.999, gt=0, lt=1)
    id_confidence: float = pydantic.Field(0.99, gt=0, le=1)
    p_chip: float = pydantic.Field(0.05, gt=0, lt=0.5)
    accel_px_s2: float = pydantic.Field(60.0, gt=0)
    search_phase: bool = False
    revoke_window: int = pydantic.Field(led_code.CODE_LENGTH, ge=0)
    revoke_prob: float = pydantic.Field(1e-3, ge=0, lt=1)
    id_keep_prob: float = pydantic.Field(0.5, ge=0, lt=1)
    mixture_min_ratio: float | None = pydantic.Field(None, gt=0, le=1)
    mixture_min_f: float = pydantic.Field(2.0, ge=0)
    mixture_action: Literal["drop", "resolve", "resolve_or_decoded"] = "drop"


class RelnavParams(ParamsModel):
    """The relnav aid's settings (RelnavAid.Params).

    cameras (sensor names), detector {type, params}, uwb (sensor name or None),
    uwb_lever_arm_b_m (own antenna; default: the UWB sensor's), target_offset_b_m (where the
    detector's centre lies on a neighbour relative to its CG, its body axes: e.g. the LED
    centroid; rotated with our own attitude, the neighbour's being unknown),
    target_offset_by_chip_b_m (the same for a frame in which the track showed blink chip 0 and
    chip 1, when the detector's centre moves with the chip: the LED centroid of the quad is the
    top anchor alone, 0.22 m above the CG, or all five LEDs, 0.02 m; used once the track's
    decoder reads the frame's chip, target_offset_b_m before), target_offset_data_b_m (the same
    for the centroid of the data LEDs alone, which a merged blob's chip-resolved bearing takes:
    tracker.mixture_action "resolve"; the quad's four arm LEDs, 0.03 m above the CG; default
    target_offset_b_m), led_rate_hz (default: the
    first camera's rate), range_max_age_s (a range this recent may start a filter with a
    bearing), stale_after_s (a neighbour with no bearing fused for this long is forgotten),
    report_max_age_s (the NeighbourTable holds only neighbours with both a bearing and a range
    fused within this age: with one of them missing the estimate drifts along the unobserved
    direction, e.g. along the line of sight beyond UWB range),
    predicted_association (an undecoded track may feed the neighbour it uniquely matches, when
    that neighbour's estimate is settled: sigma below assoc_max_sigma_m, and no track in any
    camera carries that neighbour's decoded ID. It keeps in the table the neighbours that
    stand behind a nearer one on the arrowhead's lines of sight, whose blobs merge with it and
    whose own tracks rarely decode, and the followers' formation needs them. Its cost, measured
    on 2026-11-25 (paper swarm, LED): of its associations in a 30 s run 57 % fed a blob of
    several vehicles alike and 55 % of the rest the wrong vehicle, whose estimate had already
    been pulled 9 px off; 300 s with / without it: relnav mean 0.186 / 0.184 m, p95 0.41 /
    0.40 m, max 6.9 / 4.0 m, but formation RMS 2.6 / 4.4 m (max 13 / 29 m: the back row,
    left with one neighbour 173 m away for 20 s, ran 11 m off its slot in the first turn),
    table rows 27 257 / 22 917; feeding its bearings with 3x the pixel noise: 0.193 m, 6.4 m,
    2.6 m; with the oracle detector it changes nothing (60 s: 0.177 / 0.176 m)), reset_after_rejects
    (a neighbour whose bearings were rejected this many times in a row, or whose ranges were
    rejected filter.max_consecutive_rejects times in a row, restarts from the next bearing of a
    track with a decoded ID and the median of the recent ranges; on bearings alone only once
    none has been accepted for reset_bearing_after_s, and not when the restart would move the
    neighbour more than restart_max_jump_m + 3 sigma from its prediction: a track under a wrong
    ID, since at 100 m spacing a real lost estimate is off by tens of metres, not a vehicle
    spacing or more; a really lost estimate is then dropped after stale_after_s and restarted
    afresh, within the same distance, plus forgotten_speed_mps per second since, of where it
    was when dropped, for forgotten_max_age_s; every start or restart also needs a track whose
    ID posterior is at least the tracker's id_confidence, the posterior that assigns an ID: the
    tracker keeps an assigned ID down to lower posteriors, with hysteresis, and uav1's estimate
    of uav7 once started 90 m off from a blob of the collinear uav3/uav6 still labelled uav7 at
    0.86), coasting_tracks_keep_ids (a decoded track that saw no detection in its latest frame
    still keeps its vehicle from predicted association, as a seen one does; see
    RelnavAid._decoded_in_view: off, the merged blob of two vehicles that came onto one line of
    sight can feed the one estimate that predicts it while their decoded tracks coast, which
    kept swarm_fixedwing from losing a follower for good; on the paper arrowhead, whose lattice
    puts three or four vehicles on every line of sight, it was slightly worse off in three
    realisations of three: track-frame IDs 0.99001 / 0.98968 / 0.99115 -> 0.98992 / 0.98850 /
    0.98939, formation RMS 2.246 / 2.190 / 1.978 -> 2.255 / 2.282 / 2.001 m, relnav max 4.2 /
    5.1 / 4.0 -> 3.1 / 7.5 / 5.3 m (300 s, LED, B)), skip_ambiguous (leave bearings that
    another neighbour's estimate claims: association.py), occlusion_margin_m (a bearing that a
    neighbour's estimate this much nearer also predicts is left to that one),
    layout (the formation's slot table, mission data every vehicle carries: a start or restart
    farther from the slot-predicted position than its tolerance is refused, layout.py; None:
    no such check),
    target_extent_m (the largest extent of the formation's vehicles, m, e.g. a quad's 0.55 m
    rotor-tip diagonal: a detection whose box is larger than box_size_factor times what that
    extent makes at the nearest neighbour's UWB range, plus box_slack_px, is no neighbour and
    is dropped before tracking; None: no such check; only for detectors whose box is the
    vehicle's outline (Detector.box_shows_extent: not the LED detector). Why: the CNN now and
    then draws a box of 100-180 px about the horizon, where a quad at 100-270 m makes 1-12 px;
    the LED reader then read several vehicles' LEDs inside it, the track decoded an ID from
    that mixture, and it started estimates on another vehicle's line of sight 30-60 m off
    (swarm_cnn, 18 s, the horizon then a black no-data band: 9 of 81 starts; with haze and
    sky there, 30 s: 191 boxes dropped, relnav mean 0.31 -> 0.27 m, max 13.0 -> 7.3 m),
    log_rate_hz (rows of table "relnav"), led_reader (params of the LED detector that reads
    the blink level inside boxes from detectors without LED output, e.g. the CNN), seed (oracle noise when no rng is injected), roi,
    filter, tracker.
    """

    cameras: list[str]
    detector: DetectorSpec = DetectorSpec()
    uwb: str | None = "uwb"
    uwb_lever_arm_b_m: tuple[float, float, float] | None = None
    target_offset_b_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    target_offset_by_chip_b_m: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    target_offset_data_b_m: tuple[float, float, float] | None = None
    led_rate_hz: float | None = pydantic.Field(None, gt=0)
    range_max_age_s: float = pydantic.Field(0.5, gt=0)
    stale_after_s: float = pydantic.Field(5.0, gt=0)
    report_max_age_s: float = pydantic.Field(1.0, gt=0)
    predicted_association: bool = True
    assoc_max_sigma_m: float = pydantic.Field(1.0, gt=0)
    reset_after_rejects: int = pydantic.Field(5, ge=1)
    reset_bearing_after_s: float = pydantic.Field(1.0, ge=0)
    restart_max_jump_m: float = pydantic.Field(30.0, gt=0)
    forgotten_max_age_s: float = pydantic.Field(30.0, ge=0)
    forgotten_speed_mps: float = pydantic.Field(5.0, ge=0)
    occlusion_margin_m: float = pydantic.Field(10.0, ge=0)
    coasting_tracks_keep_ids: bool = True
    skip_ambiguous: bool = True
    layout: LayoutParams | None = None
    target_extent_m: float | None = pydantic.Field(None, gt=0)
    box_size_factor: float = pydantic.Field(3.0, ge=1)
    box_slack_px: float = pydantic.Field(4.0, ge=0)
    log_rate_hz: float = pydantic.Field(2.0, gt=0)
    led_reader: dict = {}
    seed: int = 0
    roi: RoiParams = RoiParams()
    filter: FilterParams = FilterParams()
    tracker: TrackerParams = TrackerParams()
