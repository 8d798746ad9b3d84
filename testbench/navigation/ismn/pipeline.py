"""The ISMN pipeline: search window -> inertial-aided orthorectification -> registration ->
pose -> position fix (paper section 2.1; DESIGN.md eq. 3-10).

    pipe = IsmnPipeline(camera, mount, reference_map, elevation, matcher, params)
    fix, diag = pipe.process(frame_image, t_s, estimate)

reference_map / elevation: anything with read_local(north_min, north_max, east_min, east_max,
gsd_m) -> LocalRaster (testbench.world MapSource, or synth.RasterMapSource over an in-memory
LocalRaster). The fix goes to the EKF, which gates it; this module reports quality.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from typing import Literal

import cv2
import numpy as np
import pydantic

from testbench.core.camera_geometry import CameraMount, PinholeCamera, camera_pose_ned
from testbench.core.messages import NavEstimate, PositionFix
from testbench.core.registry import ParamsModel
from testbench.core.rotations import quat_to_dcm, rotvec_to_quat
from testbench.navigation.fix_quality import appearance_gain
from testbench.navigation.ismn.area import NccMatcher
from testbench.navigation.ismn.mapcache import MapWindowCache, quantise_gsd
from testbench.navigation.ismn.geometry import estimate_pose, footprint_bounds, nadir_gsd_m, predict_search_window
from testbench.navigation.ismn.cloud_mask import CloudMaskParams, cloud_mask
from testbench.navigation.ismn.ortho import Orthorectifier, to_grey_u8
from testbench.navigation.ismn.pose import image_heading, seed_centre, solve_camera_pose
from testbench.navigation.ismn.rolling import RowMotion
from testbench.navigation.ismn.types import IsmnDiagnostics, MatchPrior

log = logging.getLogger(__name__)


class IsmnParams(ParamsModel):
    """Settings of the ISMN pipeline (metres, degrees at the edge)."""

    gsd_m: float | None = None  # working ground sample; None: the map's own (or the camera's, if coarser)
    max_ortho_px: int = 2048  # the ortho frame's larger side is at most this (coarsens gsd)
    n_sigma: float = 3.0  # window = footprint + n_sigma * position sigma + margin
    margin_m: float = 20.0
    max_off_nadir_deg: float = 70.0  # ground farther from nadir than this is not used
    terrain_height_m: float = 0.0  # flat ground height above the origin without elevation
    relief_min_span_m: float = 5.0  # per-pixel relief when the footprint's height span exceeds this
    elevation_gsd_m: float = 30.0
    min_quality: float = 0.15  # below: no fix
    min_correspondences: int = 6
    pose_method: Literal["map", "opencv"] = "map"
    use_attitude_prior: bool = True  # MAP pose with the INS attitude covariance as prior
    att_prior_floor_deg: float = 0.1  # added (in quadrature) to the INS attitude sigma in the prior
    sigma_floor_m: float = 0.3  # added to the sigma in quadrature (map georeference, model errors)
    sigma_floor_down_m: float | None = None
    """The floor of the fix's down axis (m; None: sigma_floor_m). A fix's height is the pose
    solve's scale against the reference elevation: a misregistered or seasonally changed map
    moves the fix sideways but not up, so what no solve can average vertically is the
    elevation model's error (a few centimetres over a procedural world's own heights, the
    DEM's vertical accuracy over real terrain), not the horizontal floor."""
    appearance_sigma_m: float | None = None
    """The appearance term of the fix's claim (m, None: none): added in quadrature on every axis,
    appearance_sigma_m * ((1 - quality) / (1 - appearance_ref_quality)) ** appearance_exponent,
    quality the fix's (PositionFix.quality: the matcher's quality, for the area matchers the
    NCC-weighted share of the tiles that agree, times the pose solve's inlier share).
    Why: the pose solve's covariance comes from how the tiles scatter about their consensus, so
    it cannot see an error all tiles share, and the largest such error is the shadows that move
    between the map's date and the image's (every shadow-cast edge moves the same way). The more
    the two differ, the more tiles find another peak than the consensus, and the lower the
    quality; the fixes' error beyond their claim grows as it falls: over 20 procedural worlds
    under random suns, quality 0.45 / 0.6 / 0.8 -> about 1.2 / 0.4 / 0.05 m of error not claimed
    (docs/measurements.md, filter consistency)."""
    appearance_ref_quality: float = pydantic.Field(0.6, ge=0.0, lt=1.0)  # quality at which the term is appearance_sigma_m
    appearance_exponent: float = pydantic.Field(3.0, gt=0.0)  # how steeply it grows as the quality falls
    sigma_img_px: float = 0.5  # image-side noise of a correspondence (full-resolution px)
    heading_from_image: bool = False
    """Give each fix the body heading the image alone fixes (the pose solve's attitude without
    the INS prior) and its sigma, for the navigator to fuse (PositionFix.heading_rad). Across a
    wide nadir view the tiles' rotation pins the heading far better than a magnetometer:
    paper_ismn_800m frames, 100 fixes, 0.013 deg RMS (claimed 0.014 deg) against the filter's
    0.093 deg."""
    heading_floor_deg: float = 0.02
    """Added in quadrature to that heading's sigma: the camera-to-IMU boresight's yaw, which no
    image can see (the simulated mount is exact; a calibrated real one is known to a few
    hundredths of a degree)."""
    pose_from_image: bool = False
    """Give each fix the pose the image alone fixes (PositionFix.image_pos_ned_m, image_R_nb,
    image_pose_cov: the pose solve without the INS prior, its centre-attitude cross terms kept,
    the same floors on the position as the fix's), for a navigator that carries the camera's
    boresight error as states (InsEkfParams.camera_boresight): the image's attitude against the
    INS attitude is what shows that error, and a filter fusing the image's pose does the MAP
    solve's work itself, with the boresight in its prior."""
    attitude_floor_deg: float = pydantic.Field(0.03, ge=0.0)
    """Added in quadrature to each axis of that pose's attitude sigma: what the tiles share
    moves the image-only attitude as it moves the centre, the same from fix to fix over the
    same ground (paper_ismn_800m frames at the true pose: 0.014 / 0.020 / 0.013 deg RMS roll /
    pitch / heading). Taken as white, 0.01 deg left the filter overconfident (paper_ismn_800m
    with camera_boresight, 200 s: attitude NEES 3.6 and position 4.0 for 3 dof, against 2.2 and
    3.5 with 0.03 deg)."""
    max_heading_sigma_deg: float | None = None
    """No fix while the estimate's heading sigma exceeds this (None: always try). A heading error
    rotates the ortho view against the map, and the area matchers search translations: their
    fixes then err by more than they claim (paper_ismn_800m, 20 runs: error/claim 0.94 at a
    heading sigma of 2-3 mrad, 0.66 below 1.5 mrad, i.e. while the magnetometer settles the
    cold-start heading). A vehicle can wait for its heading before it trusts scene matching."""
    cloud_mask: CloudMaskParams | None = None
    """Mask the frame's clouds before matching, found from the pixels alone (bright and grey,
    grown by a margin: ismn.cloud_mask), and try no match where they hide more than
    cloud_mask.max_share of it; None: match every pixel. On this project's rendered clouds the
    tiles' homography consensus already refuses most cloud edges: six paired 200 s flights under
    70 % cover (paper_ismn_clouds) gained nothing significant from it (docs/measurements.md,
    "Scene matching under clouds"); it is there for clouds whose edges a matcher takes."""
    readout_s: float | None = pydantic.Field(None, ge=0, le=0.1)
    """The camera's rolling-shutter readout the pose solve models (s; ismn.rolling): each
    correspondence is seen from the pose the estimate's velocity and body rate give at its
    row's exposure time, and the pose solved for is the middle row's (the frame's). None: the
    camera's own (CameraParams.readout_s: a datasheet figure, known onboard as the intrinsics
    are); 0: solve as for a global shutter. At 800 m in a 30 deg bank turn, a 30 ms readout
    solved as a global shutter bends the frame by about 2.6 m at its ends."""
    rolling_shutter_ortho: bool = False
    """With a rolling shutter (readout_s > 0), also warp the ortho view row by row: each ground
    point taken from the row that saw it (ismn.rolling.RowMotion.project), a remap as over
    relief, instead of the middle row's homography. The pose solve models the rows either way
    (its correspondences are exact whichever warp made the ortho view); the row-wise warp
    straightens what the tiles see, which matters where the rows' turn moves the frame's ends
    by several pixels (a multirotor yawing fast: 1 rad/s over 30 ms is 8 px at a 1080-row
    frame's ends). In the paper's turns (1.8 px), ten runs: the turns' fixes 0.723 m against
    0.836 m without it (0.703 m with a global shutter), the navigation no better, the latency
    p95 about twice (one run pinned to a core: 144 ms against 57 ms; docs/measurements.md, "A
    rolling shutter")."""
    max_jump_factor: float = 1.5  # reject fixes farther from the estimate than this x window margin
    thumb_px: int = 320  # width of the frame thumbnail kept in the diagnostics
    keep_images: bool = True  # keep ortho / map window / thumbnail in the diagnostics
    cache_map: bool = True  # serve search windows from a larger cached map read (see mapcache)


def _heading_sigma_rad(estimate: NavEstimate) -> float:
    """1-sigma (rad) of the heading of an estimate: its attitude covariance's down-axis part
    (NED small angles)."""
    return math.sqrt(max(float(np.asarray(estimate.cov_att_rad2, float)[2, 2]), 0.0))


def with_camera_readout(params: IsmnParams, camera_sensor) -> IsmnParams:
    """params with readout_s None resolved to the camera sensor's own (CameraParams.readout_s;
    0 for a sensor without one)."""
    if params.readout_s is not None:
        return params
    readout = float(getattr(getattr(camera_sensor, "params", None), "readout_s", 0.0))
    return params.model_copy(update={"readout_s": readout})


class IsmnPipeline:
    """One camera's scene-matching position fixes against an onboard reference map."""

    Params = IsmnParams

    def __init__(self, camera: PinholeCamera, mount: CameraMount, reference_map, elevation=None,
                 matcher=None, params: IsmnParams | None = None):
        self.camera = camera
        self.mount = mount
        self.reference_map = reference_map
        self.elevation = elevation
        self.matcher = matcher if matcher is not None else NccMatcher()
        self.p = params if params is not None else IsmnParams()
        self.ortho = Orthorectifier(camera, math.radians(self.p.max_off_nadir_deg))
        self._maps = MapWindowCache(reference_map) if self.p.cache_map else None

    # -- helpers -------------------------------------------------------------------------------
    def _ground(self, centre, R_nc):
        """(ground_down_m, height_fn or None) under the predicted footprint."""
        flat = -self.p.terrain_height_m
        if self.elevation is None:
            return flat, None
        fp = footprint_bounds(centre, R_nc, self.camera, flat, self.ortho.max_off_nadir_rad)
        if fp is None:
            return flat, None
        pad = 2 * self.p.elevation_gsd_m + 3 * self.p.margin_m
        e = self.elevation.read_local(fp[0] - pad, fp[1] + pad, fp[2] - pad, fp[3] + pad, self.p.elevation_gsd_m)
        if not e.valid.any():
            return flat, None
        h = e.data.astype(np.float32)
        mean_h = float(h[e.valid].mean())
        if float(h[e.valid].max() - h[e.valid].min()) < self.p.relief_min_span_m:
            return -mean_h, None
        filled = np.where(e.valid, h, np.float32(mean_h)).astype(np.float32)

        def height_fn(north, east):
            """NED down (m) of the terrain at (north, east), bilinear."""
            r, c = e.ne_to_rowcol(north, east)
            v = cv2.remap(filled, np.asarray(c, np.float32).reshape(-1, 1), np.asarray(r, np.float32).reshape(-1, 1),
                          cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
            return -v.reshape(np.shape(north)).astype(float)

        return -mean_h, height_fn

    def _gsd(self, height_m: float, fp) -> float:
        rm = self.reference_map
        g = self.p.gsd_m or getattr(rm, "gsd_m", None) or getattr(rm, "native_gsd_m", None) or nadir_gsd_m(self.camera, height_m)
        g = max(float(g), nadir_gsd_m(self.camera, height_m) if self.p.gsd_m is None else 0.0)
        extent = max(fp[1] - fp[0], fp[3] - fp[2])
        # Quantised (steps of 2^(1/8)) so that successive frames share the cached map window.
        native = self.p.gsd_m or getattr(rm, "gsd_m", None) or getattr(rm, "native_gsd_m", None)
        return quantise_gsd(max(g, extent / self.p.max_ortho_px), native)

    def _seed(self, estimate: NavEstimate, R_nb: np.ndarray) -> tuple[CameraMount, NavEstimate]:
        """The mounting and the estimate the solve is seeded with: the calibrated mounting and
        the estimate itself, or, when the navigator estimates the camera's boresight
        (NavEstimate.camera_boresight_b_rad, body axes), the mounting corrected by it and the
        estimate's attitude covariance widened by its uncertainty in NED (C P_b C^T): the
        camera's attitude is what the window, the ortho view and the prior need."""
        b = estimate.camera_boresight_b_rad
        if b is None:
            return self.mount, estimate
        mount = CameraMount(quat_to_dcm(rotvec_to_quat(np.asarray(b, float))) @ self.mount.R_bc, self.mount.lever_arm_b_m)
        cov_att = (np.asarray(estimate.cov_att_rad2, float)
                   + R_nb @ np.asarray(estimate.cov_camera_boresight_rad2, float) @ R_nb.T)
        return mount, dataclasses.replace(estimate, cov_att_rad2=cov_att)

    def _image_pose(self, sol, R_nc_seed: np.ndarray, floor_ned_m2: np.ndarray):
        """(body position (3,) NED m, R_nb (3, 3), covariance (6, 6)) of the image-only pose of
        the solve `sol` (seeded with the camera attitude R_nc_seed (3, 3), camera -> NED)
        through the calibrated mount (PositionFix.image_*), the position floors
        floor_ned_m2 (3, 3) and attitude_floor_deg added; (None, None, None) when the image
        alone does not fix the pose."""
        if sol.centre_img_ned_m is None:
            return None, None, None
        # Through the calibrated mounting, whatever the seed's (the navigator's measurement model).
        R_nb = quat_to_dcm(rotvec_to_quat(sol.att_img_ned_rad)) @ R_nc_seed @ self.mount.R_bc.T
        lever = np.asarray(self.mount.lever_arm_b_m, float)
        pos = sol.centre_img_ned_m - R_nb @ lever
        cov = np.array(sol.cov_pose_img, float)
        cov[:3, :3] += floor_ned_m2
        cov[3:, 3:] += math.radians(self.p.attitude_floor_deg) ** 2 * np.eye(3)
        return pos, R_nb, cov

    def _solve_K(self, estimate: NavEstimate) -> np.ndarray:
        """(3, 3) the intrinsics the pose is solved with: the calibrated K, corrected by the
        navigator's estimate of its error (NavEstimate.camera_intrinsics_error: principal point
        and focal length) when it carries one. The ortho view keeps the calibrated K: its
        correspondences are image pixels whichever K drew the view."""
        K = self.camera.K
        err = estimate.camera_intrinsics_error
        if err is not None:
            K = K.copy()
            K[0, 0] *= 1.0 + float(err[2])
            K[1, 1] *= 1.0 + float(err[2])
            K[0, 2] += float(err[0])
            K[1, 2] += float(err[1])
        return K

    def _row_motion(self, estimate: NavEstimate, R_nb: np.ndarray, mount: CameraMount) -> RowMotion | None:
        """The camera's motion over a rolling shutter's readout (IsmnParams.readout_s), from the
        estimate: its velocity (with the lever arm's turn) and body rate in NED. None with a
        global shutter."""
        readout = self.p.readout_s or 0.0
        if readout <= 0.0:
            return None
        omega_n = R_nb @ np.asarray(estimate.omega_b_rps, float)
        vel_c = np.asarray(estimate.vel_ned_mps, float) + np.cross(omega_n, R_nb @ np.asarray(mount.lever_arm_b_m, float))
        return RowMotion(self.camera, readout, vel_c, omega_n)

    def _appearance_sigma_m(self, quality: float) -> float:
        """The appearance term of the claim (m) at a fix's quality (IsmnParams.appearance_sigma_m)."""
        p = self.p
        if p.appearance_sigma_m is None:
            return 0.0
        return p.appearance_sigma_m * appearance_gain(quality, p.appearance_ref_quality, p.appearance_exponent)

    # -- the pipeline --------------------------------------------------------------------------
    def process(self, frame_image: np.ndarray, t_s: float, estimate: NavEstimate) -> tuple[PositionFix | None, IsmnDiagnostics]:
        """One frame -> (PositionFix or None, IsmnDiagnostics). frame_image (H, W[, 3]) uint8."""
        lat = {}
        t0 = time.perf_counter()
        p = self.p
        pos, R_nb = estimate_pose(estimate)
        # The heading gate reads the INS's own heading: a boresight's yaw is learnt from the
        # fixes alone, and a gate on the camera's would wait for it for ever.
        heading_sigma = _heading_sigma_rad(estimate)
        mount, estimate = self._seed(estimate, R_nb)
        centre, R_nc = camera_pose_ned(pos, R_nb, mount)
        ground_down, height_fn = self._ground(centre, R_nc)
        height = ground_down - centre[2]
        fp = footprint_bounds(centre, R_nc, self.camera, ground_down, self.ortho.max_off_nadir_rad)

        def fail(reason, **kw):
            lat["total"] = sum(lat.values())
            return None, IsmnDiagnostics(t_s, dict(lat), reason=reason, **kw)

        if height <= 0 or fp is None:
            lat["window"] = 1e3 * (time.perf_counter() - t0)
            return fail("camera sees no ground")
        if p.max_heading_sigma_deg is not None and heading_sigma > math.radians(p.max_heading_sigma_deg):
            lat["window"] = 1e3 * (time.perf_counter() - t0)
            return fail(f"heading sigma {math.degrees(heading_sigma):.2f} deg > {p.max_heading_sigma_deg} deg: "
                        "waiting for the heading to settle", attempted=False)
        g = self._gsd(height, fp)
        win = predict_search_window(estimate, self.camera, mount, ground_down, g, n_sigma=p.n_sigma,
                                    margin_m=p.margin_m, max_off_nadir_rad=self.ortho.max_off_nadir_rad)
        b = win.bounds_ne_m
        if self._maps is not None:
            mapw = self._maps.read(b[0], b[1], b[2], b[3], g)
        else:
            mapw = self.reference_map.read_local(b[0], b[1], b[2], b[3], g)
        g = mapw.gsd_m
        Hw, Ww = mapw.shape
        r0 = max(0, int(math.floor((mapw.north0_m - fp[1]) / g)))
        c0 = max(0, int(math.floor((fp[2] - mapw.east0_m) / g)))
        Ho = min(Hw - r0, int(math.ceil((fp[1] - fp[0]) / g)))
        Wo = min(Ww - c0, int(math.ceil((fp[3] - fp[2]) / g)))
        map_grey = to_grey_u8(mapw.data)
        kind = getattr(getattr(self.matcher, "p", None), "feature", None)
        if self._maps is not None and isinstance(kind, str):
            self._maps.features(mapw, kind)  # once per cached read: part of the map access
        t1 = time.perf_counter()
        lat["window"] = 1e3 * (t1 - t0)
        if Ho < 16 or Wo < 16 or cv2.countNonZero(np.asarray(mapw.valid, bool).view(np.uint8)) < 0.05 * mapw.valid.size:
            return fail("search window off the reference map", window=win)

        nodata = None
        if p.cloud_mask is not None:
            nodata = cloud_mask(frame_image, p.cloud_mask)
            share = float(np.count_nonzero(nodata)) / nodata.size
            if share > p.cloud_mask.max_share:
                lat["ortho"] = 1e3 * (time.perf_counter() - t1)
                return fail(f"clouds hide {100 * share:.0f} % of the frame", window=win)
        small, K_s = self.ortho.prepare(frame_image, nadir_gsd_m(self.camera, height) / g, nodata)
        motion = self._row_motion(estimate, R_nb, mount)
        of = self.ortho.rectify(small, K_s, centre, R_nc, mapw.north0_m - r0 * g, mapw.east0_m + c0 * g, g,
                                (Ho, Wo), (c0, r0), ground_down, height_fn, motion if p.rolling_shutter_ortho else None)
        t2 = time.perf_counter()
        lat["ortho"] = 1e3 * (t2 - t1)

        feats = levels = None
        if self._maps is not None:
            def feats(kind, level=0, _w=mapw):
                return self._maps.features(_w, kind, level)

            def levels(level, _w=mapw):
                return self._maps.pyramid_level(_w, level)
        # A matcher that takes the OrthoFrame warps only what it uses (the area matchers: a
        # coarse level and their tiles); any other gets the whole warped image and its mask.
        lazy = bool(getattr(self.matcher, "accepts_ortho_frame", False))
        # The tiles search as far as the camera's heading is uncertain: the seeded estimate's,
        # with an unlearnt boresight's yaw in it (with the INS's alone, an unlearnt boresight left
        # the first fixes' tiles 20-30 m off at 1.5 deg, and their image pose showing a tenth of it).
        cam_heading_sigma = _heading_sigma_rad(estimate)
        prior = MatchPrior((float(c0), float(r0)), win.margin_m / g, None if lazy else of.valid, mapw.valid, g, feats,
                           cam_heading_sigma, levels)
        res = self.matcher.match(of if lazy else of.image, map_grey, prior)
        t3 = time.perf_counter()
        lat["match"] = 1e3 * (t3 - t2)
        keep = dict(window=win)
        if p.keep_images:
            # The frame, not its thumbnail: IsmnDiagnostics makes that when the report asks.
            # The OrthoFrame, not its image: that is warped only if the report asks for it.
            keep.update(ortho_frame=of, map_window=map_grey, frame=small, thumb_px=p.thumb_px)
        if res is None:
            return fail("no match", **keep)
        off_m = np.array([-res.offset_px[1] * g, res.offset_px[0] * g])  # (north, east)
        keep.update(peak_quality=res.quality, offset_px=res.offset_px, offset_m=off_m)
        if res.quality < p.min_quality:
            return fail(f"match quality {res.quality:.2f} < {p.min_quality}", **keep)

        # Correspondences: ortho px -> original camera px (through the estimated-pose mapping),
        # map px -> NE of the map window at the terrain height.
        shared_px = 0.0  # error common to every correspondence (one offset for all of them)
        if res.ortho_px is not None and len(res.ortho_px) >= p.min_correspondences:
            o_px, m_px = res.ortho_px, res.map_px
        else:  # area match without tiles: a grid of valid ortho pixels shifted by the offset
            gy, gx = np.mgrid[0:Ho:max(1, Ho // 8), 0:Wo:max(1, Wo // 8)]
            sel = of.valid[gy, gx]
            o_px = np.c_[gx[sel], gy[sel]].astype(float)
            m_px = o_px + np.array([c0, r0]) + res.offset_px
            shared_px = math.sqrt(max(float(np.linalg.eigvalsh(res.cov_px2).max()), 1e-4))
        uv = of.cam_xy_full(o_px[:, 0], o_px[:, 1])
        north, east = mapw.rowcol_to_ne(m_px[:, 1], m_px[:, 0])
        down = np.full_like(north, ground_down) if height_fn is None else height_fn(north, east)
        X = np.c_[north, east, down]
        sigma_px = math.sqrt(max(float(np.linalg.eigvalsh(res.cov_px2).max()), 1e-4))
        # The INS attitude as a prior, widened by a floor: a filter that is too sure of its
        # attitude would otherwise turn its attitude error into a position error of the fix.
        att_cov = (np.asarray(estimate.cov_att_rad2, float) + math.radians(p.att_prior_floor_deg) ** 2 * np.eye(3)
                   if p.use_attitude_prior else None)
        # Where the estimate put each ortho pixel's ground: the solve starts from the match's
        # offset when the estimate is too far off for it to converge from there (a cold start).
        pred_north, pred_east = mapw.rowcol_to_ne(o_px[:, 1] + r0, o_px[:, 0] + c0)
        c_seed = seed_centre(centre, height, north - pred_north, east - pred_east)
        sol = solve_camera_pose(X, uv, self._solve_K(estimate), c_seed, R_nc, sigma_px * g, att_cov,
                                sigma_img_px=p.sigma_img_px, method=p.pose_method,
                                point_poses=None if motion is None else motion.point_poses(uv))
        t4 = time.perf_counter()
        lat["pose"] = 1e3 * (t4 - t3)
        keep.update(n_correspondences=len(X))
        if sol is None:
            return fail("pose solve failed", **keep)
        keep.update(n_inliers=int(sol.inliers.sum()))
        R_nb_fix = sol.R_nc @ mount.R_bc.T  # camera->NED times body->camera
        pos_fix = sol.centre_ned_m - R_nb_fix @ np.asarray(mount.lever_arm_b_m, float)
        jump = float(np.hypot(*(pos_fix[:2] - pos[:2])))
        if jump > p.max_jump_factor * win.margin_m + 2 * g:
            return fail(f"fix {jump:.0f} m from the estimate, outside the search window", **keep)
        # Errors the solve cannot average are added: sigma_floor_m (map georeference, unmodelled
        # relief, what the tiles share), without tiles the one offset all points share, and the
        # appearance term (what the tiles share under changed shadows, larger as fewer agree).
        floor_down_m = p.sigma_floor_m if p.sigma_floor_down_m is None else p.sigma_floor_down_m
        quality = float(res.quality * sol.inliers.mean())
        floor = (np.diag([p.sigma_floor_m**2, p.sigma_floor_m**2, floor_down_m**2])
                 + ((shared_px * g) ** 2 + self._appearance_sigma_m(quality) ** 2) * np.eye(3))
        cov = sol.cov_centre_m2 + floor
        lat["total"] = sum(lat.values())
        lat["ortho_to_fix"] = lat["ortho"] + lat["match"] + lat["pose"]
        coupled = att_cov is not None
        heading = heading_sigma = None
        if p.heading_from_image and sol.att_img_ned_rad is not None:
            heading, heading_sigma = image_heading(sol.att_img_ned_rad, sol.cov_att_img_rad2, R_nb)
            heading_sigma = math.hypot(heading_sigma, math.radians(p.heading_floor_deg))
        # Without tiles the correspondences are the seed's own ortho grid shifted by one offset:
        # they hold the seed's attitude, not the image's, so there is no image-only pose to give.
        tiled = shared_px == 0.0
        image_pose = self._image_pose(sol, R_nc, floor) if p.pose_from_image and tiled else (None, None, None)
        fix = PositionFix(float(t_s), pos_fix, cov, quality, "ismn",
                          att_sensitivity_m_per_rad=sol.att_sensitivity_m_per_rad if coupled else None,
                          cov_given_att_ned_m2=sol.cov_centre_given_att_m2 + floor if coupled else None,
                          heading_rad=heading, heading_sigma_rad=heading_sigma,
                          image_pos_ned_m=image_pose[0], image_R_nb=image_pose[1], image_pose_cov=image_pose[2],
                          intrinsics_sensitivity=sol.intrinsics_sensitivity)
        return fix, IsmnDiagnostics(t_s, dict(lat), **{**keep, "peak_quality": quality})
