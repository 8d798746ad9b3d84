"""Neighbour EKF (convergence, NLOS rejection) and the oracle detector's statistics."""

import numpy as np
import pytest

from testbench.core.camera_geometry import CameraMount, mount_rotation
from testbench.navigation.relative.detectors import OracleDetector
from testbench.navigation.relative.neighbour_filter import FilterSettings, NeighbourFilter, initial_covariance
from testbench.sensors.camera.types import VehicleTruth

MOUNT = CameraMount(mount_rotation(0, 0, 0), np.array([0.1, 0.0, 0.0]))
F_PX = 554.0


def _run(robust: bool, seed: int = 0):
    """A neighbour at 100 m moving at 0.5 m/s relative; bearings at 10 Hz, ranges at 10 Hz, one
    NLOS range with +6 m excess at t = 5 s. Returns the position errors (m) after t = 5 s."""
    rng = np.random.default_rng(seed)
    R_nc = MOUNT.R_bc  # level vehicle heading north: R_nb = I
    c = MOUNT.lever_arm_b_m
    r_true = lambda t: np.array([100.0, 10.0 + 0.5 * t, -5.0])
    f = NeighbourFilter(0.0, r_true(0) + [3.0, -2.0, 1.0], initial_covariance(r_true(0), 0.5, 0.02),
                        FilterSettings(robust=robust))
    errs = []
    for k in range(1, 101):
        t = 0.1 * k
        d = (r_true(t) - c) @ R_nc
        m = d[:2] / d[2] + rng.normal(0, 1.0 / F_PX, 2)
        f.update_bearing(t, m, R_nc, c, F_PX)
        rho = np.linalg.norm(r_true(t + 0.05)) + rng.normal(0, 0.1) + (6.0 if k == 50 else 0.0)
        nis, ok = f.update_range(t + 0.05, rho)
        if k == 50:
            nlos_accepted = ok
        if k >= 50:
            errs.append(np.linalg.norm(f.x[:3] - r_true(f.t_s)))
    return np.array(errs), nlos_accepted, f


def test_filter_rejects_nlos_outlier():
    errs, accepted, f = _run(robust=True)
    assert not accepted and f.counters["range_rejected"] >= 1
    assert errs.max() < 0.5
    errs_naive, accepted_naive, _ = _run(robust=False)
    assert accepted_naive and errs_naive.max() > errs.max() + 0.5  # the outlier pulls a naive filter


def test_filter_converges_and_is_consistent():
    errs, _, f = _run(robust=True, seed=1)
    assert errs[-20:].mean() < 0.3  # 1 px at 100 m is 0.18 m per axis
    P = f.P[:3, :3]
    assert np.all(np.linalg.eigvalsh(P) > 0)


def test_soft_accept_after_persistent_disagreement():
    f = NeighbourFilter(0.0, [50.0, 0, 0], np.eye(3) * 0.01, FilterSettings(max_consecutive_rejects=3))
    oks = [f.update_range(0.1 * k, 60.0)[1] for k in range(1, 6)]
    assert oks[:3] == [False] * 3 and oks[3]  # the 4th is taken softly
    assert f.counters["range_soft"] == 1


def _truths(n=200):
    rng = np.random.default_rng(0)
    out = []
    for i in range(n):
        u, v = rng.uniform(100, 1800), rng.uniform(100, 1000)
        out.append(VehicleTruth(f"v{i}", (u - 5, v - 4, u + 5, v + 4), np.array([u, v]), np.array([[u - 1, v], [u + 1, v]]),
                                (True, bool(i % 2)), (True, True), True, 100.0))
    return out


def test_oracle_noise_miss_and_false_alarm_statistics():
    truths = _truths()
    img = np.zeros((1080, 1920, 3), np.uint8)
    p = OracleDetector.Params(sigma_px=2.0, miss_probability=0.2, false_alarms_per_mpx=1.0, size_sigma=0.0)
    det = OracleDetector(p, rng=np.random.default_rng(5))
    n_det, n_fa, errs = 0, 0, []
    frames = 50
    centres = np.array([t.centre_px for t in truths])
    for _ in range(frames):
        ds = det.detect_region(img, (0, 0), truths)
        for d in ds:
            dist = np.linalg.norm(centres - d.centre_px, axis=1)
            j = int(np.argmin(dist))
            if d.led_on is None:
                n_fa += 1
                continue
            n_det += 1
            errs.append(np.asarray(d.centre_px) - centres[j])
            assert d.led_level == float(sum(truths[j].led_on))
    n = frames * len(truths)
    # Misses ~ Binomial(n, 0.2): 4-sigma bounds.
    assert abs(n_det / n - 0.8) < 4 * np.sqrt(0.2 * 0.8 / n)
    errs = np.array(errs)
    assert np.std(errs[:, 0]) == pytest.approx(2.0, rel=0.05) and abs(np.mean(errs[:, 1])) < 0.1
    lam = frames * 1920 * 1080 / 1e6
    assert abs(n_fa - lam) < 4 * np.sqrt(lam)


def test_oracle_is_deterministic_under_seed():
    truths = _truths(20)
    img = np.zeros((1080, 1920, 3), np.uint8)
    p = OracleDetector.Params(sigma_px=1.0, miss_probability=0.3)
    a = [d.centre_px for d in OracleDetector(p, rng=np.random.default_rng(9)).detect_region(img, (0, 0), truths)]
    b = [d.centre_px for d in OracleDetector(p, rng=np.random.default_rng(9)).detect_region(img, (0, 0), truths)]
    assert a == b


def test_own_acceleration_is_taken_out_of_the_prediction():
    """We accelerate at 2 m/s^2 for 3 s past a hovering neighbour: with our own velocity given
    at each step the predicted relative position stays on the truth (it moved 9 m) without any
    measurement; without it the constant-relative-velocity model is 9 m off."""
    r0 = np.array([80.0, 30.0, 0.0])
    a = np.array([2.0, 0.0, 0.0])
    with_v = NeighbourFilter(0.0, r0, np.eye(3) * 0.01, FilterSettings(init_vel_sigma_mps=0.1))
    without = NeighbourFilter(0.0, r0, np.eye(3) * 0.01, FilterSettings(init_vel_sigma_mps=0.1))
    with_v.predict(0.0, np.zeros(3))
    for k in range(1, 31):
        t = 0.1 * k
        with_v.predict(t, a * t)
        without.predict(t)
    truth = r0 - 0.5 * a * 3.0**2
    assert np.linalg.norm(with_v.x[:3] - truth) < 0.05
    assert np.allclose(with_v.x[3:], -a * 3.0)  # relative velocity: minus ours
    assert np.linalg.norm(without.x[:3] - truth) > 8.0


def test_a_short_range_is_never_taken_for_nlos():
    """NLOS lengthens ranges only: a range 5 m SHORTER than predicted (the estimate drifted) is
    fused at once; one 5 m longer is rejected as NLOS."""
    f = NeighbourFilter(0.0, [100.0, 0, 0], np.eye(3) * 0.01)
    nis, ok = f.update_range(0.1, 95.0)
    assert ok and nis > f.gate1 and f.counters["range_rejected"] == 0
    assert np.linalg.norm(f.x[:3]) < 96.0  # pulled most of the 5 m (prior sigma 0.1 m, noise 0.1 m)
    g = NeighbourFilter(0.0, [100.0, 0, 0], np.eye(3) * 0.01)
    assert not g.update_range(0.1, 105.0)[1] and g.counters["range_rejected"] == 1


def test_ranges_do_not_clear_the_bearing_rejects_count():
    """Bearings rejected in a row stay counted while ranges are accepted in between (a range
    says nothing of the direction; the aid restarts a neighbour on that count)."""
    R_nc, c = MOUNT.R_bc, MOUNT.lever_arm_b_m
    f = NeighbourFilter(0.0, [100.0, 0.0, 0.0], initial_covariance([100.0, 0.0, 0.0], 0.1, 0.001))
    wrong = np.array([0.2, 0.0])  # 11 deg off the estimate's line of sight
    for k in range(1, 6):
        assert not f.update_bearing(0.1 * k, wrong, R_nc, c, F_PX)[1]
        assert f.update_range(0.1 * k + 0.05, 100.0)[1]
    assert f.consecutive_bearing_rejects == 5


def _perturbed_m_xy(direction_c: np.ndarray, sigma_rad: float, n: int, rng) -> np.ndarray:
    """(n, 2) normalised image coordinates of `direction_c` (camera frame, z forward) turned
    by random angles of sigma_rad per axis perpendicular to it."""
    d = direction_c / np.linalg.norm(direction_c)
    a = np.cross(d, [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(d, a)
    e = rng.normal(0.0, sigma_rad, (n, 2))
    rays = d + e[:, :1] * a + e[:, 1:] * b
    return rays[:, :2] / rays[:, 2:]


@pytest.mark.parametrize("off_axis_deg", [0.0, 30.0, 59.0])
def test_angle_bearing_noise_is_an_angular_error_through_the_pinhole(off_axis_deg):
    """bearing_noise_cov "angle": the covariance of a direction's image coordinates when the
    direction errs by an angle, at the centre, 30 deg off axis, and at a 120 deg field's edge."""
    from testbench.navigation.relative.neighbour_filter import bearing_noise_cov

    rng = np.random.default_rng(3)
    sigma_rad = 1.0 / F_PX
    th = np.radians(off_axis_deg)
    direction = np.array([np.sin(th) * 0.8, np.sin(th) * 0.6, np.cos(th)])  # off axis both ways
    m = _perturbed_m_xy(direction, sigma_rad, 200_000, rng)
    C_empirical = np.cov(m.T)
    m0 = direction[:2] / direction[2]
    C = bearing_noise_cov(m0, 1.0, F_PX, "angle")
    assert np.allclose(C, C_empirical, rtol=0.03, atol=0.03 * C[0, 0])
    # The stretch: radially (1 + r^2), tangentially sqrt(1 + r^2) times the centre's sigma.
    r2 = float(m0 @ m0)
    w = np.linalg.eigvalsh(C)
    assert np.allclose(np.sqrt(w) * F_PX, sorted([np.sqrt(1 + r2), 1 + r2]), rtol=1e-9)
    # "pixel" is the same everywhere: the centre's.
    assert np.allclose(bearing_noise_cov(m0, 1.0, F_PX, "pixel"), np.eye(2) / F_PX**2)
    with pytest.raises(ValueError, match="bearing_sigma_model"):
        bearing_noise_cov(m0, 1.0, F_PX, "pixels")


def test_angle_bearing_noise_leaves_the_centre_as_pixel_and_discounts_the_edge():
    """Near the edge a bearing under "angle" moves the estimate less than under "pixel" (it is
    worth less), at the centre alike."""
    R_nc = MOUNT.R_bc
    c = MOUNT.lever_arm_b_m
    shifts = {}
    for model in ("pixel", "angle"):
        for name, r_true in (("centre", np.array([100.0, 0.0, 0.0])), ("edge", np.array([50.0, 86.6, 0.0]))):
            f = NeighbourFilter(0.0, r_true, initial_covariance(r_true, 0.1, 0.002),
                                FilterSettings(bearing_sigma_model=model))
            d = (r_true - c) @ R_nc
            m = d[:2] / d[2] + np.array([3.0 / F_PX, 0.0])  # a 3 px error along the image's u
            f.update_bearing(0.0, m, R_nc, c, F_PX)
            shifts[model, name] = float(np.linalg.norm(f.x[:3] - r_true))
    assert shifts["angle", "centre"] == pytest.approx(shifts["pixel", "centre"], rel=1e-3)
    assert shifts["angle", "edge"] < 0.7 * shifts["pixel", "edge"]

