"""`testbench locate`: single-image localisation of a real photo against a real map (ISMN).

    testbench locate --map MAP.tif --image IMG --camera CAM.yaml --altitude-agl-m H
                     --attitude-deg ROLL,PITCH,YAW [--prior-lat-lon LAT,LON --prior-radius-m R]
                     [--matcher ncc|phase|orb|sift]

CAM.yaml: width, height and either hfov_deg or fx, fy, cx, cy; optional dist [k1, k2, p1, p2,
k3]; mount_roll_deg, mount_pitch_deg (default -90: nadir), mount_yaw_deg; lever_arm_b_m [x, y, z].
The ground is taken flat at the prior's (or map centre's) altitude, H metres below the camera.
Without a prior the whole map is searched at a coarse resolution first, then refined.
Prints one JSON object: lat_deg, lon_deg, sigma_h_m, quality, time_ms (and the NED fix).
Exit 0 found; 3 not found (the JSON says found: false and why, and so does one line on stderr);
2 bad input (a prior circle that misses the map among them).
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from testbench.core.errors import EXIT_THRESHOLD_FAILED, InputError


def register(subparsers) -> None:
    p = subparsers.add_parser("locate", help="locate one photo on a georeferenced map (scene matching)")
    p.add_argument("--map", required=True, help="reference map GeoTIFF")
    p.add_argument("--image", required=True, help="camera image (any format OpenCV reads)")
    p.add_argument("--camera", required=True, help="camera YAML (width, height, hfov_deg or fx/fy/cx/cy, ...)")
    p.add_argument("--altitude-agl-m", type=float, required=True, help="camera height above the ground (m)")
    p.add_argument("--attitude-deg", required=True, help="ROLL,PITCH,YAW of the vehicle (deg)")
    p.add_argument("--prior-lat-lon", default=None, help="LAT,LON of the prior position (deg)")
    p.add_argument("--prior-radius-m", type=float, default=None, help="prior radius (3 sigma, m)")
    p.add_argument("--matcher", default="ncc", choices=["ncc", "phase", "orb", "sift"])
    p.set_defaults(handler=_locate)


def _floats(text: str, n: int, name: str) -> list[float]:
    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        vals = []
    if len(vals) != n:
        raise InputError(f"{name}: expected {n} comma-separated numbers, got {text!r}")
    return vals


def load_camera(path: str):
    """(PinholeCamera, CameraMount) from a camera YAML file."""
    import yaml

    from testbench.core.camera_geometry import CameraMount, PinholeCamera, mount_rotation

    try:
        cfg = yaml.safe_load(Path(path).read_text()) or {}
    except OSError as exc:
        raise InputError(f"{path}: cannot read camera file ({exc.strerror})") from None
    except yaml.YAMLError as exc:
        raise InputError(f"{path}: not valid YAML ({str(exc).splitlines()[0]})") from None
    if not isinstance(cfg, dict):
        raise InputError(f"{path}: expected a mapping of camera keys")
    known = {"width", "height", "hfov_deg", "fx", "fy", "cx", "cy", "dist", "mount_roll_deg", "mount_pitch_deg",
             "mount_yaw_deg", "lever_arm_b_m"}
    for key in cfg:
        if key not in known:
            raise InputError(f"{path}: unknown key {key!r}; expected one of {sorted(known)}")
    try:
        w, h = int(cfg["width"]), int(cfg["height"])
        dist = tuple(float(v) for v in cfg.get("dist", [0.0] * 5)) + (0.0,) * 5
        dist = dist[:5]
        if "hfov_deg" in cfg:
            cam = PinholeCamera.from_hfov(w, h, float(cfg["hfov_deg"]), dist)
        else:
            cam = PinholeCamera(w, h, float(cfg["fx"]), float(cfg["fy"]), float(cfg["cx"]), float(cfg["cy"]), dist)
        R_bc = mount_rotation(float(cfg.get("mount_roll_deg", 0.0)), float(cfg.get("mount_pitch_deg", -90.0)),
                              float(cfg.get("mount_yaw_deg", 0.0)))
        lever = np.asarray(cfg.get("lever_arm_b_m", [0.0, 0.0, 0.0]), float).reshape(3)
    except KeyError as exc:
        raise InputError(f"{path}: missing key {exc.args[0]!r} (need width, height and hfov_deg or fx, fy, cx, cy)") from None
    except (TypeError, ValueError) as exc:
        raise InputError(f"{path}: bad camera value ({exc})") from None
    return cam, CameraMount(R_bc, lever)


def _locate(args) -> int:
    import cv2

    from testbench.core.geodesy import ned_to_geodetic
    from testbench.core.interfaces import GeodeticOrigin
    from testbench.core.messages import NavEstimate
    from testbench.core.registry import build
    from testbench.core.rotations import euler_to_quat
    from testbench.navigation.ismn import IsmnParams, IsmnPipeline
    from testbench.world.geotiff import map_centre_lat_lon_deg
    from testbench.world.imagery import MapSource

    t0 = time.perf_counter()
    roll, pitch, yaw = _floats(args.attitude_deg, 3, "--attitude-deg")
    if args.altitude_agl_m <= 0:
        raise InputError(f"--altitude-agl-m: expected a positive height, got {args.altitude_agl_m}")
    cam, mount = load_camera(args.camera)
    img = cv2.imread(args.image, cv2.IMREAD_COLOR)
    if img is None:
        raise InputError(f"--image {args.image}: cannot read the image")
    if img.shape[:2] != (cam.height_px, cam.width_px):
        raise InputError(f"--image {args.image}: size {img.shape[1]}x{img.shape[0]} differs from the camera's "
                         f"{cam.width_px}x{cam.height_px} ({args.camera})")
    img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    if args.prior_lat_lon is not None:
        lat, lon = _floats(args.prior_lat_lon, 2, "--prior-lat-lon")
        radius = args.prior_radius_m if args.prior_radius_m is not None else 200.0
        if radius <= 0:
            raise InputError(f"--prior-radius-m: expected a positive radius, got {radius}")
    else:
        lat, lon = map_centre_lat_lon_deg(args.map, "--map")
        radius = None
    if radius is not None:
        _check_prior_on_map(args.map, lat, lon, radius)
    origin = GeodeticOrigin(math.radians(lat), math.radians(lon), 0.0)
    rpy = np.radians([roll, pitch, yaw])
    matcher = build("matcher", args.matcher, None, where="--matcher", ctx=None)

    def estimate(pos_ne, sigma):
        return NavEstimate(0.0, np.r_[pos_ne, -args.altitude_agl_m], np.zeros(3), euler_to_quat(rpy), rpy,
                           np.zeros(3), np.diag([sigma**2, sigma**2, 1.0]), np.eye(3),
                           np.eye(3) * math.radians(1.0) ** 2)

    with MapSource(args.map, origin) as ref:
        pos_ne = np.zeros(2)
        native = float(ref.native_gsd_m)
        if radius is None:  # whole map, coarse: window = the map, then refine around the result
            fp = ref.footprint
            half = 0.5 * math.hypot(fp.north_max_m - fp.north_min_m, fp.east_max_m - fp.east_min_m)
            pos_ne = np.array([(fp.north_min_m + fp.north_max_m) / 2, (fp.east_min_m + fp.east_max_m) / 2])
            coarse = IsmnParams(gsd_m=max(native, 2 * half / 600.0), margin_m=0.0, min_quality=0.05,
                                keep_images=False)
            fix, diag = IsmnPipeline(cam, mount, ref, None, matcher, coarse).process(img, 0.0, estimate(pos_ne, half / 3))
            if fix is None:
                return _not_found(args, f"not found on the whole map ({diag.reason}); give --prior-lat-lon", t0)
            pos_ne = fix.pos_ned_m[:2]
            radius = max(30.0, 3.0 * math.sqrt(max(fix.cov_ned_m2[0, 0], fix.cov_ned_m2[1, 1])))
        fine = IsmnParams(gsd_m=native, keep_images=False, margin_m=10.0)
        fix, diag = IsmnPipeline(cam, mount, ref, None, matcher, fine).process(img, 0.0, estimate(pos_ne, radius / 3.0))
    elapsed_ms = 1e3 * (time.perf_counter() - t0)
    if fix is None:
        return _not_found(args, diag.reason, t0)
    lat_r, lon_r, _ = ned_to_geodetic(fix.pos_ned_m, origin.lat_rad, origin.lon_rad, origin.alt_m)
    sigma_h = math.sqrt(float(np.linalg.eigvalsh(fix.cov_ned_m2[:2, :2]).max()))
    print(json.dumps({
        "found": True, "lat_deg": round(math.degrees(float(lat_r)), 8), "lon_deg": round(math.degrees(float(lon_r)), 8),
        "sigma_h_m": round(sigma_h, 2), "quality": round(fix.quality, 3), "time_ms": round(elapsed_ms, 1),
        "matcher": args.matcher, "pos_ned_m": [round(float(v), 2) for v in fix.pos_ned_m],
        "match_ms": {k: round(v, 1) for k, v in diag.latency_ms.items()},
    }))
    return 0


def _not_found(args, reason: str, t0: float) -> int:
    """found: false on stdout (the one JSON object) and on stderr; exit 3."""
    import sys

    print(json.dumps({"found": False, "reason": reason, "time_ms": round(1e3 * (time.perf_counter() - t0), 1)}))
    print(f"testbench locate: --image {args.image}: {reason}", file=sys.stderr)
    return EXIT_THRESHOLD_FAILED


def _check_prior_on_map(map_path: str, lat_deg: float, lon_deg: float, radius_m: float) -> None:
    """InputError when the prior circle (radius_m about LAT, LON) does not reach the map."""
    from testbench.core.geodesy import geodetic_to_ned
    from testbench.core.interfaces import GeodeticOrigin
    from testbench.world.geotiff import map_centre_lat_lon_deg
    from testbench.world.imagery import MapSource

    if not (-90.0 <= lat_deg <= 90.0 and -180.0 <= lon_deg <= 360.0):
        raise InputError(f"--prior-lat-lon {lat_deg},{lon_deg}: expected a latitude in [-90, 90] and a longitude "
                         "in degrees")
    c_lat, c_lon = map_centre_lat_lon_deg(map_path, "--map")
    centre = GeodeticOrigin(math.radians(c_lat), math.radians(c_lon), 0.0)
    n, e, _ = geodetic_to_ned(math.radians(lat_deg), math.radians(lon_deg), 0.0, centre.lat_rad, centre.lon_rad, 0.0)
    with MapSource(map_path, centre, what="--map") as ref:
        fp = ref.footprint
    # Distance from the prior to the map's bounding box in the map centre's local frame.
    gap_m = math.hypot(max(fp.north_min_m - n, 0.0, n - fp.north_max_m), max(fp.east_min_m - e, 0.0, e - fp.east_max_m))
    if gap_m > radius_m:
        raise InputError(f"--prior-lat-lon {lat_deg},{lon_deg}: {gap_m / 1e3:.1f} km off the map, beyond "
                         f"--prior-radius-m {radius_m:g} (the map's centre is at {c_lat:.5f},{c_lon:.5f})")
