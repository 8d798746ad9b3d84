"""Image-plane tracking of detected vehicles in one camera (SORT-like).

State per track: x = [u, v, a, h, du, dv, da, dh] (box centre px, aspect w/h, height px, and
their rates per second), constant-velocity Kalman filter (filterpy). Assignment: Hungarian
(scipy.optimize.linear_sum_assignment) on the squared Mahalanobis distance of the measurement
[u, v, a, h] to each track's prediction, gated at the chi-square(4) quantile `gate_prob`.
Birth: a track is confirmed after `n_init` hits; death after `max_misses` frames without a
detection (a tentative track dies at its first miss). Each track decodes its LED blink ID
(idcode.IdDecoder); once its confidence passes `id_confidence` the track carries that ID, and
a later change of the decoded ID is counted (`counters["id_changes"]`). An ID that the track's
last `revoke_window` chips contradict (their posterior of it below `revoke_prob`: the track
has moved to another vehicle, idcode module docstring) is revoked at once and the older chips
dropped (`counters["id_revoked"]`); an ID whose posterior over the whole window falls below
`id_keep_prob` is dropped too (`counters["id_lost"]`): the track is then unidentified until its
chips decode again. A track's id_confidence is the current posterior of the ID it carries.
With `mixture_min_ratio` set, a track whose window of blink levels is the sum of two code words
(two vehicles' blobs merged on one line of sight: idcode module docstring) loses its ID and the
chips seen so far (`mixture_action` "drop"; "resolve" keeps them, see TrackerSettings), and
decodes afresh from the chips that follow (`Track.mixture` holds the
pair until then; counters `id_mixture_frames`, and `id_mixture_dropped` when it took an ID
away): the blink of such a blob decodes, confidently, as one vehicle while its centre lies on
the other, and the track may leave with either when they part.

Ego-rotation: a vehicle that turns or tilts by a few degrees between frames moves every image
point by f * angle (tens of pixels), far outside any image-plane motion model. When the caller
passes the camera attitude R_nc (camera -> NED, from the OWN ESTIMATED attitude) and the
intrinsic matrix K, each track's centre is first carried through the infinite homography
K R_nc_new^T R_nc_old K^-1 (a pure rotation; lens distortion neglected), so that the filter only
models the slow relative motion.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np
from filterpy.kalman import KalmanFilter
from scipy.optimize import linear_sum_assignment
from scipy.stats import chi2

from testbench.core.led_code import CODE_LENGTH
from testbench.navigation.relative.idcode import IdDecoder
from testbench.navigation.relative.types import Detection


@dataclass(frozen=True)
class TrackerSettings:
    """sigma_px_min: floor of the pixel noise of a centre; pos_sigma_frac: centre noise as a
    fraction of the box height; accel_px_s2: white-noise image acceleration (px/s^2);
    n_init, max_misses: birth and death; gate_prob: chi-square gate; id_confidence: posterior
    that assigns a decoded ID; p_chip: LED chip error probability; revoke_window,
    revoke_prob: an assigned ID whose posterior over the last revoke_window observations falls
    below revoke_prob is revoked (0 disables). Window one code cycle: every chip position is in
    it, so two words differ in >= 4 of its chips (fewer when frames are missed). Measured over
    all IDs and phases with 10 % missed frames: the true ID never falls below 1e-3 with 2 chip
    errors among the 16 (worst 2.7e-3), does in 0.2 % of 3-error patterns; after the track
    moves to another vehicle the old ID is revoked in 10 frames on average (16 at most);
    id_keep_prob: an assigned ID whose posterior over the whole window falls below this is
    dropped (hysteresis below id_confidence: a blob merged with another vehicle's mixes their
    chips and no longer singles the ID out); mixture_min_ratio, mixture_min_f: a track whose
    window of levels two code words explain better than one (IdDecoder.mixture: the smaller
    amplitude at least mixture_min_ratio of the larger, F statistic above mixture_min_f) holds
    two vehicles' blobs merged and carries no ID while it does (None: no such test; 0.2 and 2
    marked 77 % of the wrong track-frames and 3 % of the right ones on single vehicles, and
    took the paper arrowhead's track-frame IDs from 0.989-0.991 to 0.9987, but its start-up
    formation, sensitive to the set of neighbours each follower estimates, came out worse in
    two of three realisations, so the shipped scenarios leave it off: docs/measurements.md,
    "What the wrong track IDs are"); mixture_action: what such a track does: "drop" its ID
    and chips and decode afresh, or "resolve" / "resolve_or_decoded": keep its ID and chips,
    assign and change no ID while the window is a mixture, and hold the pair in
    Track.mixture, whose frames the relative-navigation aid attributes by the pair's chips
    (RelnavAid._resolved; the two differ there, in the frames the chips cannot attribute)."""

    sigma_px_min: float = 0.7
    pos_sigma_frac: float = 0.1
    accel_px_s2: float = 60.0
    n_init: int = 3
    max_misses: int = 5
    gate_prob: float = 0.999
    id_confidence: float = 0.99
    p_chip: float = 0.05
    search_phase: bool = False
    revoke_window: int = CODE_LENGTH
    revoke_prob: float = 1e-3
    id_keep_prob: float = 0.5
    mixture_min_ratio: float | None = None
    mixture_min_f: float = 2.0
    mixture_action: str = "drop"


# Identity blocks reused every prediction (read-only).
_I4 = np.eye(4)
_I8 = np.eye(8)
_I4.flags.writeable = _I8.flags.writeable = False

def _z(det: Detection) -> np.ndarray:
    h = max(det.height_px, 1.0)
    return np.array([det.centre_px[0], det.centre_px[1], max(det.width_px, 1.0) / h, h])


@dataclass
class Track:
    """One image-plane track. id_index: decoded vehicle index (None until confident)."""

    track_id: int
    kf: KalmanFilter
    t_s: float
    decoder: IdDecoder
    hits: int = 1
    misses: int = 0
    confirmed: bool = False
    id_index: int | None = None
    id_confidence: float = 0.0
    last_detection: Detection | None = None
    history: list = field(default_factory=list)
    R_nc: np.ndarray | None = None  # camera attitude the state's pixels refer to (None: unknown)
    mixture: tuple[int, int] | None = None  # vehicle indices whose blinks its levels mix (None: one or unknown)

    @property
    def centre_px(self) -> np.ndarray:
        return self.kf.x[:2, 0].copy()

    def box_at(self, t_s: float, R_nc: np.ndarray | None = None, K: np.ndarray | None = None) -> tuple[float, float, float, float]:
        """Predicted (u0, v0, u1, v1) at time t_s (constant image velocity), seen with camera
        attitude R_nc (3, 3) when given with K (3, 3) (see module docstring)."""
        x = self.kf.x[:, 0]
        dt = t_s - self.t_s
        u, v, a, h = x[:4] + dt * x[4:]
        if R_nc is not None and K is not None and self.R_nc is not None:
            u, v = rotate_pixel(u, v, np.asarray(R_nc).T @ self.R_nc, K)
        h = max(h, 1.0)
        w = max(a, 0.05) * h
        return (u - w / 2, v - h / 2, u + w / 2, v + h / 2)


def rotate_pixel(u: float, v: float, M: np.ndarray, K: np.ndarray) -> tuple[float, float]:
    """Pixel (u, v) of a ray after the camera rotates: M (3, 3) maps old camera-frame vectors to
    the new camera frame; the ray is K^-1 [u v 1]. A ray that ends behind the camera is left."""
    d = M @ np.linalg.solve(K, np.array([u, v, 1.0]))
    if d[2] <= 1e-6:
        return u, v
    p = K @ (d / d[2])
    return float(p[0]), float(p[1])


class Tracker:
    """Tracks of one camera. `update(t_s, frame_index, detections)` once per frame."""

    def __init__(self, n_vehicles: int, own_index: int | None = None, settings: TrackerSettings | None = None):
        self.s = settings or TrackerSettings()
        self.n_vehicles = n_vehicles
        self.exclude = () if own_index is None else (own_index,)
        self.tracks: list[Track] = []
        self._ids = itertools.count(1)
        self.gate = float(chi2.ppf(self.s.gate_prob, 4))
        self.counters = {"born": 0, "confirmed": 0, "died": 0, "id_assigned": 0, "id_changes": 0, "id_revoked": 0,
                         "id_lost": 0, "id_mixture_frames": 0, "id_mixture_dropped": 0}

    # -- Kalman filter ----------------------------------------------------------------------

    def _R(self, h: float) -> np.ndarray:
        sp = max(self.s.sigma_px_min, self.s.pos_sigma_frac * h)
        # Box shape of a vehicle a few pixels tall jumps with the blink state and the body
        # segmentation: loose on aspect and height, the centre carries the association.
        return np.diag([sp**2, sp**2, 0.5**2, (max(1.5, 0.3 * h)) ** 2])

    def _new_kf(self, z: np.ndarray) -> KalmanFilter:
        kf = KalmanFilter(dim_x=8, dim_z=4)
        kf.H = np.hstack([np.eye(4), np.zeros((4, 4))])
        kf.x = np.concatenate([z, np.zeros(4)]).reshape(8, 1)
        sp = max(self.s.sigma_px_min, self.s.pos_sigma_frac * z[3])
        kf.P = np.diag([sp**2, sp**2, 0.2**2, (0.2 * z[3] + 1) ** 2, 200.0**2, 200.0**2, 0.5**2, (z[3] + 10) ** 2])
        kf.R = self._R(z[3])
        return kf

    def _predict(self, tr: Track, t_s: float) -> None:
        dt = t_s - tr.t_s
        if dt <= 0:
            return
        F = _I8.copy()
        F[:4, 4:] = dt * _I4
        q = self.s.accel_px_s2**2
        qa = np.array([q, q, 0.05**2, (0.05 * tr.kf.x[3, 0] + 2.0) ** 2])
        G = np.vstack([0.5 * dt**2 * _I4, dt * _I4])
        tr.kf.F = F
        tr.kf.Q = G @ np.diag(qa) @ G.T
        tr.kf.predict()
        tr.t_s = t_s

    # -- frames -----------------------------------------------------------------------------

    def update(self, t_s: float, frame_index: int, detections: list[Detection], R_nc: np.ndarray | None = None,
               K: np.ndarray | None = None) -> list[Track]:
        """Predict all tracks to t_s, assign `detections`, update, birth and death.
        R_nc (3, 3) camera -> NED and K (3, 3): compensate the camera's rotation since each
        track's last frame (module docstring). Returns the tracks that received a detection."""
        for tr in self.tracks:
            if R_nc is not None and K is not None and tr.R_nc is not None:
                u, v = rotate_pixel(tr.kf.x[0, 0], tr.kf.x[1, 0], np.asarray(R_nc).T @ tr.R_nc, K)
                tr.kf.x[0, 0], tr.kf.x[1, 0] = u, v
            tr.R_nc = None if R_nc is None else np.asarray(R_nc, float)
            self._predict(tr, t_s)
        zs = [_z(d) for d in detections]
        n, m = len(self.tracks), len(detections)
        cost = np.full((n, m), 1e6)
        if n and m:
            # Every track against every detection in one batched solve (the per-pair solves
            # were a tenth of the swarm's run time); S_ij = P_i + R(h_j), y_ij = z_j - H x_i.
            Z = np.array(zs)  # (m, 4)
            S = np.array([tr.kf.P[:4, :4] for tr in self.tracks])[:, None] + np.array([self._R(z[3]) for z in zs])[None]
            Y = Z[None, :, :] - np.array([tr.kf.x[:4, 0] for tr in self.tracks])[:, None, :]  # (n, m, 4)
            X = np.linalg.solve(S, Y[..., None])[..., 0]
            for i in range(n):
                for j in range(m):
                    d2 = float(Y[i, j] @ X[i, j])
                    if d2 <= self.gate:
                        cost[i, j] = d2
        matched_t, matched_d = set(), set()
        updated = []
        if n and m:
            rows, cols = linear_sum_assignment(cost)
            for i, j in zip(rows, cols):
                if cost[i, j] >= 1e6:
                    continue
                tr, det = self.tracks[i], detections[j]
                tr.kf.R = self._R(zs[j][3])
                tr.kf.update(zs[j].reshape(4, 1))
                tr.hits += 1
                tr.misses = 0
                tr.last_detection = det
                if not tr.confirmed and tr.hits >= self.s.n_init:
                    tr.confirmed = True
                    self.counters["confirmed"] += 1
                self._observe_id(tr, frame_index, det)
                matched_t.add(i)
                matched_d.add(j)
                updated.append(tr)
        survivors = []
        for i, tr in enumerate(self.tracks):
            if i not in matched_t:
                tr.misses += 1
                tr.last_detection = None
                if (not tr.confirmed) or tr.misses > self.s.max_misses:
                    self.counters["died"] += 1
                    continue
            survivors.append(tr)
        self.tracks = survivors
        for j, det in enumerate(detections):
            if j in matched_d:
                continue
            tr = Track(next(self._ids), self._new_kf(zs[j]), t_s,
                       IdDecoder(self.n_vehicles, self.exclude, self.s.p_chip, search_phase=self.s.search_phase),
                       last_detection=det, R_nc=None if R_nc is None else np.asarray(R_nc, float))
            if self.s.n_init <= 1:
                tr.confirmed = True
                self.counters["confirmed"] += 1
            self._observe_id(tr, frame_index, det)
            self.counters["born"] += 1
            self.tracks.append(tr)
            updated.append(tr)
        return updated

    def _observe_id(self, tr: Track, frame_index: int, det: Detection) -> None:
        tr.decoder.observe(frame_index, det.led_level)
        post, recent = tr.decoder.posteriors(self.s.revoke_window if tr.id_index is not None else 0)
        if tr.id_index is not None:
            if recent is not None and recent[tr.id_index] < self.s.revoke_prob:
                # The last code cycle contradicts the ID: the track has moved to another vehicle.
                self.counters["id_revoked"] += 1
                tr.id_index, tr.id_confidence = None, 0.0
                tr.decoder.forget_older(self.s.revoke_window)
                post = tr.decoder.posterior()
            elif post is not None and post[tr.id_index] < self.s.id_keep_prob:
                # Its chips no longer single it out (a blob merged with another vehicle's).
                self.counters["id_lost"] += 1
                tr.id_index, tr.id_confidence = None, 0.0
        if self.s.mixture_min_ratio is not None and self.s.mixture_action != "drop" and self._resolved_as_mixture(tr):
            return
        if post is None:
            return
        k = int(np.argmax(post))
        conf = float(post[k])
        if self.s.mixture_min_ratio is not None and self.s.mixture_action == "drop" and self._withheld_as_mixture(tr, conf):
            return
        if tr.id_index is not None:
            tr.id_confidence = float(post[tr.id_index])
        if conf < self.s.id_confidence:
            if tr.id_index is None:
                tr.id_confidence = conf
            return
        if tr.id_index is None:
            self.counters["id_assigned"] += 1
        elif tr.id_index != k:
            self.counters["id_changes"] += 1
        tr.id_index, tr.id_confidence = k, conf

    def _resolved_as_mixture(self, tr: Track) -> bool:
        """Whether `tr`'s window of levels mixes two code words (mixture_action "resolve" or
        "resolve_or_decoded"):
        then Track.mixture holds the pair, the track keeps its ID and chips but neither claims
        nor changes an ID while it does, and the caller attributes each frame to the one
        vehicle of the pair whose chip is on (RelnavAid)."""
        mix = tr.decoder.mixture(min_obs=CODE_LENGTH)
        if mix is None or not mix.is_mixture(self.s.mixture_min_ratio, self.s.mixture_min_f):
            tr.mixture = None
            return False
        self.counters["id_mixture_frames"] += 1
        tr.mixture = mix.pair
        return True

    def _withheld_as_mixture(self, tr: Track, conf: float) -> bool:
        """Whether `tr`, whose best word has posterior `conf`, must carry no ID after this
        frame: its window of levels mixes two code words (module docstring; the ID and the
        chips go), or it would take a new ID before a code cycle of levels, the span over which
        a mixture shows."""
        if tr.id_index is None and conf < self.s.id_confidence:
            return False  # no ID to keep or to assign
        mix = tr.decoder.mixture(min_obs=CODE_LENGTH)
        if mix is None and tr.id_index is None:
            tr.id_confidence = conf
            return True
        if mix is None or not mix.is_mixture(self.s.mixture_min_ratio, self.s.mixture_min_f):
            tr.mixture = None
            return False
        self.counters["id_mixture_frames"] += 1
        self.counters["id_mixture_dropped"] += int(tr.id_index is not None)
        tr.id_index, tr.id_confidence, tr.mixture = None, 0.0, mix.pair
        # The window's chips are a mixture, and the track may leave with either vehicle when the
        # blobs part: decode afresh from the chips that follow.
        tr.decoder.forget_older(0)
        return True

    def confirmed(self) -> list[Track]:
        return [t for t in self.tracks if t.confirmed]
