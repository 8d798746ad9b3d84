"""Helpers of the report tests: decode the PNGs embedded in an HTML report."""

import base64
import re

import cv2
import numpy as np

DATA_PNG = re.compile(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"')


def n_colors(img: np.ndarray) -> int:
    """Number of distinct RGB colours of a (h, w, 3) uint8 image."""
    packed = img.reshape(-1, 3).astype(np.int32) @ np.array([1 << 16, 1 << 8, 1], np.int32)
    return int(np.unique(packed).size)


def decoded_images(html: str) -> list[np.ndarray]:
    return [cv2.imdecode(np.frombuffer(base64.b64decode(b), np.uint8), cv2.IMREAD_COLOR) for b in DATA_PNG.findall(html)]
