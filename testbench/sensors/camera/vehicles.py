"""Other vehicles as small shaded 3D shapes with LED markers, and their truth in the frame.

Shapes are lists of planar faces in body FRD coordinates scaled by the vehicle's size; each
face is projected through the full camera model (lens distortion included, through
cv2.projectPoints), shaded by a fixed sun (Lambert plus ambient), culled when it faces away,
and drawn far-to-near (painter's order over all vehicles) as an anti-aliased filled polygon.
LEDs are discs at known body positions drawn bright when on and as dark lenses when off.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Callable, Sequence

import cv2
import numpy as np

from testbench.core.camera_geometry import PinholeCamera
from testbench.core.obstacles import first_hit
from testbench.sensors.camera.lens import project_points
from testbench.sensors.camera.types import VehicleAppearance, VehicleTruth

# Unit vector towards the sun in NED: azimuth 135 deg (south-east), elevation 50 deg.
SUN_NED = np.array([np.cos(np.radians(50)) * np.cos(np.radians(135)),
                    np.cos(np.radians(50)) * np.sin(np.radians(135)), -np.sin(np.radians(50))])
_SHIFT = 4  # sub-pixel bits for cv2 drawing
# Draw item kinds: a face, a far vehicle's whole silhouette (its convex hull, which covers its
# own outboard LEDs without hiding them), an LED.
_FACE, _SILHOUETTE, _LED = 0, 2, 1
_LED_OFF_RGB = (35, 35, 38)


def _box(centre, half, yaw_rad: float = 0.0, shade: float = 1.0):
    """Six outward-facing quads of a box (body axes), optionally yawed about body z."""
    c = np.asarray(centre, float)
    hx, hy, hz = half
    cy, sy = np.cos(yaw_rad), np.sin(yaw_rad)
    R = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    signs = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                      [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], float)
    v = c + (signs * [hx, hy, hz]) @ R.T
    quads = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (2, 3, 7, 6), (1, 2, 6, 5), (0, 4, 7, 3)]
    faces = []
    for q in quads:
        pts = v[list(q)]
        n = np.cross(pts[1] - pts[0], pts[2] - pts[0])
        if np.dot(n, pts.mean(axis=0) - c) < 0:
            n = -n
        faces.append((pts, n / np.linalg.norm(n), shade, True))
    return faces


def _disc(centre, radius: float, shade: float, n_sides: int = 12):
    """A horizontal disc (rotor), visible from both sides."""
    a = np.linspace(0, 2 * np.pi, n_sides, endpoint=False)
    pts = np.asarray(centre, float) + radius * np.stack([np.cos(a), np.sin(a), 0 * a], axis=1)
    return [(pts, np.array([0.0, 0.0, -1.0]), shade, False)]


@lru_cache(maxsize=32)
def shape_faces(kind: str, size_m: float):
    """Faces (vertices (n, 3) body m, outward normal (3,), shade factor, one-sided) of a shape."""
    s = float(size_m)
    if kind == "quad":
        arm = 0.33 * s
        faces = _box((0, 0, 0), (0.12 * s, 0.09 * s, 0.05 * s))
        for ang in (45.0, 135.0, 225.0, 315.0):
            a = np.radians(ang)
            mid = 0.5 * arm * np.array([np.cos(a), np.sin(a), 0.0])
            faces += _box(mid, (0.5 * arm, 0.02 * s, 0.015 * s), yaw_rad=a)
            tip = arm * np.array([np.cos(a), np.sin(a), 0.0])
            faces += _box(tip + [0, 0, -0.03 * s], (0.025 * s, 0.025 * s, 0.03 * s), shade=0.5)
            faces += _disc(tip + [0, 0, -0.065 * s], 0.16 * s, 0.35)
        return tuple(faces)
    if kind == "fixed_wing":
        faces = _box((0.02 * s, 0, 0), (0.28 * s, 0.04 * s, 0.045 * s))
        faces += _box((0.05 * s, 0, -0.05 * s), (0.07 * s, 0.5 * s, 0.008 * s))
        faces += _box((-0.25 * s, 0, -0.02 * s), (0.045 * s, 0.16 * s, 0.006 * s))
        faces += _box((-0.25 * s, 0, -0.1 * s), (0.05 * s, 0.006 * s, 0.06 * s))
        return tuple(faces)
    if kind == "box":
        return tuple(_box((0, 0, 0), (0.5 * s, 0.5 * s, 0.5 * s)))
    raise ValueError(f"vehicle shape must be quad, fixed_wing or box (got {kind!r})")


@lru_cache(maxsize=32)
def shape_arrays(kind: str, size_m: float):
    """The faces of a shape as arrays: vertices (V, 3) body m, face slices into them, face
    centroids (F, 3), outward normals (F, 3), shade factors (F,), one-sided flags (F,)."""
    faces = shape_faces(kind, size_m)
    verts = np.concatenate([fv for fv, _, _, _ in faces])
    bounds = np.cumsum([0] + [len(fv) for fv, _, _, _ in faces])
    slices = tuple(slice(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:]))
    centroids = np.array([fv.mean(axis=0) for fv, _, _, _ in faces])
    normals = np.array([n for _, n, _, _ in faces])
    shades = np.array([sh for _, _, sh, _ in faces])
    one_sided = np.array([o for _, _, _, o in faces], bool)
    return verts, slices, centroids, normals, shades, one_sided


# Below this projected size (px) a vehicle is drawn as one silhouette (its convex hull) in
# its mean shaded colour: its faces would be sub-pixel anyway.
_SILHOUETTE_PX = 6.0


@dataclass(frozen=True)
class _FrameProjection:
    """Every vehicle of one frame projected once (the frame's regions of interest reuse it).

    truths: each vehicle's VehicleTruth before terrain occlusion (visible: in front of the
    camera with a non-empty box clipped to the frame); centre_z (n,) camera depth of each
    centre (m); centre_px_clipped (n, 2): the centre pixel clamped into the frame, where
    terrain occlusion is looked up; uv (N, 2) full-frame px and z (N,) camera depth (m) of all
    shape vertices, vehicle after vehicle from vert_bounds (n + 1,); led_z: each vehicle's LED
    depths (m); C (3,) the optical centre (NED m); focal_px; near_m; items: each vehicle's
    draw items, made the first time a region needs them (draw_items).
    """

    vehicles: Sequence[VehicleAppearance]
    truths: tuple[VehicleTruth, ...]
    centre_z: np.ndarray
    centre_px_clipped: np.ndarray
    uv: np.ndarray
    z: np.ndarray
    vert_bounds: np.ndarray
    led_z: tuple[np.ndarray, ...]
    C: np.ndarray
    focal_px: float
    near_m: float
    items: dict = field(default_factory=dict)

    def draw_items(self, j: int) -> list:
        """Vehicle j's faces (shaded, back faces culled) and LEDs as (depth m, kind, payload, j):
        kind _FACE or _SILHOUETTE a filled polygon (vertices (k, 2) full-frame px, RGB), _LED
        an LED ((u, v) px, radius px, on, RGB)."""
        if j not in self.items:
            self.items[j] = self._make_items(j)
        return self.items[j]

    def _make_items(self, j: int) -> list:
        veh, tr, C = self.vehicles[j], self.truths[j], self.C
        p = np.asarray(veh.pos_ned_m, float)
        R_nb = np.asarray(veh.R_nb, float)
        _, slices, centroids_b, normals_b, shades, one_sided = shape_arrays(veh.shape, float(veh.size_m))
        a, b = self.vert_bounds[j], self.vert_bounds[j + 1]
        uv, z = self.uv[a:b], self.z[a:b]
        bbox = tr.bbox_px
        items = []
        # Face lighting, vectorised: normals and centroids to NED, back faces culled.
        n_n = normals_b @ R_nb.T
        c_n = p + centroids_b @ R_nb.T
        facing = np.einsum("ij,ij->i", n_n, c_n - C)
        lit_n = np.where(one_sided[:, None], n_n, -np.sign(facing)[:, None] * n_n)
        light = 0.45 + 0.55 * np.maximum(0.0, lit_n @ SUN_NED)
        show = ~(one_sided & (facing >= 0))
        base = np.asarray(veh.colour_rgb, float)
        if max(bbox[2] - bbox[0], bbox[3] - bbox[1]) < _SILHOUETTE_PX:
            hull = cv2.convexHull(uv.astype(np.float32)).reshape(-1, 2).astype(float)
            col = tuple(float(x) for x in np.minimum(255.0, base * float(np.mean((light * shades)[show]))))
            items.append((float(self.centre_z[j]), _SILHOUETTE, (hull, col), j))
        else:
            for i in np.flatnonzero(show):
                sl = slices[i]
                col = tuple(float(x) for x in np.minimum(255.0, base * light[i] * shades[i]))
                items.append((float(z[sl].mean()), _FACE, (uv[sl], col), j))
        led_z = self.led_z[j]
        for i in range(len(led_z)):
            lz = led_z[i]
            if lz <= self.near_m:
                continue
            on = bool(veh.led_on[i]) if i < len(veh.led_on) else False
            colour = veh.led_colours[i] if i < len(veh.led_colours) else (255, 255, 255)
            r_px = max(0.9, veh.led_radius_m * self.focal_px / lz)
            items.append((float(lz) - 1e-3 * veh.size_m, _LED, ((tr.led_px[i, 0], tr.led_px[i, 1]), r_px, on, colour), j))
        return items


# The last frame's projection and what it was made from (camera, pose, vehicles tuple): a
# frame rendered as several regions draws the same vehicles from the same pose each time.
_last_projection: tuple | None = None


def _frozen(a: np.ndarray) -> np.ndarray:
    """a, read-only: truths are shared by every region of a frame."""
    a.flags.writeable = False
    return a


def _project_frame(camera: PinholeCamera, C: np.ndarray, R_nc: np.ndarray,
                   vehicles: Sequence[VehicleAppearance], near_m: float, far_m: float) -> _FrameProjection:
    """One projection (lens.project_points) of every vehicle's vertices, centre and LEDs
    together (a call per vehicle cost more than the drawing in a ten-vehicle swarm), and the
    per-vehicle truths, vectorised over the vehicles."""
    global _last_projection
    # Only an immutable container is recognised again (a list could have changed since).
    cacheable = isinstance(vehicles, tuple)
    last = _last_projection
    if (cacheable and last is not None and last[0] is vehicles and last[1] == camera and last[2] == (near_m, far_m)
            and np.array_equal(last[3], C) and np.array_equal(last[4], R_nc)):
        return last[5]
    W, H = camera.width_px, camera.height_px
    n = len(vehicles)
    verts, leds, counts = [], [], []
    for veh in vehicles:
        p = np.asarray(veh.pos_ned_m, float)
        R_nb = np.asarray(veh.R_nb, float)
        verts_b = shape_arrays(veh.shape, float(veh.size_m))[0]
        leds_b = np.asarray(veh.led_positions_b_m, float).reshape(-1, 3)
        verts.append(p + verts_b @ R_nb.T)
        leds.append(p + leds_b @ R_nb.T)
        counts.append(len(verts_b))
    centres = np.array([np.asarray(v.pos_ned_m, float) for v in vehicles]).reshape(n, 3)
    uv_all, z_all = project_points(camera, C, R_nc, np.vstack(verts + [centres] + leds))
    n_vert = int(sum(counts))
    uv, z = uv_all[:n_vert], z_all[:n_vert]
    bounds = np.cumsum([0] + counts).astype(np.intp)
    starts = bounds[:-1]
    centre_uv, centre_z = uv_all[n_vert:n_vert + n], z_all[n_vert:n_vert + n]
    lo = np.clip(np.minimum.reduceat(uv, starts, axis=0), -0.5, [W - 0.5, H - 0.5])
    hi = np.clip(np.maximum.reduceat(uv, starts, axis=0), -0.5, [W - 0.5, H - 0.5])
    in_front = np.logical_and.reduceat(z > near_m, starts) & (centre_z <= far_m)
    has_area = (in_front & (hi[:, 0] > lo[:, 0]) & (hi[:, 1] > lo[:, 1])).tolist()
    led_uv_all, led_z_all = uv_all[n_vert + n:], z_all[n_vert + n:]
    led_ok = ((led_z_all > near_m) & (led_uv_all[:, 0] >= -0.5) & (led_uv_all[:, 0] < W - 0.5)
              & (led_uv_all[:, 1] >= -0.5) & (led_uv_all[:, 1] < H - 0.5)).tolist()
    truths, led_z, k = [], [], 0
    for j, (veh, arr) in enumerate(zip(vehicles, leds)):
        bbox = (float(lo[j, 0]), float(lo[j, 1]), float(hi[j, 0]), float(hi[j, 1])) if has_area[j] else (0.0, 0.0, 0.0, 0.0)
        truths.append(VehicleTruth(
            veh.id, bbox, _frozen(centre_uv[j].copy()), _frozen(led_uv_all[k:k + len(arr)].copy()),
            tuple(bool(x) for x in veh.led_on), tuple(led_ok[k:k + len(arr)]), has_area[j],
            float(np.linalg.norm(centres[j] - C))))
        led_z.append(led_z_all[k:k + len(arr)])
        k += len(arr)
    clipped = np.c_[np.clip(centre_uv[:, 0], 0, W - 1), np.clip(centre_uv[:, 1], 0, H - 1)]
    proj = _FrameProjection(tuple(vehicles), tuple(truths), centre_z, clipped, uv, z, bounds, tuple(led_z),
                            C.copy(), 0.5 * (camera.fx + camera.fy), near_m)
    if cacheable:
        _last_projection = (vehicles, camera, (near_m, far_m), C.copy(), R_nc.copy(), proj)
    return proj


def draw_vehicles(img: np.ndarray, camera: PinholeCamera, roi_origin: tuple[int, int],
                  centre_ned_m, R_nc, vehicles: Sequence[VehicleAppearance], near_m: float,
                  far_m: float, ground_depth: Callable[[float, float], float] | None,
                  obstacles: Sequence = (),
                  hidden_by: Callable[[np.ndarray, np.ndarray], bool] | None = None) -> tuple[VehicleTruth, ...]:
    """Draw `vehicles` into `img` (the rendered region, top-left at full-frame pixel
    roi_origin) and return their truth in full-frame pixel coordinates (arrays read-only).

    camera: the full-frame camera; ground_depth(u, v): camera depth of the terrain seen at a
    full-frame pixel (inf where sky), used to hide vehicles behind terrain; obstacles: boxes
    (core.obstacles.Obstacle) that hide the vehicles whose centre they stand in front of;
    hidden_by(camera centre, vehicle position), NED m: True where something else lies between
    them (a cloud: world.clouds.CloudView.hides).
    Vehicles whose projection misses the rendered region get their truth but are not drawn.
    """
    if not vehicles:
        return ()
    pr = _project_frame(camera, np.asarray(centre_ned_m, float), np.asarray(R_nc, float), vehicles, near_m, far_m)
    ou, ov = roi_origin
    rh, rw = img.shape[:2]
    items = []  # (depth, kind, payload, vehicle index)
    truths = []
    for j, veh in enumerate(vehicles):
        tr = pr.truths[j]
        if tr.visible and ground_depth is not None:
            cu, cv_ = pr.centre_px_clipped[j]
            if not pr.centre_z[j] < ground_depth(float(cu), float(cv_)):
                tr = replace(tr, visible=False)  # behind the terrain
        if tr.visible and obstacles and first_hit(pr.C, veh.pos_ned_m, obstacles) is not None:
            tr = replace(tr, visible=False)  # behind an obstacle
        if tr.visible and hidden_by is not None and hidden_by(pr.C, np.asarray(veh.pos_ned_m, float)):
            tr = replace(tr, visible=False)  # behind a cloud
        truths.append(tr)
        if not tr.visible:
            continue
        # Cull against the rendered region (LED glow can reach a few pixels beyond the body).
        bbox = tr.bbox_px
        pad = 3.0 * max(1.0, veh.led_radius_m * pr.focal_px / max(float(pr.centre_z[j]), near_m)) + 2.0
        if bbox[2] + pad < ou or bbox[0] - pad > ou + rw or bbox[3] + pad < ov or bbox[1] - pad > ov + rh:
            continue
        items.extend(pr.draw_items(j))
    items.sort(key=lambda it: -it[0])
    _paint(img, items, ou, ov)
    return tuple(truths)


def _paint(img: np.ndarray, items: list, ou: int, ov: int) -> None:
    """Draw the depth-sorted (far first) items into img (the region at full-frame (ou, ov)).

    Faces and LEDs: painter's order. A lit LED's glow is light its core spreads in the camera's
    optics, not a disc in the scene: nearer faces do not cut it unless they hide the core
    itself. (Drawn as a disc in depth order, the vehicle's own hub, seen from level, hid the
    lower half of the top anchor's glow, and the LED detector's centre sat 2.4 px above the
    anchor.) So a lit LED whose projected centre lies inside no nearer face (exact polygons, not
    pixels: at 200 m the anchor is half a pixel above the hub; a vehicle's own silhouette, the
    hull of a far vehicle drawn whole, hides none of its LEDs) gets its glow and core again
    after everything else, far first; one behind a nearer face shows at most its core's edge."""
    scale = 1 << _SHIFT
    origin = np.array([ou, ov], float)
    shown = []  # (centre in 1/2^_SHIFT px, radius px, colour) of the lit LEDs seen
    lit = [i for i, (_, kind, payload, _) in enumerate(items) if kind == _LED and payload[2]]
    polys = [None if k == _LED else pl[0].astype(np.float32) for _, k, pl, _ in items] if lit else []
    for i in lit:
        (lu, lv), r_px, _, colour = items[i][2]
        owner, pt = items[i][3], (float(lu), float(lv))
        hidden = any(polys[m] is not None and not (items[m][1] == _SILHOUETTE and items[m][3] == owner)
                     and cv2.pointPolygonTest(polys[m], pt, False) >= 0 for m in range(i + 1, len(items)))
        if not hidden:
            shown.append(((int(round((lu - ou) * scale)), int(round((lv - ov) * scale))), r_px, colour))
    for _, kind, payload, _ in items:
        if kind != _LED:
            fu, col = payload
            pts = np.round((fu - origin) * scale).astype(np.int32)
            cv2.fillPoly(img, [pts], col, lineType=cv2.LINE_AA, shift=_SHIFT)
        else:  # the LED itself, lit or not, is an object in the scene
            (lu, lv), r_px, on, colour = payload
            c = (int(round((lu - ou) * scale)), int(round((lv - ov) * scale)))
            cv2.circle(img, c, int(round(r_px * scale)), _core_rgb(colour) if on else _LED_OFF_RGB, -1,
                       cv2.LINE_AA, _SHIFT)
    for c, r_px, colour in shown:
        glow = tuple(float(0.6 * x + 0.4 * 255) for x in colour)
        cv2.circle(img, c, int(round(2.2 * r_px * scale)), glow, -1, cv2.LINE_AA, _SHIFT)
        cv2.circle(img, c, int(round(r_px * scale)), _core_rgb(colour), -1, cv2.LINE_AA, _SHIFT)


def _core_rgb(colour) -> tuple[float, float, float]:
    """A lit LED's core: its colour washed towards white (the sensor saturates)."""
    return tuple(float(0.35 * x + 0.65 * 255) for x in colour)
