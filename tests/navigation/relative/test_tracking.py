"""Image tracking: Hungarian assignment keeps identities of crossing tracks; LED IDs decode
through missed frames and chip errors; birth and death."""

import numpy as np

from testbench.core import led_code
from testbench.navigation.relative.idcode import IdDecoder, chips_from_levels
from testbench.navigation.relative.tracking import Tracker, TrackerSettings
from testbench.navigation.relative.types import Detection


def _det(u, v, level=None, size=6.0):
    return Detection((u - size / 2, v - size / 2, u + size / 2, v + size / 2), (u, v), 1.0, led_level=level)


def _level(k, fi, n_leds=4):
    return float(sum(led_code.led_states(k, fi, n_leds)))


def test_crossing_tracks_keep_identity_and_decode_ids():
    tr = Tracker(n_vehicles=10, own_index=0, settings=TrackerSettings(n_init=2))
    rng = np.random.default_rng(3)
    ids_a, ids_b = set(), set()
    for k in range(60):  # 6 s at 10 Hz; A moves right, B left; they cross at k = 30
        t = 0.1 * k
        ua, ub = 100 + 10 * k, 700 - 10 * k
        va, vb = 300 + 0.5 * k, 303 - 0.5 * k
        dets = [_det(ua + rng.normal(0, 0.5), va + rng.normal(0, 0.5), _level(3, k)),
                _det(ub + rng.normal(0, 0.5), vb + rng.normal(0, 0.5), _level(7, k))]
        if k % 2:
            dets = dets[::-1]  # detection order must not matter
        tr.update(t, k, dets)
        if k > 3:  # after the velocity has converged: A's track moves right, B's left
            for t_ in tr.tracks:
                (ids_a if t_.kf.x[4, 0] > 0 else ids_b).add(t_.track_id)
                assert abs(t_.centre_px[0] - (ua if t_.kf.x[4, 0] > 0 else ub)) < 3.0
    assert len(tr.tracks) == 2
    assert len(ids_a) == 1 and len(ids_b) == 1 and ids_a != ids_b  # no swap at the crossing
    by_id = {t_.track_id: t_ for t_ in tr.tracks}
    assert by_id[ids_a.pop()].id_index == 3
    assert by_id[ids_b.pop()].id_index == 7
    assert tr.counters["id_changes"] == 0


def test_track_birth_and_death():
    tr = Tracker(4, settings=TrackerSettings(n_init=3, max_misses=2))
    for k in range(3):
        tr.update(0.1 * k, k, [_det(50, 50)])
    assert len(tr.confirmed()) == 1
    for k in range(3, 6):
        tr.update(0.1 * k, k, [])
    assert tr.tracks == [] and tr.counters["died"] == 1
    tr.update(0.6, 6, [_det(500, 500)])  # a single false alarm never confirms
    tr.update(0.7, 7, [])
    assert tr.tracks == []


def test_led_decoding_with_missed_frames_and_chip_errors():
    rng = np.random.default_rng(7)
    L = led_code.CODE_LENGTH
    for k in range(1, 16):
        dec = IdDecoder(16, exclude=(0,))
        flipped = 0
        for fi in range(100, 100 + 2 * L):
            if rng.random() < 0.3:
                continue  # missed frame
            level = _level(k, fi) * rng.uniform(0.8, 1.2) * 40.0  # brightness scale unknown to the decoder
            if flipped == 0 and fi > 100 + L:
                level = 40.0 * (5.0 - _level(k, fi))  # one chip error
                flipped = 1
            dec.observe(fi, level)
        idx, conf = dec.decode()
        assert idx == k and conf > 0.99


def test_decoder_waits_for_evidence():
    dec = IdDecoder(8)
    assert dec.decode() == (None, 0.0)
    for fi in range(3):  # preamble 1, 1, 1: one brightness level only
        dec.observe(fi, 4.0)
    assert dec.decode()[0] is None
    assert chips_from_levels(np.array([4.0, 4.0, 4.1])) is None


def test_chip_of_the_current_frame():
    """chip_at gives the frame's blink chip (the data LEDs lit: 1) once two levels are seen,
    the same before and after the decoder has scored its window, and None for another frame."""
    k = 5
    dec = IdDecoder(8)
    states = []
    for fi in range(40, 40 + led_code.CODE_LENGTH):
        lit = led_code.led_states(k, fi, 5)
        dec.observe(fi, 0.05 + 30.0 * sum(lit[1:]))  # the data LEDs' level (anchor excluded)
        states.append(int(all(lit[1:])))
        if fi == 40:
            assert dec.chip_at(fi) is None  # one level seen: no threshold yet
        elif len(set(states)) == 2:
            before = dec.chip_at(fi)
            dec.posteriors(4)  # (the tracker scores the window before the aid asks)
            assert before == dec.chip_at(fi) == states[-1]
    assert dec.chip_at(40 + led_code.CODE_LENGTH) is None  # a frame it did not see


def test_code_properties():
    assert led_code.min_distance(32) >= 4
    for k in range(32):
        for fi in range(led_code.CODE_LENGTH):
            s = led_code.led_states(k, fi, 4)
            assert s[0] and len(s) == 4  # the anchor LED is always on
    assert led_code.frame_index(0.3, 10.0) == 3


def test_own_rotation_is_compensated():
    """A fixed line of sight seen by a camera that yaws 4 deg per frame moves ~39 px per frame
    in the image: with the camera attitude given, one track follows it; without, it is lost."""
    from testbench.core.camera_geometry import PinholeCamera

    cam = PinholeCamera.from_hfov(1920, 1080, 120.0)
    los_n = np.array([1.0, 0.02, 0.05])  # NED direction of a distant neighbour

    def run(with_attitude):
        tr = Tracker(n_vehicles=10, own_index=0, settings=TrackerSettings(n_init=2))
        for k in range(20):
            ang = np.radians(4.0) * k * (1 if k < 10 else -1) + (np.radians(80.0) if k >= 10 else 0.0)
            R_nb = np.array([[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1.0]])
            R_bc = np.array([[0, 0, 1.0], [1.0, 0, 0], [0, 1.0, 0]])  # camera z forward, x right, y down
            R_nc = R_nb @ R_bc
            d = R_nc.T @ los_n
            uv = cam.K @ (d / d[2])
            tr.update(0.1 * k, k, [_det(uv[0], uv[1], 1.0)], R_nc if with_attitude else None, cam.K if with_attitude else None)
        return tr.counters["born"]

    assert run(True) == 1
    assert run(False) > 3


def test_an_id_contradicted_by_the_last_code_cycle_is_revoked():
    """A track that moves from vehicle 3 to vehicle 6 (blobs merged and parted) loses the ID 3
    within one code cycle of vehicle 6's chips, then decodes 6; a few chip errors on a track
    that stays on its vehicle never revoke its ID."""
    L = led_code.CODE_LENGTH
    tr = Tracker(n_vehicles=10, own_index=0, settings=TrackerSettings(n_init=1))
    for k in range(2 * L):
        tr.update(0.1 * k, k, [_det(500, 300, 40.0 * _level(3, k))])
    (track,) = tr.tracks
    assert track.id_index == 3
    revoked_at = None
    for k in range(2 * L, 5 * L):
        tr.update(0.1 * k, k, [_det(500, 300, 40.0 * _level(6, k))])
        if revoked_at is None and track.id_index != 3:
            revoked_at = k - 2 * L
    assert revoked_at is not None and revoked_at <= L
    assert tr.counters["id_revoked"] + tr.counters["id_lost"] == 1
    assert track.id_index == 6

    rng = np.random.default_rng(5)
    for trial in range(20):
        tr = Tracker(n_vehicles=10, own_index=0, settings=TrackerSettings(n_init=1))
        errors = set(rng.choice(np.arange(2 * L, 4 * L), 2, replace=False))
        for k in range(4 * L):
            level = _level(4, k) if k not in errors else 5.0 - _level(4, k)  # a flipped chip
            tr.update(0.1 * k, k, [_det(500, 300, 40.0 * level)])
        assert tr.tracks[0].id_index == 4 and tr.counters["id_revoked"] == 0


def test_mixture_tells_two_blinks_in_one_blob_from_one_blink():
    """Levels summing vehicle 3's blink (amplitude 12) and vehicle 7's (5) fit the pair (3, 7)
    far better than any single word; one vehicle's blink with level noise and a flipped chip
    does not look like a mixture."""
    rng = np.random.default_rng(4)
    merged, single = IdDecoder(10, exclude=(0,)), IdDecoder(10, exclude=(0,))
    for k in range(2 * led_code.CODE_LENGTH):
        merged.observe(k, 0.05 + 12.0 * led_code.chip(3, k) + 5.0 * led_code.chip(7, k) + rng.normal(0, 0.3))
        flipped = k == 20
        single.observe(k, 0.05 + 12.0 * (led_code.chip(3, k) ^ flipped) + rng.normal(0, 0.3))
    mix = merged.mixture()
    assert mix.pair == (3, 7) and mix.is_mixture(0.2, 2.0)
    assert abs(mix.amplitudes[0] - 12.0) < 0.5 and abs(mix.amplitudes[1] - 5.0) < 0.5
    assert merged.decode()[0] in (3, 7)  # what thresholded chips make of it: one of the two
    one = single.mixture()
    assert one.single == 3 and not one.is_mixture(0.2, 2.0)
    assert IdDecoder(10).mixture() is None  # no levels yet


def test_a_track_on_a_merged_blob_carries_no_id_while_merged():
    """Vehicle 3's blob merged with the dimmer blob of vehicle 6 behind it: without the
    mixture test the track decodes 3, confidently (its chips are 3's); with it, no ID while
    the blobs stay merged, and vehicle 6 alone once they part and the track keeps 6."""
    L = led_code.CODE_LENGTH

    def level(k):
        return 40.0 * _level(3, k) + 12.0 * _level(6, k)

    plain = Tracker(n_vehicles=10, own_index=0, settings=TrackerSettings(n_init=1))
    for k in range(2 * L):
        plain.update(0.1 * k, k, [_det(500, 300, level(k))])
    assert plain.tracks[0].id_index == 3 and plain.tracks[0].id_confidence > 0.99

    tr = Tracker(n_vehicles=10, own_index=0, settings=TrackerSettings(n_init=1, mixture_min_ratio=0.2))
    for k in range(2 * L):
        tr.update(0.1 * k, k, [_det(500, 300, level(k))])
    (track,) = tr.tracks
    assert track.id_index is None and set(track.mixture) == {3, 6}
    assert tr.counters["id_mixture_frames"] > 0 and tr.counters["id_mixture_dropped"] == 0
    shown = []
    for k in range(2 * L, 5 * L):
        tr.update(0.1 * k, k, [_det(500, 300, 12.0 * _level(6, k))])
        shown.append(track.id_index)
    assert 3 not in shown and shown[-1] == 6


def test_resolve_keeps_the_id_of_a_track_while_its_blob_is_merged():
    """mixture_action "resolve": vehicle 3's track keeps the ID it decoded before vehicle 6's
    dimmer blob joins it, carries the pair (3, 6) without changing its ID while they stay
    merged (the aid then attributes each frame by the chips), and when they part the pair is
    gone and the track goes on decoding."""
    L = led_code.CODE_LENGTH
    tr = Tracker(n_vehicles=10, own_index=0,
                 settings=TrackerSettings(n_init=1, mixture_min_ratio=0.2, mixture_action="resolve"))
    for k in range(2 * L):
        tr.update(0.1 * k, k, [_det(500, 300, 40.0 * _level(3, k))])
    (track,) = tr.tracks
    assert track.id_index == 3 and track.mixture is None
    pairs, ids = [], []
    for k in range(2 * L, 4 * L):
        tr.update(0.1 * k, k, [_det(500, 300, 40.0 * _level(3, k) + 12.0 * _level(6, k))])
        pairs.append(track.mixture)
        ids.append(track.id_index)
    assert set(pairs[-1]) == {3, 6} and set(ids) == {3}
    assert tr.counters["id_mixture_frames"] > 0 and tr.counters["id_mixture_dropped"] == 0
    for k in range(4 * L, 7 * L):
        tr.update(0.1 * k, k, [_det(500, 300, 40.0 * _level(3, k))])
    assert track.mixture is None and track.id_index == 3
