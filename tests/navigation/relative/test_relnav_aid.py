"""The relnav aid end to end on rendered frames: LED detector, region rendering from the aid's
render_requests, tracking, LED IDs, bearing + UWB fusion; and with the oracle detector."""

import numpy as np
import pytest

from testbench.core import registry
from testbench.navigation.relative.association import Bearing
from testbench.navigation.relative.bench import simulate_relnav

OFFSETS = [(40.0, 10.0, 0.0), (0.0, 50.0, -3.0), (5.0, -45.0, 2.0)]


@pytest.mark.slow
def test_led_pipeline_finds_identifies_and_locates_neighbours():
    res = simulate_relnav(OFFSETS, duration_s=4.0, width_px=960, height_px=540, seed=2, nlos_every=2)  # half the ranges NLOS
    e = np.asarray(res.errors_m)
    assert np.isfinite(e).all()  # every neighbour estimated after 2 s
    assert e.max() < 0.5 and e.mean() < 0.25
    c = res.counters
    assert c["id_checks"] > 50 and c["id_wrong"] == 0
    assert c["range_rejected"] >= 1  # NLOS outliers gated
    assert sorted(res.table) == ["n0", "n1", "n2"]
    assert all(est.id_confidence > 0.99 for est in res.table.values())
    # Regions around tracks between full frames: far fewer pixels than full frames.
    assert np.mean(res.render_px) < 0.4 * 960 * 540


def test_oracle_pipeline_and_registration():
    assert {"led", "oracle"} <= set(registry.available("detector"))
    assert "relnav" in registry.available("aid")
    det = {"type": "oracle", "params": {"sigma_px": 0.3, "miss_probability": 0.1}}
    res = simulate_relnav(OFFSETS[:2], duration_s=3.0, width_px=640, height_px=360, detector=det, cameras=("front", "right"))
    e = np.asarray(res.errors_m)
    assert np.isfinite(e).all() and e.max() < 0.6
    assert res.counters["id_wrong"] == 0


class _BoxOnly:
    """A detector that reports boxes without LED information (as the CNN does)."""

    def __init__(self, inner):
        self.inner = inner

    def detect(self, image):
        from dataclasses import replace

        return [replace(d, led_level=None, led_px=np.zeros((0, 2))) for d in self.inner.detect(image)]


@pytest.mark.slow
def test_box_only_detector_gets_led_levels_read_in_its_boxes(monkeypatch):
    from testbench.navigation.relative import aid as aid_mod
    from testbench.navigation.relative.detectors import LedDetector

    orig = aid_mod.RelnavAid.__init__

    def init(self, *a, **k):
        orig(self, *a, **k)
        self.detector = _BoxOnly(LedDetector(LedDetector.Params(data_hue_deg=0.0)))

    monkeypatch.setattr(aid_mod.RelnavAid, "__init__", init)
    res = simulate_relnav(OFFSETS[:2], duration_s=3.5, width_px=960, height_px=540, cameras=("front", "right"),
                          aid_params={"led_reader": {"data_hue_deg": 0.0}})
    assert sorted(res.table) == ["n0", "n1"] and res.counters["id_wrong"] == 0


def test_a_neighbour_held_by_ranges_alone_is_forgotten():
    """Ranges keep only the distance: a neighbour without a bearing for stale_after_s is
    dropped even while its ranges keep arriving (its direction is no longer known), and the next
    identified track restarts it."""
    from testbench.core.interfaces import BuildContext
    from testbench.core.messages import UwbRange
    from testbench.navigation.relative.aid import RelnavAid
    from testbench.navigation.relative.bench import ORIGIN, _Camera, _Uwb, _estimate
    from testbench.navigation.relative.neighbour_filter import NeighbourFilter
    from testbench.core.camera_geometry import CameraMount, PinholeCamera, mount_rotation

    cam = PinholeCamera.from_hfov(640, 360, 120.0)
    sensors = {"front": _Camera(cam, CameraMount(mount_rotation(0.0, 0.0, 0.0), np.zeros(3))), "uwb": _Uwb()}
    aid = RelnavAid(RelnavAid.Params(cameras=["front"], detector={"type": "oracle"}, stale_after_s=5.0),
                    ctx=BuildContext("self", ("self", "n0"), ORIGIN), sensors=sensors, rng=np.random.default_rng(0))
    f = NeighbourFilter(0.0, [50.0, 0.0, 0.0], np.eye(3))
    f.last_bearing_t_s = 0.0
    aid.filters["n0"] = f
    est = _estimate(0.0, np.zeros(3), np.random.default_rng(0), 0.0)
    for k in range(1, 61):  # 6 s of ranges, no bearing
        aid.process(UwbRange(0.1 * k, "n0", 50.0, -80.0), est)
    aid.book.drop_stale(6.0)
    assert "n0" not in aid.filters


def test_id_truth_merged_blob_is_undecidable_and_apart_vehicles_are_decided():
    """Two neighbours on one line of sight, their expected points within the tie distance of
    the detection: either ID is undecidable (nan, ambiguous); a vehicle 20 px away is decided
    (right 1.0, the other 0.0), and a third vehicle not imaged is wrong (0.0) even in a tie."""
    from testbench.navigation.relative.diagnostics import id_truth
    from testbench.navigation.relative.types import Detection
    from testbench.sensors.camera.types import VehicleTruth

    def truth(name, u, v, half, rng_m):
        return VehicleTruth(name, (u - half, v - half, u + half, v + half), np.array([u, v]), np.zeros((1, 2)),
                            (True,), (True,), True, rng_m)

    near, far = truth("near", 500.0, 300.0, 2.0, 100.0), truth("far", 500.6, 300.4, 1.0, 200.0)
    merged = id_truth(Detection((499.0, 299.0, 502.0, 302.0), (500.5, 300.3), 1.0), [far, near], tie_px=2.0)
    assert merged.ambiguous and merged.alike == {"near", "far"}
    assert np.isnan(merged.score("near")) and np.isnan(merged.score("far")) and merged.score("other") == 0.0
    apart = truth("far", 520.0, 300.0, 1.0, 200.0)
    one = id_truth(Detection((519, 299, 521, 301), (520.2, 300.1), 1.0), [near, apart], tie_px=2.0)
    assert one.best == "far" and not one.ambiguous and one.score("far") == 1.0 and one.score("near") == 0.0
    assert np.isnan(id_truth(Detection((0, 0, 2, 2), (1.0, 1.0), 1.0), [near, apart]).score("near"))  # no truth near


def test_id_truth_measures_an_led_detection_from_the_lit_leds():
    """An LED detector's centre is the centroid of the lit LEDs, not the vehicle's centre: a
    near quad whose lit anchor is 3 px above its centre owns a blob at the anchor, though a far
    quad's centre (behind it, 2.5 px below the anchor) is nearer to it than the near centre."""
    from testbench.navigation.relative.diagnostics import id_truth
    from testbench.navigation.relative.types import Detection
    from testbench.sensors.camera.types import VehicleTruth

    leds_near = np.array([[500.0, 297.0], [498.0, 300.0]])  # anchor lit, another LED dark
    near = VehicleTruth("near", (497.0, 296.0, 503.0, 301.0), np.array([500.0, 300.0]), leds_near,
                        (True, False), (True, True), True, 60.0)
    far = VehicleTruth("far", (499.0, 299.0, 501.0, 300.0), np.array([500.0, 299.5]), np.array([[500.0, 299.3]]),
                       (False,), (True,), True, 200.0)
    det = Detection((499.0, 296.0, 501.0, 298.0), (500.0, 297.1), 1.0)
    led = id_truth(det, [near, far], reference="led_centroid", tie_px=2.0)
    assert led.best == "near" and not led.ambiguous
    assert id_truth(det, [near, far], reference="vehicle_centre", tie_px=2.0).best == "far"


def _aid_with_filters(offsets):
    """A relnav aid (front camera, 1920 px, 120 deg) holding settled estimates of neighbours
    at the given NED offsets (m), the observer level and heading north."""
    from testbench.core.camera_geometry import CameraMount, PinholeCamera, mount_rotation
    from testbench.core.interfaces import BuildContext
    from testbench.navigation.relative.aid import RelnavAid
    from testbench.navigation.relative.bench import ORIGIN, _Camera, _Uwb
    from testbench.navigation.relative.neighbour_filter import NeighbourFilter

    cam = PinholeCamera.from_hfov(1920, 1080, 120.0)
    mount = CameraMount(mount_rotation(0.0, 0.0, 0.0), np.zeros(3))
    ids = ("self",) + tuple(offsets)
    aid = RelnavAid(RelnavAid.Params(cameras=["front"]), ctx=BuildContext("self", ids, ORIGIN, physics_rate_hz=100.0),
                    sensors={"front": _Camera(cam, mount), "uwb": _Uwb()})
    for name, off in offsets.items():
        f = NeighbourFilter(1.0, off, np.eye(3) * 0.04)
        f.counters["bearing_accepted"] = 20
        f.last_bearing_t_s = 1.0
        aid.filters[name] = f
    return aid, mount.R_bc, cam.fx


def _m(off):
    d = np.asarray(off, float)  # camera frame of a level camera looking north: x east, y down, z north
    return np.array([d[1] / d[0], d[2] / d[0]])


def test_a_bearing_a_nearer_neighbour_claims_is_left_to_it():
    """Three neighbours on one line of sight (the arrowhead's lattice): a blob identified as the
    far one is where the near one's estimate predicts a bearing, so it is not fused as the far
    one's; the near one's own bearing is fused; a neighbour off that line is unaffected."""
    offs = {"near": (100.0, 0.0, 0.0), "far": (200.0, 0.4, 0.0), "side": (100.0, 60.0, 0.0)}
    aid, R_nc, f_px = _aid_with_filters(offs)
    on_near = Bearing(1.05, _m(offs["near"]), R_nc, np.zeros(3), f_px, 0.0)
    assert aid.assoc.ambiguity("far", aid.filters, on_near) == "occluded"
    assert aid.assoc.ambiguity("near", aid.filters, on_near) is None
    on_side = Bearing(1.05, _m(offs["side"]), R_nc, np.zeros(3), f_px, 0.0)
    assert aid.assoc.ambiguity("side", aid.filters, on_side) is None


def test_a_bearing_another_neighbour_predicts_better_is_not_fused():
    """Two neighbours at the same range 3 m apart: a track still carrying A's ID that now sits on
    B's line of sight (its blob parted with the other vehicle) is B's, not A's."""
    offs = {"a": (100.0, 0.0, 0.0), "b": (100.0, 3.0, 0.0)}
    aid, R_nc, f_px = _aid_with_filters(offs)
    aid.filters["a"].P[:3, :3] = np.eye(3) * 4.0  # A's estimate wide enough to gate B's bearing
    on_b = Bearing(1.05, _m(offs["b"]), R_nc, np.zeros(3), f_px, 0.0)
    assert aid.assoc.ambiguity("a", aid.filters, on_b) == "closer_to_other"
    assert aid.assoc.ambiguity("b", aid.filters, on_b) is None
    # An undecoded track on B's line of sight is fed to B by predicted association (A's wide
    # estimate is not settled), unless B is excluded (claimed, or decoded on another track).
    assert aid.assoc.predicted_peer(aid.filters, on_b, set()) == "b"
    assert aid.assoc.predicted_peer(aid.filters, on_b, {"b"}) is None


def test_only_a_decoded_track_that_saw_its_vehicle_keeps_it_from_predicted_association():
    """Two neighbours come onto one line of sight: their decoded tracks coast without
    detections while the merged blob starts an undecoded track. With coasting_tracks_keep_ids
    off, the coasting tracks do not keep the estimates from that blob's bearings (predicted
    association), where they would both starve."""
    from testbench.navigation.relative.tracking import Track

    aid, _, _ = _aid_with_filters({"near": (100.0, 0.0, 0.0), "far": (200.0, 0.4, 0.0)})
    seen = Track(1, None, 1.0, None, confirmed=True, id_index=aid.ids.index("near"))
    coasting = Track(2, None, 1.0, None, misses=1, confirmed=True, id_index=aid.ids.index("far"))
    aid.trackers["front"].tracks = [seen, coasting]
    assert aid._decoded_in_view() == {"near", "far"}  # the default (the paper arrowhead's)
    aid.params = aid.params.model_copy(update={"coasting_tracks_keep_ids": False})
    assert aid._decoded_in_view() == {"near"}
    seen.misses = 1
    assert aid._decoded_in_view() == set()


def test_a_merged_detection_gives_the_bearing_of_the_part_the_estimate_predicts():
    """Two neighbours on nearly one line of sight, 100 and 200 m out, 1.5 m apart across it
    (the far one 7 px beside the near one): of a detection holding both, each estimate takes
    the part at its own vehicle; an estimate not yet settled takes none."""
    offs = {"near": (100.0, 0.0, 0.0), "far": (200.0, 1.5, 0.0)}
    aid, R_nc, f_px = _aid_with_filters(offs)
    parts = np.array([_m(offs["far"]), _m(offs["near"])]) + 0.2 / f_px  # a fifth of a pixel off
    merged = Bearing(1.05, parts.mean(axis=0), R_nc, np.zeros(3), f_px, 0.0)
    assert aid.assoc.nearest_part(aid.filters["near"], merged, parts) == 1
    assert aid.assoc.nearest_part(aid.filters["far"], merged, parts) == 0
    aid.filters["far"].counters["bearing_accepted"] = 3
    assert aid.assoc.nearest_part(aid.filters["far"], merged, parts) is None


def test_the_bearing_of_a_merged_detection_is_the_part_the_estimate_predicts():
    """A detection of two neighbours merged (near at 100 m, far 11 px beside it): the near
    one's bearing and detection centre move to its part, the far one's to the other; a
    neighbour without an estimate, or a detection of one vehicle, keeps the centre."""
    from testbench.navigation.relative.types import Detection

    offs = {"near": (100.0, 0.0, 0.0), "far": (200.0, 4.0, 0.0)}
    aid, R_nc, f_px = _aid_with_filters(offs)
    cam = aid.cams["front"][0]
    parts_m = np.array([_m(offs["far"]), _m(offs["near"])])
    parts_px = np.column_stack([cam.cx + cam.fx * parts_m[:, 0], cam.cy + cam.fy * parts_m[:, 1]])
    centre = tuple(parts_px.mean(axis=0))
    det = Detection((centre[0] - 9, centre[1] - 3, centre[0] + 9, centre[1] + 3), centre, 1.0, parts_px=parts_px)
    merged = Bearing(1.05, parts_m.mean(axis=0), R_nc, np.zeros(3), f_px, 0.0)
    for peer, k in (("far", 0), ("near", 1)):
        b, d = aid._on_part(peer, merged, det, cam)
        assert b.m_xy == pytest.approx(parts_m[k], abs=1e-9) and d.centre_px == pytest.approx(tuple(parts_px[k]))
    assert aid._on_part("other", merged, det, cam) == (merged, det)
    single = Detection(det.bbox_px, centre, 1.0)
    assert aid._on_part("near", merged, single, cam) == (merged, single)


def test_a_merged_blob_gives_a_bearing_to_the_vehicle_whose_data_leds_alone_are_lit():
    """A track on the blob of two neighbours on nearly one line of sight (near at 100 m, far
    at 200 m, 7 px apart), its levels a mixture of their blinks (Track.mixture): in an LED
    frame whose code lights only the far one's data LEDs, the blob's data-LED centroid is the
    far one's bearing, fused into its estimate (past the near one's gate, which the ambiguity
    test would refuse it for) and claimed as its ID; where the code lights both, or the
    centroid lies where the named vehicle's estimate does not put it (a blob of three vehicles
    fits a wrong pair), nothing is fused or claimed."""
    from dataclasses import replace

    from testbench.core import led_code
    from testbench.navigation.relative.diagnostics import RelnavDiagnostics
    from testbench.navigation.relative.idcode import IdDecoder
    from testbench.navigation.relative.tracking import Track
    from testbench.navigation.relative.types import Detection

    offs = {"near": (100.0, 0.0, 0.0), "far": (200.0, 1.5, 0.0)}
    aid, R_nc, f_px = _aid_with_filters(offs)
    cam, _ = aid.cams["front"]
    j, k = aid.ids.index("near"), aid.ids.index("far")
    px = {n: (cam.cx + cam.fx * _m(o)[0], cam.cy + cam.fy * _m(o)[1]) for n, o in offs.items()}
    centre = tuple(np.mean([px["near"], px["far"]], axis=0))

    def frame_with(chips):
        return next(fi for fi in range(led_code.CODE_LENGTH) if (led_code.chip(j, fi), led_code.chip(k, fi)) == chips)

    def resolve(fi, data_px):
        det = Detection((centre[0] - 6, centre[1] - 3, centre[0] + 6, centre[1] + 3), centre, 1.0, data_centre_px=data_px)
        track = Track(1, None, 1.0, IdDecoder(len(aid.ids)), confirmed=True, id_index=j, mixture=(j, k))
        claimed, diag = set(), RelnavDiagnostics(1.05)
        before = {n: f.counters["bearing_accepted"] for n, f in aid.filters.items()}
        aid._resolved(track, det, fi, [], cam, np.eye(3), R_nc, np.zeros(3), f_px, 0.0, _level_estimate(), claimed, diag, "front")
        return claimed, {n: f.counters["bearing_accepted"] - before[n] for n, f in aid.filters.items()}

    claimed, fused = resolve(frame_with((0, 1)), px["far"])
    assert claimed == {"far"} and fused == {"near": 0, "far": 1}
    assert aid.assoc.ambiguity("far", aid.filters, Bearing(1.05, _m(offs["far"]), R_nc, np.zeros(3), f_px, 0.0)) is not None
    claimed, fused = resolve(frame_with((1, 0)), px["near"])
    assert claimed == {"near"} and fused == {"near": 1, "far": 0}
    claimed, fused = resolve(frame_with((1, 1)), centre)  # both lit: the centroid is neither's
    assert claimed == set() and fused == {"near": 0, "far": 0}
    elsewhere = (px["near"][0] + 30.0, px["near"][1])  # a wrong pair's chips name a vehicle 30 px away
    claimed, fused = resolve(frame_with((1, 0)), elsewhere)
    assert claimed == set() and fused == {"near": 0, "far": 0}
    assert aid.counters["mixture_bearings"] == 2 and aid.counters["mixture_frames_unresolved"] == 1
    assert aid.counters["mixture_frames_unconfirmed"] == 1
    # "resolve_or_decoded": a frame the chips cannot attribute goes back to the caller, whose
    # decoded-ID path then claims the blob; an attributed one is dealt with here either way.
    track = Track(1, None, 1.0, IdDecoder(len(aid.ids)), confirmed=True, id_index=j, mixture=(j, k))
    det = Detection((centre[0] - 6, centre[1] - 3, centre[0] + 6, centre[1] + 3), centre, 1.0, data_centre_px=centre)
    args = ([], cam, np.eye(3), R_nc, np.zeros(3), f_px, 0.0, _level_estimate(), set(), RelnavDiagnostics(1.1), "front")
    assert aid._resolved(track, det, frame_with((1, 1)), *args) is True
    aid._unresolved_as_decoded = True
    assert aid._resolved(track, det, frame_with((1, 1)), *args) is False
    assert aid._resolved(track, replace(det, data_centre_px=px["far"]), frame_with((0, 1)), *args) is True


def _level_estimate():
    """The observer's own estimate at rest at the origin, level, heading north."""
    from testbench.core.messages import NavEstimate

    z3 = np.zeros((3, 3))
    return NavEstimate(1.05, np.zeros(3), np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3), np.zeros(3),
                       z3, z3, z3)


def test_a_restart_further_than_the_neighbour_can_have_moved_is_refused():
    """Bearings rejected while ranges agree restart an estimate only near its prediction: a
    track wearing a wrong ID (another vehicle, 200 m away on the other side) must not move it."""
    from testbench.navigation.relative.neighbour_filter import NeighbourFilter

    aid, _, _ = _aid_with_filters({"n": (100.0, 0.0, 0.0)})
    old = aid.filters["n"]
    near = NeighbourFilter(2.0, (100.0, 20.0, 0.0), np.eye(3))  # 20 m off: a lost estimate's restart
    far = NeighbourFilter(2.0, (-100.0, 0.0, 0.0), np.eye(3))  # 200 m off: another vehicle
    assert aid.assoc.within_reach(old, near, 2.0)
    assert not aid.assoc.within_reach(old, far, 2.0)
    wide = NeighbourFilter(1.0, (100.0, 0.0, 0.0), np.eye(3) * 40.0**2)  # 40 m sigma: anything near goes
    assert aid.assoc.within_reach(wide, far, 2.0)
    # An estimate forgotten for want of bearings anchors its restart for forgotten_max_age_s,
    # the allowance growing by forgotten_speed_mps per second since it was last updated.
    aid.book.drop_stale(1.0 + aid.params.stale_after_s + 0.1)
    assert "n" not in aid.filters and aid.book.recently_forgotten("n", 10.0) is old
    assert aid.book.recently_forgotten("n", 1.0 + aid.params.forgotten_max_age_s + 0.1) is None
    moved = NeighbourFilter(13.0, (100.0, 60.0, 0.0), np.eye(3))  # 60 m in 12 s: possible
    assert aid.assoc.within_reach(old, moved, 13.0) and not aid.assoc.within_reach(old, far, 13.0)


def test_a_box_too_large_for_any_neighbour_is_dropped_before_tracking():
    """target_extent_m: with the nearest UWB range 100 m a 0.55 m quad makes ~3 px at the image
    centre of a 1920 px 120 deg camera (f 554 px) and 4x that at 60 deg off axis; the CNN's
    occasional 100+ px box around distant vehicles is no neighbour. Kept: boxes within 3x + 4 px
    of that size; without a recent range, or without target_extent_m, nothing is dropped."""
    from testbench.core.camera_geometry import CameraMount, PinholeCamera, mount_rotation
    from testbench.core.interfaces import BuildContext
    from testbench.core.messages import UwbRange
    from testbench.navigation.relative.aid import RelnavAid
    from testbench.navigation.relative.bench import ORIGIN, _Camera, _estimate, _Uwb
    from testbench.navigation.relative.types import Detection

    cam = PinholeCamera.from_hfov(1920, 1080, 120.0)
    sensors = {"front": _Camera(cam, CameraMount(mount_rotation(0.0, 0.0, 0.0), np.zeros(3))), "uwb": _Uwb()}

    def aid_with(**params):
        return RelnavAid(RelnavAid.Params(cameras=["front"], detector={"type": "oracle"}, **params),
                         ctx=BuildContext("self", ("self", "n0", "n1"), ORIGIN), sensors=sensors, rng=np.random.default_rng(0))

    def box(u, v, w, h):
        return Detection((u - w / 2, v - h / 2, u + w / 2, v + h / 2), (u, v), 0.9)

    centre_ok, centre_big = box(960, 540, 12.0, 3.0), box(960, 540, 120.0, 40.0)  # limit 3 * 3.05 + 4 = 13.2 px
    edge_ok = box(60, 540, 30.0, 6.0)  # 58 deg off axis: a quad there makes ~11 px, limit 37 px
    dets = [centre_ok, centre_big, edge_ok]
    aid = aid_with(target_extent_m=0.55)
    assert aid._plausible_size(dets, cam, 1.0) == dets  # no range yet: nothing to judge by
    est = _estimate(0.0, np.zeros(3), np.random.default_rng(0), 0.0)
    aid.process(UwbRange(0.95, "n0", 100.0, -80.0), est)
    aid.process(UwbRange(0.97, "n1", 180.0, -80.0), est)
    assert aid._plausible_size(dets, cam, 1.0) == [centre_ok, edge_ok]
    assert aid.counters["detections_oversize"] == 1
    assert aid._plausible_size([box(960, 540, 14.0, 3.0)], cam, 1.0) == []  # just over the limit at 100 m
    assert aid._plausible_size(dets, cam, 5.0) == dets  # the ranges are 4 s old
    assert aid_with()._plausible_size(dets, cam, 1.0) == dets  # no target extent: no check
    # An LED detector's box is the LEDs' glow, whatever the range: the check is refused.
    from testbench.core.errors import InputError

    with pytest.raises(InputError, match="target_extent_m"):
        RelnavAid(RelnavAid.Params(cameras=["front"], detector={"type": "led"}, target_extent_m=0.55),
                  ctx=BuildContext("self", ("self", "n0"), ORIGIN), sensors=sensors)
