#!/usr/bin/env python3
"""Prints the box around a standard binary PLY's splat centres as fill --box takes it:
cx,cy,cz,sx,sy,sz (the size grown by --grow).

Example: instainpaint fill scene.ply --box "$(scripts/splat-bounds.py object.ply --grow 1.1)" --out filled.ply
"""
import argparse
import struct
import sys


def centres(path):
    data = open(path, "rb").read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii", "replace").splitlines()
    if "format binary_little_endian 1.0" not in header:
        sys.exit(f"splat-bounds: {path}: not a binary little-endian PLY")
    count = int(next(line for line in header if line.startswith("element vertex")).split()[-1])
    names = [line.split()[-1] for line in header if line.startswith("property")]
    if any(line.startswith("property") and line.split()[1] != "float" for line in header):
        sys.exit(f"splat-bounds: {path}: every property must be a float (a standard 3DGS PLY)")
    xyz = [names.index(axis) for axis in ("x", "y", "z")]
    row = struct.Struct("<%df" % len(names))
    for i in range(count):
        values = row.unpack_from(data, end + i * row.size)
        yield [values[k] for k in xyz]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("ply")
    parser.add_argument("--grow", type=float, default=1.0, help="size factor (default 1)")
    args = parser.parse_args()
    lo, hi = [float("inf")] * 3, [float("-inf")] * 3
    for p in centres(args.ply):
        lo = [min(a, b) for a, b in zip(lo, p)]
        hi = [max(a, b) for a, b in zip(hi, p)]
    centre = [(a + b) / 2 for a, b in zip(lo, hi)]
    size = [(b - a) * args.grow for a, b in zip(lo, hi)]
    print(",".join("%.5g" % v for v in centre + size))


if __name__ == "__main__":
    main()
