"""The relative-navigation aid "relnav": cameras + UWB -> per-neighbour relative estimates.

Per camera frame: detect (full frame, or regions around predicted tracks), track in the image,
decode LED IDs, and fuse each identified track's line of sight (eq. 17-18, rotated with the
vehicle's OWN ESTIMATED attitude) in that neighbour's EKF; per UWB range: fuse it in the EKF of
the peer with that ID (NLOS-gated). When a neighbour's estimate starts, restarts or is forgotten
is book.py's. No measurement goes to the INS (process returns []);
`controller_input()` hands the NeighbourTable to the formation controller.
Nothing here reads another vehicle's state: only this vehicle's sensors and estimate.
"""

from __future__ import annotations

import zlib
from dataclasses import replace
from typing import Any

import numpy as np
import pydantic

from testbench.core import led_code
from testbench.core.errors import InputError
from testbench.core.interfaces import BuildContext, NavigationAid
from testbench.core.messages import NavEstimate, UwbRange
from testbench.core.registry import ParamsModel, build, register
from testbench.core.rotations import quat_to_dcm, rotvec_to_quat
from testbench.navigation.relative.association import AssociationRules, Bearing
from testbench.navigation.relative.book import NeighbourBook, StartRules
from testbench.navigation.relative.box_size import small_enough
from testbench.navigation.relative.detectors import LedDetector
from testbench.navigation.relative.diagnostics import RelnavDiagnostics, id_truth
from testbench.navigation.relative.frames import camera_model, frame_camera_name, frame_parts, is_camera_frame
from testbench.navigation.relative.geometry import undistort_normalized
from testbench.navigation.relative.layout import LayoutParams
from testbench.navigation.relative.neighbour_filter import FilterSettings, constant_velocity_F
from testbench.navigation.relative.regions import detect_regions, rois_around_tracks
from testbench.navigation.relative.tracking import Tracker, TrackerSettings
from testbench.navigation.relative.types import Detection, NeighbourTable, RelativeEstimate


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
    sigma_accel_mps2: float = pydantic.Field(1.0, gt=0)
    range_sigma_m: float = pydantic.Field(0.10, gt=0)
    bearing_sigma_px: float = pydantic.Field(1.0, gt=0)
    robust: bool = True
    gate_prob: float = pydantic.Field(0.999, gt=0, lt=1)
    max_consecutive_rejects: int = pydantic.Field(10, ge=0)
    init_vel_sigma_mps: float = pydantic.Field(3.0, gt=0)


class TrackerParams(ParamsModel):
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


@register("aid", "relnav")
class RelnavAid(NavigationAid):
    """Relative navigation of one vehicle (see the module docstring).

    Params: cameras (sensor names), detector {type, params}, uwb (sensor name or None),
    uwb_lever_arm_b_m (own antenna; default: the UWB sensor's), target_offset_b_m (where the
    detector's centre lies on a neighbour relative to its CG, its body axes: e.g. the LED
    centroid; rotated with our own attitude, the neighbour's being unknown),
    target_offset_by_chip_b_m (the same for a frame in which the track showed blink chip 0 and
    chip 1, when the detector's centre moves with the chip: the LED centroid of the quad is the
    top anchor alone, 0.22 m above the CG, or all five LEDs, 0.02 m; used once the track's
    decoder reads the frame's chip, target_offset_b_m before), led_rate_hz (default: the
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
    0.86), skip_ambiguous (leave bearings that
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

    class Params(ParamsModel):
        cameras: list[str]
        detector: DetectorSpec = DetectorSpec()
        uwb: str | None = "uwb"
        uwb_lever_arm_b_m: tuple[float, float, float] | None = None
        target_offset_b_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
        target_offset_by_chip_b_m: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
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

    def __init__(self, params: "RelnavAid.Params", *, ctx: BuildContext, sensors: dict | None = None,
                 onboard: dict | None = None, rng: np.random.Generator | None = None, **_: Any):
        self.params = params
        self.ctx = ctx
        self.self_id = ctx.vehicle_id
        self.ids = tuple(ctx.vehicle_ids)
        if len(self.ids) > led_code.MAX_VEHICLES:
            raise InputError(f"relnav: at most {led_code.MAX_VEHICLES} vehicles carry an LED ID (got {len(self.ids)})")
        self.own_index = self.ids.index(self.self_id) if self.self_id in self.ids else None
        sensors = sensors or {}
        self.cams = {}
        for name in params.cameras:
            if name not in sensors:
                raise InputError(f"relnav.cameras: no sensor named {name!r} on vehicle {self.self_id!r}")
            self.cams[name] = camera_model(sensors[name], name)
        self.cam_rate = {n: float(getattr(sensors[n], "rate_hz", 10.0)) for n in params.cameras}
        self._phase = {n: zlib.crc32(f"{ctx.vehicle_id}/{n}".encode()) % params.roi.full_frame_every for n in params.cameras}
        self.led_rate_hz = float(params.led_rate_hz or next(iter(self.cam_rate.values()), 10.0))
        uwb_sensor = sensors.get(params.uwb) if params.uwb else None
        if params.uwb and uwb_sensor is None:
            raise InputError(f"relnav.uwb: no sensor named {params.uwb!r} on vehicle {self.self_id!r}")
        lever = params.uwb_lever_arm_b_m if params.uwb_lever_arm_b_m is not None else getattr(uwb_sensor, "lever", (0, 0, 0))
        self.uwb_lever = np.asarray(lever, float)
        if rng is None:
            rng = np.random.default_rng(np.random.SeedSequence([params.seed, zlib.crc32(self.self_id.encode())]))
        self.detector = build("detector", params.detector.type, params.detector.params, "relnav.detector", ctx=ctx, rng=rng)
        offsets = [params.target_offset_b_m, *(params.target_offset_by_chip_b_m or ())]
        self._target_b_m = np.asarray(params.target_offset_b_m, float)
        self._target_by_chip_b_m = (None if params.target_offset_by_chip_b_m is None
                                    else np.asarray(params.target_offset_by_chip_b_m, float))  # (2, 3)
        self._centre_reference = getattr(self.detector, "centre_reference", "vehicle_centre")
        if self._centre_reference == "vehicle_centre" and np.any(np.asarray(offsets, float)):
            # (A leftover LED offset with a CG detector biases every bearing: the oracle runs
            # of the swarm benchmark carried the LED's 0.13 m, swarm_cnn likewise.)
            raise InputError(f"relnav.target_offset_b_m / target_offset_by_chip_b_m: detector {params.detector.type!r} "
                             f"reports the vehicle's centre, so the target offsets must be zero (got {offsets})")
        if params.target_extent_m is not None and not getattr(self.detector, "box_shows_extent", True):
            raise InputError(f"relnav.target_extent_m: detector {params.detector.type!r} reports boxes of the LEDs' glow, "
                             f"not of the vehicle, so their size says nothing of the range: leave target_extent_m unset")
        # Detectors that give boxes only (the CNN) get their LED level read inside each box.
        self.led_reader = LedDetector(LedDetector.Params(**params.led_reader))
        tp = params.tracker
        ts = TrackerSettings(n_init=tp.n_init, max_misses=tp.max_misses, gate_prob=tp.gate_prob, id_confidence=tp.id_confidence,
                             p_chip=tp.p_chip, accel_px_s2=tp.accel_px_s2, search_phase=tp.search_phase,
                             revoke_window=tp.revoke_window, revoke_prob=tp.revoke_prob,
                             id_keep_prob=tp.id_keep_prob)
        self.trackers = {n: Tracker(len(self.ids), self.own_index, ts) for n in params.cameras}
        self.fset = FilterSettings(**params.filter.model_dump())
        self.assoc = AssociationRules(self.fset.bearing_sigma_px, params.assoc_max_sigma_m, params.report_max_age_s,
                                      params.occlusion_margin_m, params.restart_max_jump_m, params.forgotten_speed_mps)
        self.id_conf: dict[str, float] = {}
        # Diagnostics only: did the last bearing fused for a peer come from that peer (frame
        # truth)? peer -> (IdTruth.score, ambiguous 1.0/0.0). Vehicles whose expected points lie
        # within two detection sigmas of each other are alike (diagnostics.id_truth).
        self.bearing_id_ok: dict[str, tuple[float, float]] = {}
        self._id_tie_px = 2.0 * self.fset.bearing_sigma_px
        self.last_estimate: NavEstimate | None = None
        self.t_s = 0.0
        self._next_log_t = 0.0
        self.counters = {"frames": 0, "detections": 0, "id_checks": 0, "id_wrong": 0, "id_ambiguous": 0, "bearings_used": 0, "predicted_assoc": 0, "restarts_refused": 0,
                         "filter_resets": 0, "bearings_occluded": 0, "starts_off_layout": 0,
                         "bearings_closer_to_other": 0, "bearings_from_part": 0,
                         "detections_oversize": 0}
        self.book = NeighbourBook(
            self.self_id,
            StartRules(params.reset_after_rejects, params.reset_bearing_after_s, params.tracker.id_confidence,
                       params.range_max_age_s, params.stale_after_s, params.forgotten_max_age_s,
                       np.asarray(params.target_offset_b_m, float), params.layout),
            self.fset, self.assoc, self.counters)
        self.filters = self.book.filters
        """peer ID -> its NeighbourFilter (the book's, shared)."""

    # -- NavigationAid ---------------------------------------------------------------------

    def accepts(self, measurement: Any) -> bool:
        if isinstance(measurement, UwbRange):
            return self.params.uwb is not None
        return is_camera_frame(measurement) and frame_camera_name(measurement) in self.cams

    def process(self, measurement: Any, estimate: NavEstimate) -> tuple[list, Any]:
        self.last_estimate = estimate
        self.t_s = max(self.t_s, float(measurement.t_s))
        if isinstance(measurement, UwbRange):
            self.book.add_range(measurement, estimate)
            return [], None
        return [], self._frame(measurement, estimate)

    # -- cameras ---------------------------------------------------------------------------

    def _frame(self, frame: Any, est: NavEstimate) -> RelnavDiagnostics:
        name = frame_camera_name(frame)
        cam, mount = self.cams[name]
        tracker = self.trackers[name]
        t = float(frame.t_s)
        fi = led_code.frame_index(t, self.led_rate_hz)
        n_cam = int(round(t * self.cam_rate[name])) + self._phase[name]
        # A full frame, when the camera rendered one, is searched whole on full-frame ticks and
        # while this camera has no track; otherwise only around the predicted tracks.
        full_due = (not self.params.roi.enabled) or n_cam % self.params.roi.full_frame_every == 0 or not tracker.tracks
        dets, truths = [], []
        for part in frame_parts(frame, cam.width_px, cam.height_px):
            rois = None
            if part.full and not full_due:
                rois = self._track_rois(name, t)
            found = self._plausible_size(detect_regions(self.detector, part.image, rois, part.origin_uv, part.truths), cam, t)
            dets.extend(self._with_led_level(d, part) if d.led_level is None else d for d in found)
            truths.extend(part.truths)
        self.counters["frames"] += 1
        self.counters["detections"] += len(dets)
        R_nb = quat_to_dcm(est.q_nb_wxyz)
        R_nc = R_nb @ mount.R_bc
        # Own rotation between frames compensated in the image tracker (own estimated attitude).
        updated = tracker.update(t, fi, dets, R_nc, cam.K)

        # The bearing points at the detected point p_peer + R_nb o (o: target offset): fuse it as
        # a bearing to the CG seen from a camera moved by -R_nb o.
        lever_b = np.asarray(mount.lever_arm_b_m, float)
        c_off = R_nb @ (lever_b - self._target_b_m)
        by_chip = self._target_by_chip_b_m
        att_sigma = float(np.sqrt(max(np.max(np.linalg.eigvalsh(np.asarray(est.cov_att_rad2, float))), 0.0)))
        focal = 0.5 * (cam.fx + cam.fy)
        diag = RelnavDiagnostics(t)
        claimed: set[str] = set()
        # Predicted association never feeds a neighbour some track in any camera carries as its
        # decoded ID: the ID is the stronger evidence, and an estimate that lost its neighbour
        # (it rejects that track's bearings) would be held on the wrong vehicle by the
        # unidentified tracks it still gates, never reaching its reset (17 m in a 15 s run).
        decoded = {self.ids[x.id_index] for trk in self.trackers.values() for x in trk.tracks
                   if x.confirmed and x.id_index is not None}
        for tr in sorted((x for x in updated if x.confirmed), key=lambda x: -x.id_confidence):
            det = tr.last_detection
            peer = self.ids[tr.id_index] if tr.id_index is not None else None
            truth = id_truth(det, truths, self._centre_reference, self._id_tie_px) if truths else None  # scoring only, never fused
            if truth is not None and peer is not None and truth.best is not None:
                score = truth.score(peer)
                self.counters["id_checks"] += 1
                self.counters["id_wrong"] += int(score == 0.0)
                self.counters["id_ambiguous"] += int(truth.ambiguous)
                diag.id_rows.append(dict(t_s=t, camera=name, track_id=tr.track_id, decoded_id=peer, truth_id=truth.best,
                                         id_correct=score, id_ambiguous=float(truth.ambiguous), id_confidence=tr.id_confidence))
            chip = tr.decoder.chip_at(fi) if by_chip is not None else None
            off_n = c_off if chip is None else R_nb @ (lever_b - by_chip[chip])
            bearing = Bearing(t, undistort_normalized(cam, [det.centre_px])[0], R_nc, off_n, focal, att_sigma)
            if peer is None and self.params.predicted_association:
                peer = self.assoc.predicted_peer(self.filters, bearing, claimed | decoded)
                if peer is not None:
                    self.counters["predicted_assoc"] += 1
            if peer is None or peer in claimed:
                continue
            claimed.add(peer)
            bearing, det_fed = self._on_part(peer, bearing, det, cam)
            if det_fed is not det and truths:
                truth = id_truth(det_fed, truths, self._centre_reference, self._id_tie_px)  # the part's
            if tr.id_index is not None:
                self.id_conf[peer] = tr.id_confidence
            self._fuse(peer, tr, bearing, truth, cam, mount, R_nb, est)
        self.book.drop_stale(t)
        if t + 1e-9 >= self._next_log_t:
            self._next_log_t = t + 1.0 / self.params.log_rate_hz
            diag.table = self.controller_input(t)
            nan2 = (float("nan"), float("nan"))
            diag.id_correct = {p: self.bearing_id_ok.get(p, nan2)[0] for p in diag.table}
            diag.id_ambiguous = {p: self.bearing_id_ok.get(p, nan2)[1] for p in diag.table}
        return diag

    def _on_part(self, peer: str, bearing: Bearing, det: Detection, cam: Any) -> tuple[Bearing, Detection]:
        """(bearing, detection) of `peer` from one track's detection `det` and its bearing.

        A detection of several vehicles merged (det.parts_px) is centred between them, a few
        pixels off each: the peer's settled estimate takes the bearing of the part it predicts
        (association.nearest_part), and the detection is re-centred there (for its ID score).
        Otherwise both are returned as they are. Only with the LED detector's anchor_split
        "parts" (off in the shipped scenarios: no better, detectors.LedDetector). Tried and
        not kept besides: feeding the other parts, too, to the estimates their own bearings
        gate (predicted association by part); paper_swarm_relnav, LED, 120 s (2026-11-26):
        relnav mean 0.179 -> 0.183 m, max 4.5 -> 8.9 m, filter resets 6 -> 47."""
        if len(det.parts_px) < 2 or peer not in self.filters:
            return bearing, det
        parts_m = undistort_normalized(cam, det.parts_px)
        k = self.assoc.nearest_part(self.filters[peer], bearing, parts_m)
        if k is None:
            return bearing, det
        self.counters["bearings_from_part"] += 1
        u, v = (float(x) for x in det.parts_px[k])
        return replace(bearing, m_xy=parts_m[k]), replace(det, centre_px=(u, v))

    def _fuse(self, peer: str, tr: Any, bearing: Bearing, truth: Any, cam: Any, mount: Any, R_nb: np.ndarray,
              est: NavEstimate) -> None:
        """Fuse `bearing` (of camera track tr) into peer's estimate, starting or restarting it
        where the book allows, unless another estimate claims it (association.ambiguity);
        truth: the frame's IdTruth of the detection it came from (scoring only)."""
        f = self.book.filter_for_bearing(peer, tr, bearing, cam, mount, R_nb, est)
        if f is None:
            return
        why = self.assoc.ambiguity(peer, self.filters, bearing) if self.params.skip_ambiguous else None
        if why is not None:
            self.counters[f"bearings_{why}"] += 1
            return
        _, ok = f.update_bearing(bearing.t_s, bearing.m_xy, bearing.R_nc, bearing.cam_offset_ned_m, bearing.focal_px,
                                 bearing.att_sigma_rad, est.vel_ned_mps)
        self.counters["bearings_used"] += int(ok)
        if ok:
            # Unknown (nan) when the frame has no truth or the detection lies on no vehicle:
            # a score left over from an earlier bearing would speak for this one.
            self.bearing_id_ok[peer] = ((truth.score(peer), float(truth.ambiguous))
                                        if truth is not None and truth.best is not None else (float("nan"), float("nan")))

    def _plausible_size(self, dets: list, cam: Any, t: float) -> list:
        """The detections whose box could be a neighbour's at the shortest UWB range of the last
        report_max_age_s (box_size.py; target_extent_m); all of them without such a range."""
        extent = self.params.target_extent_m
        nearest_m = self.book.nearest_range_m(t, self.params.report_max_age_s) if extent is not None and dets else None
        if nearest_m is None:
            return dets
        keep = small_enough(dets, cam, nearest_m, extent, self.params.box_size_factor, self.params.box_slack_px)
        self.counters["detections_oversize"] += len(dets) - len(keep)
        return keep

    def _with_led_level(self, det, part) -> "Detection":
        """The detection with led_level read by the LED reader inside its box (+3 px)."""
        u0, v0, u1, v1 = det.bbox_px
        ou, ov = part.origin_uv
        h, w = part.image.shape[:2]
        a0, b0 = max(int(u0) - 3 - ou, 0), max(int(v0) - 3 - ov, 0)
        a1, b1 = min(int(np.ceil(u1)) + 4 - ou, w), min(int(np.ceil(v1)) + 4 - ov, h)
        if a1 <= a0 or b1 <= b0:
            return det
        found = self.led_reader.detect(part.image[b0:b1, a0:a1])
        if not found:
            return det
        return replace(det, led_level=float(sum(d.led_level for d in found)))

    def _attitude_at(self, t: float) -> np.ndarray | None:
        """Own attitude R_nb (3, 3) at t: the latest estimate carried by its body rate."""
        est = self.last_estimate
        if est is None:
            return None
        R_nb = quat_to_dcm(est.q_nb_wxyz)
        dt = t - float(est.t_s)
        if 0.0 < dt < 0.5:
            R_nb = R_nb @ quat_to_dcm(rotvec_to_quat(np.asarray(est.omega_b_rps, float) * dt))
        return R_nb

    def _track_rois(self, name: str, t: float) -> list:
        """Merged regions of camera `name` at t around its predicted tracks and the projected
        neighbour estimates (regions.rois_around_tracks)."""
        cam, mount = self.cams[name]
        rp = self.params.roi
        return rois_around_tracks(self.trackers[name].tracks, self.filters.values(), cam, mount, self._attitude_at(t), t,
                                  rp.margin_px, rp.margin_per_miss_px, rp.min_size_px)

    # -- for the engine and the controller -------------------------------------------------

    def render_requests(self, t_s: float) -> dict[str, list[tuple[int, int, int, int]]]:
        """Regions each camera should render at t_s (full-frame pixels, u1/v1 exclusive):
        the whole frame [(0, 0, W, H)] on full-frame ticks (every roi.full_frame_every frames),
        else the merged regions around predicted tracks and projected neighbour estimates (may
        be empty: nothing to render; new vehicles are found on the next full frame). Cameras
        without a frame at t_s are left out."""
        out = {}
        for name, (cam, _) in self.cams.items():
            n = t_s * self.cam_rate[name]
            if abs(n - round(n)) > 1e-6:
                continue  # not a frame of this camera (the engine asks at every sensor tick)
            # Full frames are staggered over cameras (a fixed phase per camera), so that the
            # expensive searches do not all fall on the same tick.
            n_cam = int(round(n)) + self._phase[name]
            rp = self.params.roi
            rois = None if (not rp.enabled or n_cam % rp.full_frame_every == 0) else self._track_rois(name, t_s)
            if rois is not None and not rois and n_cam % rp.search_every == 0:
                rois = None  # nothing expected in view: search the whole frame now and then
            out[name] = [(0, 0, cam.width_px, cam.height_px)] if rois is None else rois
        return out

    def controller_input(self, t_s: float | None = None) -> NeighbourTable:
        """Current NeighbourTable (neighbours observed in bearing and range within
        report_max_age_s), each estimate extrapolated (constant relative velocity) to t_s
        (default: the latest measurement time)."""
        t = self.t_s if t_s is None else float(t_s)
        table: NeighbourTable = {}
        for peer, f in self.filters.items():
            if t - min(f.last_bearing_t_s, f.last_range_t_s) > self.params.report_max_age_s:
                continue  # not observed in both bearing and range lately (see report_max_age_s)
            dt = max(t - f.t_s, 0.0)
            F = constant_velocity_F(dt)
            x = F @ f.x
            P = F @ f.P @ F.T
            table[peer] = RelativeEstimate(t, peer, x[:3].copy(), x[3:].copy(), P[:3, :3].copy(), P[3:, 3:].copy(),
                                           self.id_conf.get(peer, float("nan")), f.last_bearing_t_s, f.last_range_t_s)
        return table

    def all_counters(self) -> dict[str, int]:
        """Aid, tracker (summed over cameras) and filter (summed over neighbours) counters."""
        out = dict(self.counters)
        for tr in self.trackers.values():
            for k, v in tr.counters.items():
                out[f"tracks_{k}"] = out.get(f"tracks_{k}", 0) + v
        for f in self.filters.values():
            for k, v in f.counters.items():
                out[k] = out.get(k, 0) + v
        return out
