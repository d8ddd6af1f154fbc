"""Helpers of the click measurements (measure-click-every-view.py, measure-click-splats.py,
mask-sheet.py): where a user would click inside a mask, and PNGs written without an image library."""
import struct
import zlib

import numpy as np


def deepest_pixel(mask: np.ndarray):
    """The pixel of `mask` farthest from its outline (erosion by the 4-neighbourhood until none is
    left: the middle one of the last pixels standing, in row order), as (x, y) pixel centres; None
    for an empty mask."""
    inside = mask > 0.5
    if not inside.any():
        return None
    while True:
        eroded = inside.copy()
        eroded[1:, :] &= inside[:-1, :]
        eroded[:-1, :] &= inside[1:, :]
        eroded[:, 1:] &= inside[:, :-1]
        eroded[:, :-1] &= inside[:, 1:]
        eroded[0, :] = eroded[-1, :] = eroded[:, 0] = eroded[:, -1] = False
        if not eroded.any():
            break
        inside = eroded
    ys, xs = np.nonzero(inside)
    k = len(xs) // 2
    return float(xs[k]) + 0.5, float(ys[k]) + 0.5


def write_png(path, pixels: np.ndarray) -> None:
    """An 8-bit PNG of an H x W (grey) or H x W x 3 (RGB) uint8 array."""
    h, w = pixels.shape[:2]
    colour = 2 if pixels.ndim == 3 else 0
    rows = b"".join(b"\x00" + np.ascontiguousarray(pixels[y]).tobytes() for y in range(h))

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, colour, 0, 0, 0))
                + chunk(b"IDAT", zlib.compress(rows, 9)) + chunk(b"IEND", b""))
