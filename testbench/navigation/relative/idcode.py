"""Decoding a neighbour's ID from its LED blink sequence (code: testbench.core.led_code).

Per track, the decoder keeps the last `window` observations (LED frame index, LED level).
Bits: a level is "all LEDs on" (chip 1) or "anchor only" (chip 0); the threshold between the
two clusters is found per track (Otsu on log levels) because the absolute brightness depends
on range and exposure; no decision while the two clusters are not yet both seen.
Decision: maximum a posteriori over the code book with a uniform prior and independent chip
errors of probability p_chip: log L_k = sum over observations [match ? log(1-p) : log p].
Missed frames are erasures (they just add nothing); confidence = posterior of the best word.

Change of target: an image track can move from one vehicle to another (two neighbours on one
line of sight merge into one blob and part again; the track may leave with the far one). Its
window still holds a code cycle or two of the first vehicle's chips, which outvote the new
ones for a second or more. `recent_posterior(n)` scores only the last n observations (the
chips still thresholded over the whole window, so a jump in brightness, near to far, also
reads as chips that contradict the old word): the tracker revokes an ID the recent chips
contradict and `forget_older(n)` drops the old vehicle's chips.

Merged blobs: two neighbours on one line of sight, a few pixels apart, fall into one detection,
whose level is then the sum of two blinks: b + a_j c_j(f) + a_k c_k(f). Thresholded into chips it
often decodes, confidently, as one of the two (the brighter blink), while the detection's centre
lies on the other. `mixture()` fits the window's levels with one code word and with every pair
of words (linear least squares, an offset and one amplitude per word) and reports how much
better the best pair explains them (MixtureFit): the tracker can withhold the ID from a track
whose blink is a mixture (tracking.TrackerSettings.mixture_min_ratio).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from testbench.core.led_code import CODE_LENGTH, codebook


def chips_from_levels(levels: np.ndarray, min_ratio: float = 1.4) -> np.ndarray | None:
    """0/1 chips from positive LED levels (n,), or None when they do not form two clusters
    whose means differ by at least min_ratio."""
    x = np.log(np.maximum(np.asarray(levels, float), 1e-9))
    if len(x) < 2 or x.max() - x.min() < np.log(min_ratio):
        return None
    xs = np.sort(x)
    # Otsu: maximise the between-class variance i (n - i) (mean_lo - mean_hi)^2 over the split
    # after the i lowest, with the class means from one cumulative sum (the first maximum wins).
    n = len(xs)
    c = np.cumsum(xs)
    i = np.arange(1, n)
    between = i * (n - i) * (c[:-1] / i - (c[-1] - c[:-1]) / (n - i)) ** 2
    k = int(np.argmax(between))
    thr = 0.5 * (xs[k] + xs[k + 1])
    lo, hi = x[x < thr], x[x >= thr]
    if len(lo) == 0 or hi.mean() - lo.mean() < np.log(min_ratio):
        return None
    return (x >= thr).astype(np.uint8)


@dataclass(frozen=True)
class MixtureFit:
    """How the window's levels fit one code word against two (IdDecoder.mixture).

    single: the best single word's vehicle index; pair: the best pair's (j, k); amplitudes:
    their level amplitudes (a_j, a_k), in the pair order; f_stat: (RSS_single - RSS_pair) /
    (RSS_pair / (n - 3)), the F statistic of the pair's extra amplitude (n observations);
    ratio: the smaller amplitude over the larger, 0 when either is not positive."""

    single: int
    pair: tuple[int, int]
    amplitudes: tuple[float, float]
    f_stat: float
    ratio: float

    def is_mixture(self, min_ratio: float, min_f: float) -> bool:
        """Both words blink with at least min_ratio of the larger amplitude, and the pair
        explains the levels better than one word by an F statistic above min_f."""
        return self.ratio >= min_ratio and self.f_stat > min_f


class IdDecoder:
    """Accumulates (frame_index, led_level) of one track and decodes the vehicle index.

    n_vehicles: size of the code book (scenario vehicles); exclude: indices that cannot be seen
    (the observer itself); p_chip: chip error probability used in the likelihood;
    window: observations kept (default two code cycles); search_phase: also search the cyclic
    shift (clocks not shared; weaker: minimum distance between shifted words is 2).
    """

    def __init__(self, n_vehicles: int, exclude: tuple[int, ...] = (), p_chip: float = 0.05,
                 window: int = 2 * CODE_LENGTH, search_phase: bool = False, min_ratio: float = 1.4):
        self.book = codebook(n_vehicles).astype(np.int8)
        self.allowed = np.ones(n_vehicles, bool)
        for k in exclude:
            if 0 <= k < n_vehicles:
                self.allowed[k] = False
        self.p = float(p_chip)
        self.obs: deque[tuple[int, float]] = deque(maxlen=int(window))
        self.search_phase = search_phase
        self.min_ratio = min_ratio
        self._chips: tuple | None = None  # (last observation, count, chips) of the last thresholding

    def observe(self, frame_index: int, level: float | None) -> None:
        """Add one frame's LED level of the track (None: the detector saw no LED level)."""
        if level is None or not np.isfinite(level) or level <= 0:
            return
        if self.obs and self.obs[-1][0] == frame_index:
            self.obs[-1] = (frame_index, max(self.obs[-1][1], float(level)))  # two views of one frame
            return
        self.obs.append((int(frame_index), float(level)))

    def posterior(self) -> np.ndarray | None:
        """Posterior over vehicle indices (n_vehicles,), or None before two chip levels."""
        return self.posteriors(0)[0]

    def recent_posterior(self, n: int) -> np.ndarray | None:
        """Posterior (n_vehicles,) from the chips of the last n observations alone (thresholded
        over the whole window, module docstring); None with fewer than n observations."""
        return self.posteriors(n)[1]

    def posteriors(self, n: int) -> tuple[np.ndarray | None, np.ndarray | None]:
        """(posterior over the whole window, posterior over its last n observations) from one
        thresholding of the levels; the second is None when n < 1 or fewer than n are held."""
        if len(self.obs) < 2:
            return None, None
        fi = np.array([o[0] for o in self.obs])
        bits = chips_from_levels(np.array([o[1] for o in self.obs]), self.min_ratio)
        self._chips = (self.obs[-1], len(self.obs), bits)
        if bits is None:
            return None, None
        recent = self._likelihood_posterior(fi[-n:], bits[-n:]) if 1 <= n <= len(fi) else None
        return self._likelihood_posterior(fi, bits), recent

    def chip_at(self, frame_index: int) -> int | None:
        """The chip (0/1) this track showed in LED frame `frame_index`, as thresholded over the
        window, or None (no observation in that frame, or the levels not yet two clusters)."""
        if not self.obs or self.obs[-1][0] != frame_index:
            return None
        cached = self._chips
        if cached is not None and cached[0] == self.obs[-1] and cached[1] == len(self.obs):
            bits = cached[2]  # posteriors() thresholded this very window
        else:
            bits = chips_from_levels(np.array([o[1] for o in self.obs]), self.min_ratio)
        return None if bits is None else int(bits[-1])

    def forget_older(self, n: int) -> None:
        """Keep only the last n observations."""
        while len(self.obs) > n:
            self.obs.popleft()

    def mixture(self, min_obs: int = 8) -> MixtureFit | None:
        """Fit the window's levels as one blink and as the sum of two (module docstring);
        None with fewer than min_obs observations, fewer than three allowed words, or a
        decoder that searches the code phase (its chips have no known position).

        One word k: level = b + a c_k(f); a pair j, k: level = b + a_j c_j(f) + a_k c_k(f), c
        the 0/1 chips at each observation's LED frame f; least squares through the normal
        equations of all words and pairs at once (a small ridge keeps a word constant over the
        window from making them singular)."""
        n = len(self.obs)
        idx = np.flatnonzero(self.allowed)
        if n < max(min_obs, 4) or len(idx) < 3 or self.search_phase:
            return None
        fi = np.fromiter((o[0] for o in self.obs), np.int64, n)
        y = np.fromiter((o[1] for o in self.obs), np.float64, n)
        C = self.book[idx][:, fi % CODE_LENGTH].astype(np.float64)  # (m, n) chips, 0/1
        s = C.sum(axis=1)  # (m,) = c.c, chips being 0/1
        cy = C @ y
        sy, yy = float(y.sum()), float(y @ y)
        ridge = 1e-9 * n
        # One word: [[n, s], [s, s]] [b, a] = [sy, cy].
        det1 = (n + ridge) * (s + ridge) - s * s
        a1 = ((n + ridge) * cy - s * sy) / det1
        b1 = (sy - s * a1) / (n + ridge)
        rss1 = yy - b1 * sy - a1 * cy
        i1 = int(np.argmin(rss1))
        # Pairs: the 3x3 normal equations of every (j, k), j < k, solved in one batch.
        j, k = np.triu_indices(len(idx), 1)
        S = C @ C.T  # (m, m) chip overlaps
        G = np.empty((len(j), 3, 3))
        G[:, 0, 0] = n
        G[:, 0, 1] = G[:, 1, 0] = s[j]
        G[:, 0, 2] = G[:, 2, 0] = s[k]
        G[:, 1, 1] = s[j]
        G[:, 2, 2] = s[k]
        G[:, 1, 2] = G[:, 2, 1] = S[j, k]
        G[:, [0, 1, 2], [0, 1, 2]] += ridge
        rhs = np.stack([np.full(len(j), sy), cy[j], cy[k]], axis=1)
        beta = np.linalg.solve(G, rhs[..., None])[..., 0]
        rss2 = yy - (beta * rhs).sum(axis=1)
        i2 = int(np.argmin(rss2))
        aj, ak = float(beta[i2, 1]), float(beta[i2, 2])
        lo, hi = min(aj, ak), max(aj, ak)
        ratio = lo / hi if lo > 0.0 else 0.0
        f_stat = float((rss1[i1] - rss2[i2]) / max(rss2[i2] / max(n - 3, 1), 1e-12 * max(yy, 1e-12)))
        return MixtureFit(int(idx[i1]), (int(idx[j[i2]]), int(idx[k[i2]])), (aj, ak), f_stat, ratio)

    def _likelihood_posterior(self, fi: np.ndarray, bits: np.ndarray) -> np.ndarray:
        """Posterior over the code book of chips `bits` seen at LED frames `fi`."""
        lp, lq = np.log(1.0 - self.p), np.log(self.p)
        shifts = range(CODE_LENGTH) if self.search_phase else (0,)
        ll = np.full(len(self.book), -np.inf)
        for s in shifts:
            pos = (fi + s) % CODE_LENGTH
            match = self.book[:, pos] == bits[None, :]
            ll = np.maximum(ll, np.where(match, lp, lq).sum(axis=1))
        ll[~self.allowed] = -np.inf
        ll -= ll.max()
        w = np.exp(ll)
        return w / w.sum()

    def decode(self) -> tuple[int | None, float]:
        """(best vehicle index or None, its posterior probability)."""
        post = self.posterior()
        if post is None:
            return None, 0.0
        k = int(np.argmax(post))
        return k, float(post[k])
