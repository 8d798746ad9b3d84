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

from testbench.core import led_code
from testbench.core.errors import InputError
from testbench.core.interfaces import BuildContext, NavigationAid
from testbench.core.messages import NavEstimate, UwbRange
from testbench.core.registry import build, register
from testbench.core.rotations import quat_to_dcm, rotvec_to_quat
from testbench.navigation.relative.association import AssociationRules, Bearing
from testbench.navigation.relative.book import NeighbourBook, StartRules
from testbench.navigation.relative.box_size import small_enough
from testbench.navigation.relative.detectors import LedDetector
from testbench.navigation.relative.diagnostics import RelnavDiagnostics, id_truth
from testbench.navigation.relative.frames import camera_model, frame_camera_name, frame_parts, is_camera_frame
from testbench.navigation.relative.geometry import undistort_normalized
from testbench.navigation.relative.neighbour_filter import FilterSettings, constant_velocity_F
from testbench.navigation.relative.regions import detect_regions, rois_around_tracks
from testbench.navigation.relative.settings import RelnavParams
from testbench.navigation.relative.tracking import Tracker, TrackerSettings
from testbench.navigation.relative.types import Detection, NeighbourTable, RelativeEstimate


@register("aid", "relnav")
class RelnavAid(NavigationAid):
    """Relative navigation of one vehicle (see the module docstring); its settings are
    RelnavParams (settings.py), which says what each one means and why it is set as it is."""

    Params = RelnavParams

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
        offsets = [params.target_offset_b_m, *(params.target_offset_by_chip_b_m or ()),
                   *((params.target_offset_data_b_m,) if params.target_offset_data_b_m is not None else ())]
        self._target_b_m = np.asarray(params.target_offset_b_m, float)
        self._target_by_chip_b_m = (None if params.target_offset_by_chip_b_m is None
                                    else np.asarray(params.target_offset_by_chip_b_m, float))  # (2, 3)
        self._target_data_b_m = np.asarray(params.target_offset_data_b_m if params.target_offset_data_b_m is not None
                                           else params.target_offset_b_m, float)
        self._resolve_mixtures = params.tracker.mixture_action in ("resolve", "resolve_or_decoded")
        self._unresolved_as_decoded = params.tracker.mixture_action == "resolve_or_decoded"
        self._centre_reference = getattr(self.detector, "centre_reference", "vehicle_centre")
        if self._centre_reference == "vehicle_centre" and np.any(np.asarray(offsets, float)):
            # (A leftover LED offset with a CG detector biases every bearing: the oracle runs
            # of the swarm benchmark carried the LED's 0.13 m, swarm_cnn likewise.)
            raise InputError(f"relnav.target_offset_b_m / target_offset_by_chip_b_m / target_offset_data_b_m: detector {params.detector.type!r} "
                             f"reports the vehicle's centre, so the target offsets must be zero (got {offsets})")
        if params.target_extent_m is not None and not getattr(self.detector, "box_shows_extent", True):
            raise InputError(f"relnav.target_extent_m: detector {params.detector.type!r} reports boxes of the LEDs' glow, "
                             f"not of the vehicle, so their size says nothing of the range: leave target_extent_m unset")
        # Detectors that give boxes only (the CNN) get their LED level read inside each box.
        self.led_reader = LedDetector(LedDetector.Params(**params.led_reader))
        # Every relnav.tracker key is a TrackerSettings field of the same name.
        ts = TrackerSettings(**params.tracker.model_dump())
        self.trackers = {n: Tracker(len(self.ids), self.own_index, ts) for n in params.cameras}
        self.fset = FilterSettings(**params.filter.model_dump())
        self.assoc = AssociationRules(self.fset.bearing_sigma_px, params.assoc_max_sigma_m, params.report_max_age_s,
                                      params.occlusion_margin_m, params.restart_max_jump_m, params.forgotten_speed_mps,
                                      self.fset.bearing_sigma_model)
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
                         "detections_oversize": 0, "mixture_bearings": 0, "mixture_frames_unresolved": 0,
                         "mixture_frames_unconfirmed": 0}
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
        decoded = self._decoded_in_view()
        for tr in sorted((x for x in updated if x.confirmed), key=lambda x: -x.id_confidence):
            det = tr.last_detection
            if self._resolve_mixtures and tr.mixture is not None and self._resolved(
                    tr, det, fi, truths, cam, R_nb, R_nc, lever_b, focal, att_sigma, est, claimed, diag, name):
                continue
            peer = self.ids[tr.id_index] if tr.id_index is not None else None
            truth = id_truth(det, truths, self._centre_reference, self._id_tie_px) if truths else None  # scoring only, never fused
            if peer is not None:
                self._score_claim(diag, name, tr.track_id, peer, truth, tr.id_confidence)
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

    def _resolved(self, tr: Any, det: Any, fi: int, truths: list, cam: Any, R_nb: np.ndarray, R_nc: np.ndarray,
                  lever_b: np.ndarray, focal: float, att_sigma: float, est: NavEstimate, claimed: set,
                  diag: RelnavDiagnostics, name: str) -> bool:
        """Whether a frame of a track whose blob merges two vehicles j, k (Track.mixture,
        tracker mixture_action "resolve" or "resolve_or_decoded") was dealt with here. In LED
        frame fi the code lights the data LEDs of one of them only, of both, or of neither.
        Where it lights one, the blob's data-LED pixels are that vehicle's alone, so their
        centroid (Detection.data_centre_px, with target_offset_data_b_m) is its bearing: fused
        into its running estimate when that estimate's gate takes it, and then scored as an ID
        claim of it (no estimate is started from it). A frame whose chips agree gives nothing
        with "resolve"; with "resolve_or_decoded" it is returned to the caller (False), which
        treats the track as any other: its decoded ID, if any, claims the blob.

        Why: on the arrowhead's lattice lines two vehicles 100 m apart stand 3-8 px from each
        other and their LEDs join one blob, whose blink decodes as the brighter while its centre
        lies between them. docs/measurements.md ("Chip-resolved bearings of merged blobs")."""
        j, k = tr.mixture
        chips = tr.decoder.book[:, fi % led_code.CODE_LENGTH]
        if chips[j] == chips[k] or det.data_centre_px is None:
            self.counters["mixture_frames_unresolved"] += 1
            return not self._unresolved_as_decoded
        peer = self.ids[j if chips[j] else k]
        det = replace(det, centre_px=det.data_centre_px)
        off_n = R_nb @ (lever_b - self._target_data_b_m)
        bearing = Bearing(diag.t_s, undistort_normalized(cam, [det.centre_px])[0], R_nc, off_n, focal, att_sigma)
        f = self.filters.get(peer)
        if f is None or peer in claimed or not self.assoc.gates(f, bearing):
            # The pair's fit is a model of two blinks: a blob of three vehicles on one line
            # fits a wrong pair, whose chip then names a vehicle elsewhere in the image. (Starting
            # an estimate from such a bearing, as an identified track would, was tried: relnav
            # mean 0.166 / 0.182 -> 0.183 / 0.200 m, seeds 1 / 2, the formation no better.)
            self.counters["mixture_frames_unconfirmed"] += 1
            return True
        claimed.add(peer)
        truth = id_truth(det, truths, self._centre_reference, self._id_tie_px) if truths else None  # scoring only
        self._score_claim(diag, name, tr.track_id, peer, truth, float("nan"))
        self.counters["mixture_bearings"] += 1
        # No ambiguity test: the other vehicle of the blob stands a few pixels away, inside the
        # gate of its estimate, and the chips already say whose LEDs these are.
        self._update_with(peer, f, bearing, truth, est, check_ambiguity=False)
        return True

    def _score_claim(self, diag: RelnavDiagnostics, camera: str, track_id: int, peer: str, truth: Any,
                     confidence: float) -> None:
        """Score a track's claim that its detection is `peer` against the frame's IdTruth
        (scoring only: counters and a row of table relnav_id; nothing when undecidable)."""
        if truth is None or truth.best is None:
            return
        score = truth.score(peer)
        self.counters["id_checks"] += 1
        self.counters["id_wrong"] += int(score == 0.0)
        self.counters["id_ambiguous"] += int(truth.ambiguous)
        diag.id_rows.append(dict(t_s=diag.t_s, camera=camera, track_id=track_id, decoded_id=peer, truth_id=truth.best,
                                 id_correct=score, id_ambiguous=float(truth.ambiguous), id_confidence=confidence))

    def _decoded_in_view(self) -> set[str]:
        """The neighbours that a confirmed track of some camera carries as its decoded ID (and,
        unless params.coasting_tracks_keep_ids, saw in its latest frame: no miss since):
        predicted association never feeds them.

        Why excluded: the ID is the stronger evidence, and an estimate that lost its neighbour
        (it rejects that track's bearings) would be held on the wrong vehicle by the
        unidentified tracks it still gates, never reaching its reset (17 m in a 15 s run).
        Why, where asked, only tracks that saw their vehicle: when two vehicles come onto one
        line of sight their blobs merge into one detection, which often starts a new track (its
        blink is both codes at once, so it never decodes) while the two decoded tracks coast on
        without detections for max_misses frames. Excluded by those coasting tracks, neither
        estimate took the merged blob's bearings, and by the time the tracks died both were too
        wide to be fed by predicted association (settled): swarm_fixedwing with airspeed
        aiding, LED, 300 s, lost uav3 for good at 111 s that way (uav1 and uav0 1.2 deg
        apart). The paper arrowhead keeps the coasting tracks' exclusion (settings.py)."""
        coasting_too = self.params.coasting_tracks_keep_ids
        return {self.ids[x.id_index] for trk in self.trackers.values() for x in trk.tracks
                if x.confirmed and x.id_index is not None and (coasting_too or x.misses == 0)}

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
        if f is not None:
            self._update_with(peer, f, bearing, truth, est)

    def _update_with(self, peer: str, f: Any, bearing: Bearing, truth: Any, est: NavEstimate,
                     check_ambiguity: bool = True) -> None:
        """Fuse `bearing` into peer's running estimate f, unless (check_ambiguity) another
        estimate claims it (association.ambiguity); truth as in _fuse."""
        why = self.assoc.ambiguity(peer, self.filters, bearing) if self.params.skip_ambiguous and check_ambiguity else None
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
