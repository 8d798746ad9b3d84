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

from testbench.core.interfaces import GeodeticOrigin
from testbench.world.georef import local_tmerc_crs

_OVERVIEWS = (2, 4, 8, 16, 32, 64)


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
        with rasterio.Env(GDAL_TIFF_INTERNAL_MASK=True):
            with rasterio.open(tmp, "w", **prof) as dst:
                dst.write(np.moveaxis(arr, -1, 0))
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
