"""Write procedural worlds as GeoTIFFs georeferenced at the scenario origin.

CRS: local transverse Mercator centred on the origin (x = east, y = north, metres), so local
NE equals projected y/x. Tiled (256), DEFLATE with a predictor, internal overviews (average).
Files are written under a temporary name and renamed (atomic for concurrent readers).
"""

from __future__ import annotations

import os
import tempfile

import numpy as np
import rasterio
from rasterio.enums import Resampling
from rasterio.transform import from_origin
from rasterio.windows import Window

from testbench.core.interfaces import GeodeticOrigin
from testbench.world.georef import local_tmerc_crs

_OVERVIEWS = (2, 4, 8, 16, 32, 64)
_ENV = dict(GDAL_TIFF_INTERNAL_MASK=True, GDAL_CACHEMAX=128)  # MB: bounds GDAL's block cache


def _profile(origin, shape, gsd_m, count, dtype, predictor, nodata=None):
    h, w = shape
    prof = dict(driver="GTiff", width=w, height=h, count=count, dtype=dtype,
                crs=local_tmerc_crs(origin), transform=from_origin(-w * gsd_m / 2, h * gsd_m / 2, gsd_m, gsd_m),
                tiled=True, blockxsize=256, blockysize=256, compress="deflate", zlevel=3,
                predictor=predictor, interleave="pixel" if count > 1 else "band", BIGTIFF="IF_SAFER")
    if nodata is not None:
        prof["nodata"] = nodata
    return prof


def write_geotiff(path, array: np.ndarray, origin: GeodeticOrigin, gsd_m: float,
                  valid: np.ndarray | None = None, nodata=None) -> None:
    """Write (H, W, C) uint8 or (H, W) float32 `array` centred on the origin, atomically.

    valid (H, W) bool: pixels False are written as nodata (float) or masked out (uint8, with
    an internal mask) when given and not all True.
    """
    path = os.fspath(path)
    arr = array if array.ndim == 3 else array[..., None]
    count = arr.shape[2]
    dtype = arr.dtype.name
    predictor = 3 if arr.dtype.kind == "f" else 2
    if valid is not None and not valid.all() and dtype.startswith("float"):
        nodata = -32767.0 if nodata is None else nodata
        arr = np.where(valid[..., None], arr, np.float32(nodata))
    prof = _profile(origin, arr.shape[:2], gsd_m, count, dtype, predictor, nodata)
    d = os.path.dirname(os.path.abspath(path))
    os.makedirs(d, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=".tif", dir=d)
    os.close(fd)
    try:
        with rasterio.Env(**_ENV):
            with rasterio.open(tmp, "w", **prof) as dst:
                h, w = arr.shape[:2]
                for r0 in range(0, h, 1024):  # by windows: no second full-size copy
                    blk = np.ascontiguousarray(np.moveaxis(arr[r0:r0 + 1024], -1, 0))
                    dst.write(blk, window=Window(0, r0, w, blk.shape[1]))
                if valid is not None and not valid.all() and dtype == "uint8":
                    dst.write_mask(valid.astype(np.uint8) * 255)
                if count == 3:
                    dst.colorinterp = [rasterio.enums.ColorInterp.red, rasterio.enums.ColorInterp.green,
                                       rasterio.enums.ColorInterp.blue]
                levels = [f for f in _OVERVIEWS if min(arr.shape[:2]) // f >= 64]
                if levels:
                    dst.build_overviews(levels, Resampling.average)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


def elevation_factor(gsd_m: float) -> int:
    """Elevation is written at an integer multiple of the imagery gsd, at least ~2 m."""
    return max(1, int(np.ceil(2.0 / gsd_m - 1e-9)))


def write_world(out_dir, rgb: np.ndarray, z: np.ndarray, valid: np.ndarray,
                origin: GeodeticOrigin, gsd_m: float) -> tuple[str, str]:
    """Write out_dir/imagery.tif and out_dir/elevation.tif; returns their paths.

    Elevation is averaged down to elevation_factor(gsd_m) x the imagery gsd (a 1 m DEM of
    procedural relief carries nothing a 2 m one lacks) with the same extent.
    """
    import cv2

    img_path = os.path.join(out_dir, "imagery.tif")
    dem_path = os.path.join(out_dir, "elevation.tif")
    f = elevation_factor(gsd_m)
    h, w = z.shape
    if f > 1 and h // f >= 8:
        zc = cv2.resize(z, (w // f, h // f), interpolation=cv2.INTER_AREA)
        gz = gsd_m * w / (w // f)
    else:
        zc, gz = z, gsd_m
    write_geotiff(dem_path, zc.astype(np.float32) + np.float32(origin.alt_m), origin, gz)
    write_geotiff(img_path, rgb, origin, gsd_m, valid)
    return img_path, dem_path


def _tmp_in(d: str) -> str:
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=".tif", dir=d)
    os.close(fd)
    return tmp


def write_world_streamed(out_dir, terrain: str, size_km: float, gsd_m: float, seed: int,
                         season, origin: GeodeticOrigin, preview_px: int = 0):
    """Generate a procedural world band by band straight into out_dir/imagery.tif and
    out_dir/elevation.tif (the same files write_world writes for make_world's arrays, without
    holding the world in memory). preview_px > 0: also return an RGB preview (uint8, about
    preview_px on its longer side, INTER_AREA). Returns (imagery_path, elevation_path, preview
    or None, (z_min_m, z_max_m)).
    """
    import cv2

    from testbench.world.procedural.world import world_bands, world_shape

    h, w = world_shape(terrain, size_km, gsd_m)
    out_dir = os.fspath(out_dir)
    os.makedirs(out_dir, exist_ok=True)
    img_path = os.path.join(out_dir, "imagery.tif")
    dem_path = os.path.join(out_dir, "elevation.tif")
    f = elevation_factor(gsd_m)
    streamed_dem = f == 1 or (256 % f == 0 and h % f == 0 and w % f == 0 and h // f >= 8)
    kp = max(1, max(h, w) // preview_px) if preview_px else 0
    previews, z_full, zr = [], None, [np.inf, -np.inf]
    if not streamed_dem:
        z_full = np.empty((h, w), np.float32)
    tmp_img, tmp_dem = _tmp_in(out_dir), _tmp_in(out_dir)
    try:
        with rasterio.Env(**_ENV):
            pimg = _profile(origin, (h, w), gsd_m, 3, "uint8", 2)
            dem_shape = (h // f, w // f) if f > 1 else (h, w)
            pdem = _profile(origin, dem_shape, gsd_m * f, 1, "float32", 3)
            with rasterio.open(tmp_img, "w", **pimg) as di, \
                    (rasterio.open(tmp_dem, "w", **pdem) if streamed_dem else _Null()) as dd:
                for r0, rgb, z in world_bands(terrain, size_km, gsd_m, seed, season):
                    n = rgb.shape[0]
                    di.write(np.ascontiguousarray(np.moveaxis(rgb, -1, 0)), window=Window(0, r0, w, n))
                    zr[0], zr[1] = min(zr[0], float(z.min())), max(zr[1], float(z.max()))
                    if kp:
                        nn = n // kp
                        if nn:
                            previews.append(cv2.resize(rgb[:nn * kp, :(w // kp) * kp], (w // kp, nn),
                                                       interpolation=cv2.INTER_AREA))
                    zb = z + np.float32(origin.alt_m)
                    if not streamed_dem:
                        z_full[r0:r0 + n] = zb
                    elif f > 1:
                        zc = cv2.resize(zb, (w // f, n // f), interpolation=cv2.INTER_AREA)
                        dd.write(zc[None], window=Window(0, r0 // f, w // f, n // f))
                    else:
                        dd.write(zb[None], window=Window(0, r0, w, n))
                di.colorinterp = [rasterio.enums.ColorInterp.red, rasterio.enums.ColorInterp.green,
                                  rasterio.enums.ColorInterp.blue]
                levels = [k for k in _OVERVIEWS if min(h, w) // k >= 64]
                if levels:
                    di.build_overviews(levels, Resampling.average)
                if streamed_dem:
                    levels = [k for k in _OVERVIEWS if min(dem_shape) // k >= 64]
                    if levels:
                        dd.build_overviews(levels, Resampling.average)
        if not streamed_dem:  # odd sizes: the whole-array path (resampled as write_world does)
            os.remove(tmp_dem)
            tmp_dem = None
            if f > 1 and h // f >= 8:
                zc = cv2.resize(z_full, (w // f, h // f), interpolation=cv2.INTER_AREA)
                gz = gsd_m * w / (w // f)
            else:
                zc, gz = z_full, gsd_m
            del z_full
            write_geotiff(dem_path, zc, origin, gz)
        else:
            os.replace(tmp_dem, dem_path)
            tmp_dem = None
        os.replace(tmp_img, img_path)  # imagery last: its presence means the world is complete
        tmp_img = None
    finally:
        for t in (tmp_img, tmp_dem):
            if t and os.path.exists(t):
                os.remove(t)
    preview = np.concatenate(previews, axis=0) if previews else None
    return img_path, dem_path, preview, (zr[0], zr[1])


class _Null:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False
