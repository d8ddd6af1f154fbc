#!/usr/bin/env python3
"""Splat files before and after an edit, rendered from four sides of the capture: the reference
view and the views a quarter, half and three quarters of the capture after it (captures walked
round their object are in order), each splat file a row. Writes a PNG sheet.

  scripts/four-sides.py SCENE VIEW BEFORE.ply AFTER.ply [MORE.ply ...] --out sheet.png [--height 192]
Example (docs/editing.md, the coffee cup reconstructed, one click, Fill):
  .venv-py/bin/python scripts/four-sides.py ../shared/data/realtrain/custom_coffee_cup 25 cup.ply \\
      cup-filled.ply --out four-sides.png"""
import argparse
import sys

import numpy as np

import instainpaint as ii
from mask_clicks import write_png


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("view", help="the reference view's name")
    ap.add_argument("splats", nargs="+", help="splat files, one row each")
    ap.add_argument("--out", required=True)
    ap.add_argument("--height", type=int, default=192)
    args = ap.parse_args()
    scene = ii.load_scene(args.scene)
    names = scene.views
    if args.view not in names:
        sys.exit(f"{args.scene}: no view {args.view} (views {names[0]} to {names[-1]})")
    start = names.index(args.view)
    sides = [names[(start + k * len(names) // 4) % len(names)] for k in range(4)]
    cameras = []
    for name in sides:
        c = scene.camera(name)
        cameras.append(c.resized(max(1, round(c.width * args.height / c.height)), args.height))
    rows = []
    for path in args.splats:
        g = ii.load_gaussians(path)
        tiles = [(np.clip(g.render(c), 0, 1) * 255).astype(np.uint8) for c in cameras]
        gap = np.full((args.height, 4, 3), 255, np.uint8)
        row = tiles[0]
        for t in tiles[1:]:
            row = np.concatenate([row, gap, t], axis=1)
        rows.append(row)
    sheet = rows[0]
    for r in rows[1:]:
        sheet = np.concatenate([sheet, np.full((4, r.shape[1], 3), 255, np.uint8), r], axis=0)
    write_png(args.out, np.ascontiguousarray(sheet))
    print(f"wrote {args.out} ({sheet.shape[1]}x{sheet.shape[0]}): views {', '.join(sides)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
