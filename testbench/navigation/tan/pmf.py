"""Point-mass terrain matching for terrain-aided navigation (TAN): where a dead-reckoned track
lies on the DEM, from the ranges a radar altimeter measured along it.

The unknowns are the offset of the true track from the dead-reckoned one over a short window,
taken as constant in that window: (dn, de), north and east (m), and dh, the true height above
the dead-reckoned height (m, up positive). The horizontal offset lives on a regular grid, the
point-mass representation of Bergman (1999, "Recursive Bayesian Estimation: Navigation and
Tracking Applications"), so that the many-peaked likelihood of terrain matching is carried
whole: a Kalman filter linearised on the terrain slope (SITAN) locks onto the nearest peak.

For each grid offset j the ranges r_k (k = 1..N) are predicted as r_hat_jk: the nearest return
in the beam (core.radar_beam) from the dead-reckoned antenna moved by the offset, over the
onboard DEM; a higher vehicle reads a longer range by about dh (the nearest return lies within
the beam's half angle of the vertical: at 20 deg the range grows by 0.94-1 m per metre). The
residuals e_j = r - r_hat_j - dh 1 are Gaussian with covariance
    C = diag(sigma_k^2) + sigma_dem^2 K,  K_kl = exp(-d_kl^2 / (2 L^2)),
sigma_k the altimeter's white noise, sigma_dem the onboard DEM's error, d_kl the distance between
the ground points the k-th and l-th ranges came from (their nearest returns, found from the
dead-reckoned track at the grid's centre) and L the DEM error's correlation length. A DEM errs in
patches: taking its error as white would count one patch's error once per range and make the
density far narrower than the match is good (false peaks taken for true ones). dh has a flat
prior and is integrated out exactly (the likelihood is Gaussian in it):
    log L_j = -1/2 (a_j - b_j^2 / c),  a_j = e0_j' C^-1 e0_j, b_j = 1' C^-1 e0_j, c = 1' C^-1 1,
e0_j the residuals at dh = 0; given j, dh ~ N(b_j / c, 1 / c). Ranges off the model (returns
from trees, masts, water) are found at the offset that fits best robustly (beyond
outlier_sigmas of their own sigma from that offset's median residual) and dropped before the
density is formed, once.

Shapes: the grid is (n, n); predicted ranges (N, n, n).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from testbench.core.radar_beam import HeightFn, first_return_m, nearest_return_ne_m


@dataclass(frozen=True)
class PmfPosterior:
    """The density's summary.

    mean_ne_m (2,), cov_ne_m2 (2, 2): horizontal offset mean and covariance (m, m^2);
    mean_dh_m, var_dh_m2: vertical offset (true minus dead-reckoned height, up, m);
    mass_in_ellipse: the probability inside the 99 % ellipse of (mean, cov) (chi-square 2 dof,
    9.21): near 0.99 for one peak, lower where the density has several; edge_mass: the
    probability in the grid's outer ring of cells (a density pressed against the grid's edge
    was cut off there); used, outliers: ranges in the density and ranges dropped;
    misfit_per_dof: the best offset's chi-square (a_j - b_j^2 / c) over its used - 1 degrees of
    freedom: about 1 when the ranges are what the model says they are, far above it when the
    ground is not what the DEM holds (a town, a forest) or the offset is not on the grid;
    lag_weights (N, 2, 2): how a drift of the true offset over the window enters the offset
    found: o_hat = sum_k W_k o(t_k) for an offset o(t) that drifts linearly (sum_k W_k = I; 0 for
    ranges dropped; None where the grid cannot give the terrain's slopes): see
    TerrainPmf._lag_weights."""

    mean_ne_m: np.ndarray
    cov_ne_m2: np.ndarray
    mean_dh_m: float
    var_dh_m2: float
    mass_in_ellipse: float
    edge_mass: float
    used: int
    outliers: int
    misfit_per_dof: float
    lag_weights: np.ndarray | None = None


class TerrainPmf:
    """A grid of horizontal offsets, fed range by range (update), summarised at the window's
    end (posterior).

    half_width_m: the grid spans [-half_width_m, half_width_m] in north and east with `cells`
    points each (odd: 0 is a point). The density has a flat prior over the grid: the grid is the
    search region, and the density is the ranges' likelihood alone, so that a fix made of it
    tells the navigator nothing it already knew. dem_sigma_m, dem_correlation_m: the onboard
    DEM's error (1 sigma, m) and its correlation length (m; 0: white)."""

    def __init__(self, half_width_m: float, cells: int, dem_sigma_m: float, dem_correlation_m: float):
        if cells < 3 or cells % 2 == 0:
            raise ValueError(f"the grid size must be odd (the zero offset a point), got {cells}")
        self.offsets_m = np.linspace(-half_width_m, half_width_m, cells)
        self.step_m = float(self.offsets_m[1] - self.offsets_m[0])
        self._dn, self._de = np.meshgrid(self.offsets_m, self.offsets_m, indexing="ij")
        self.dem_sigma_m = float(dem_sigma_m)
        self.dem_correlation_m = float(dem_correlation_m)
        self._r_hat: list[np.ndarray] = []  # (n, n) per range
        self._ranges: list[float] = []
        self._sigmas: list[float] = []
        self._return_ne: list[np.ndarray] = []  # (2,) per range: where its echo came from, NE m

    @property
    def updates(self) -> int:
        return len(self._ranges)

    def update(self, antenna_ned_m, R_nb, rays_b, range_m: float, sigma_m: float, height_m: HeightFn) -> None:
        """Take one range (m) measured from the dead-reckoned antenna position antenna_ned_m
        (3,) NED m, attitude R_nb (3, 3, body->NED), beam rays_b (k, 3), the altimeter's white
        1-sigma sigma_m, over the onboard terrain height_m (NaN off the DEM)."""
        a = np.asarray(antenna_ned_m, float)
        pos = np.stack([a[0] + self._dn, a[1] + self._de, np.full(self._dn.shape, a[2])], axis=-1)
        self._r_hat.append(first_return_m(pos, R_nb, rays_b, height_m))
        self._ranges.append(float(range_m))
        self._sigmas.append(float(sigma_m))
        # The DEM errs where the echo comes from, not below the antenna: the nearest return lies
        # up to h tan(half angle) aside (290 m at 800 m and 20 deg, about a correlation length),
        # and ranges from one ridge share its error wherever the vehicle was. The return point
        # at the grid's centre stands for all offsets (a shift moves them all alike).
        self._return_ne.append(nearest_return_ne_m(a, R_nb, rays_b, height_m))

    def _covariance(self, keep: np.ndarray) -> np.ndarray:
        """C (m, m) over the kept ranges: their white noise plus the DEM's correlated error."""
        # A centimetre of white noise at least: a Gaussian kernel over close points is all but
        # singular, and an ideal altimeter (sigma 0) would leave C without an inverse.
        s = np.maximum(np.asarray(self._sigmas)[keep], 0.01)
        C = np.diag(s**2)
        if self.dem_sigma_m > 0:
            p = np.asarray(self._return_ne)[keep]
            if self.dem_correlation_m > 0:
                d2 = ((p[:, None, :] - p[None, :, :]) ** 2).sum(-1)
                C += self.dem_sigma_m**2 * np.exp(-0.5 * d2 / self.dem_correlation_m**2)
            else:
                C += self.dem_sigma_m**2 * np.eye(len(s))
        return C

    def _log_likelihood(self, keep: np.ndarray):
        """(log L (n*n,), b / c (n*n,), 1 / c, residuals e0 (m, n*n), C's diagonal (m,), m^2,
        C's Cholesky factor) over the kept ranges; offsets whose prediction left the DEM get -inf."""
        r_hat = np.asarray(self._r_hat)[keep].reshape(int(keep.sum()), -1)
        e0 = np.asarray(self._ranges)[keep][:, None] - r_hat
        off_dem = ~np.isfinite(e0).all(axis=0)
        e0 = np.where(np.isfinite(e0), e0, 0.0)
        C = self._covariance(keep)
        cf = cho_factor(C, lower=True)
        W = cho_solve(cf, e0)
        ones_w = cho_solve(cf, np.ones(e0.shape[0]))
        a = np.einsum("kj,kj->j", e0, W)
        b = W.sum(axis=0)
        c = float(ones_w.sum())
        log_l = -0.5 * (a - b * b / c)
        return np.where(off_dem, -np.inf, log_l), b / c, 1.0 / c, e0, np.diag(C), cf

    def posterior(self, outlier_sigmas: float = 4.0) -> PmfPosterior:
        """The density's mean, covariance and shape (PmfPosterior). Raises ValueError before
        any range or when no offset keeps its predictions on the DEM."""
        n_all = len(self._ranges)
        if n_all == 0:
            raise ValueError("no ranges")
        keep = np.ones(n_all, bool)
        log_l, dh_j, var_dh, e0, var_k, cf = self._log_likelihood(keep)
        if not np.isfinite(log_l).any():
            raise ValueError("every offset of the grid predicts ranges off the onboard DEM")
        # Ranges off the model, judged at the offset that fits best robustly: each offset's
        # residuals less their median (a robust dh), scored by a quadratic cut at outlier_sigmas
        # (a few ranges 60 m short would otherwise pull the Gaussian fit's best offset away and
        # make the good ranges look bad there).
        sig = np.sqrt(var_k)[:, None]
        z = (e0 - np.median(e0, axis=0)) / sig
        score = np.where(np.isfinite(log_l), np.minimum(z * z, outlier_sigmas**2).sum(axis=0), np.inf)
        j = int(np.argmin(score))
        bad = np.abs(z[:, j]) > outlier_sigmas
        if bad.any() and (~bad).sum() >= 3:
            keep = ~bad
            log_l, dh_j, var_dh, _, _, cf = self._log_likelihood(keep)
        w = np.exp(log_l - log_l.max())
        w /= w.sum()
        w_ne = w.reshape(self._dn.shape)
        mn = float((w_ne * self._dn).sum())
        me = float((w_ne * self._de).sum())
        dn, de = self._dn - mn, self._de - me
        # A point mass stands for its cell: its own spread (step^2 / 12) is added per axis.
        cell_var = self.step_m**2 / 12.0
        cov = np.array([[(w_ne * dn * dn).sum() + cell_var, (w_ne * dn * de).sum()],
                        [(w_ne * dn * de).sum(), (w_ne * de * de).sum() + cell_var]])
        mh = float((w * dh_j).sum())
        vh = float(var_dh + (w * (dh_j - mh) ** 2).sum())
        x = np.stack([dn, de], axis=-1)
        d2 = np.einsum("...i,ij,...j->...", x, np.linalg.inv(cov), x)
        inside = float(w_ne[d2 <= 9.21].sum())
        edge = float(w_ne[0].sum() + w_ne[-1].sum() + w_ne[1:-1, 0].sum() + w_ne[1:-1, -1].sum())
        used = int(keep.sum())
        misfit = float(-2.0 * log_l.max()) / max(used - 1, 1)  # log L_j = -1/2 (a_j - b_j^2 / c)
        weights = self._lag_weights(keep, int(np.argmax(log_l)), cf)
        return PmfPosterior(np.array([mn, me]), cov, mh, vh, inside, edge, used, n_all - used, misfit, weights)

    def _lag_weights(self, keep: np.ndarray, j_best: int, cf) -> np.ndarray | None:
        """(N, 2, 2) matrices W_k, sum_k W_k = I, such that the offset found is sum_k W_k o_k
        when the true offset differs from range to range (o_k = o(t_k), drifting with a velocity
        error over the window).

        Linearised at the best offset, the ranges see the offset through the terrain's slope
        under their echoes, G (m, 2) = d r_hat / d offset (central differences on the grid),
        and the generalised least squares with dh integrated out gives
            o_hat = F^-1 G' P y,  F = G' P G,  P = C^-1 - C^-1 1 1' C^-1 / c,
        with y_k = G_k o_k + noise: W_k = F^-1 (P G)_k G_k' (2 x 2). Ranges over steep ground
        weigh more, flat stretches nothing, and each axis by the slopes along it: over a ridge
        running north the east offset comes from the ranges over the ridge, the north offset
        from where the ridge ends. So a drift does not hold at the ranges' mean epoch, nor at one
        epoch for both axes, and a north drift can move the east offset found. None where the best
        offset lies on the grid's edge or F is singular. cf: C's Cholesky factor over the kept
        ranges (from _log_likelihood)."""
        n = self._dn.shape[0]
        i, l = divmod(j_best, n)
        if not (0 < i < n - 1 and 0 < l < n - 1):
            return None
        r_hat = np.asarray(self._r_hat)[keep]  # (m, n, n)
        G = np.stack([(r_hat[:, i + 1, l] - r_hat[:, i - 1, l]), (r_hat[:, i, l + 1] - r_hat[:, i, l - 1])],
                     axis=1) / (2.0 * self.step_m)
        if not np.isfinite(G).all():
            return None
        CiG = cho_solve(cf, G)
        Ci1 = cho_solve(cf, np.ones(G.shape[0]))
        PG = CiG - np.outer(Ci1, Ci1 @ G) / float(Ci1.sum())  # P G (P symmetric)
        F = G.T @ PG
        if np.linalg.cond(F) > 1e8:
            return None
        B = PG @ np.linalg.inv(F).T  # (m, 2): row k is (F^-1 G' P)[:, k]
        w = np.zeros((len(self._ranges), 2, 2))
        w[keep] = np.einsum("ki,kj->kij", B, G)
        return w
