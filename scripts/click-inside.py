#!/usr/bin/env python3
"""Prints X,Y: the pixel deepest inside a mask PNG (farthest from its outline), where a user
would click on the object. Standard library only (8-bit PNGs, any colour type without palette).

    scripts/click-inside.py scene/images_4/label/IMG_0001.png   # -> 681.5,216.5
"""
import struct
import sys
import zlib


def read_png_gray(path):
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        sys.exit(f"{path}: not a PNG")
    pos, idat, width = 8, b"", 0
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            width, height, depth, colour = struct.unpack(">IIBB", body[:10])
            channels = {0: 1, 2: 3, 4: 2, 6: 4}.get(colour)
            if depth != 8 or channels is None:
                sys.exit(f"{path}: only 8-bit PNGs without a palette are read here")
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    raw, stride = zlib.decompress(idat), width * channels
    rows, prev = [], bytearray(stride)
    for y in range(height):
        kind, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - channels] if i >= channels else 0
            b, c = prev[i], prev[i - channels] if i >= channels else 0
            if kind == 1: line[i] = (line[i] + a) & 255
            elif kind == 2: line[i] = (line[i] + b) & 255
            elif kind == 3: line[i] = (line[i] + (a + b) // 2) & 255
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append([line[x * channels] for x in range(width)])
        prev = line
    return rows


def deepest(mask):
    """Two-pass chamfer distance to the outside; the first pixel of the largest."""
    h, w = len(mask), len(mask[0])
    big = h + w
    d = [[big if mask[y][x] > 0 else 0 for x in range(w)] for y in range(h)]
    for y in range(h):
        for x in range(w):
            if d[y][x]:
                d[y][x] = min(d[y][x], (d[y - 1][x] + 1) if y else 1, (d[y][x - 1] + 1) if x else 1)
    for y in range(h - 1, -1, -1):
        for x in range(w - 1, -1, -1):
            if d[y][x]:
                d[y][x] = min(d[y][x], (d[y + 1][x] + 1) if y + 1 < h else 1, (d[y][x + 1] + 1) if x + 1 < w else 1)
    best = max((d[y][x], -y, -x) for y in range(h) for x in range(w))
    if best[0] == 0:
        sys.exit("the mask is empty")
    return -best[2], -best[1]


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    x, y = deepest(read_png_gray(sys.argv[1]))
    print(f"{x + 0.5},{y + 0.5}")
