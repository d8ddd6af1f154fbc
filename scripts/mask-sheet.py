#!/usr/bin/env python3
"""A picture of masks made for a scene against its own: for each named view, its photo with the
pixels in both cyan, in the made mask alone green, in the scene's own alone blue; side by side,
halved. Reads with the Python package (make python: .venv-py); writes a PNG.

  scripts/mask-sheet.py SCENE MASKS_DIR VIEW [VIEW ...] --out sheet.png [--scale 2]
Example:
  .venv-py/bin/python scripts/mask-sheet.py /work/spinnerf/data/1 masks-out 20220819_104351 \\
      20220819_104412 --out docs/select-click-scene1-views.png"""
import argparse
import sys

import numpy as np

import instainpaint as ii
from mask_clicks import write_png


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("masks")
    ap.add_argument("views", nargs="+")
    ap.add_argument("--out", required=True)
    ap.add_argument("--scale", type=int, default=2, help="keep every SCALE-th pixel")
    args = ap.parse_args()
    own = ii.load_scene(args.scene)
    made = ii.load_scene(args.scene, masks=args.masks)
    tiles = []
    for view in args.views:
        photo = own.image(view).astype(np.float32)
        truth, mask = own.mask(view) > 0.5, made.mask(view) > 0.5
        out = 0.55 * photo
        for where, colour in ((truth & mask, (0.0, 0.9, 0.9)), (mask & ~truth, (0.1, 0.9, 0.1)),
                              (truth & ~mask, (0.2, 0.3, 1.0))):
            out[where] = 0.45 * photo[where] + 0.55 * np.array(colour, dtype=np.float32)
        tiles.append((np.clip(out, 0, 1) * 255).astype(np.uint8)[:: args.scale, :: args.scale])
    gap = np.full((tiles[0].shape[0], 4, 3), 255, np.uint8)
    sheet = tiles[0]
    for t in tiles[1:]:
        sheet = np.concatenate([sheet, gap, t], axis=1)
    write_png(args.out, np.ascontiguousarray(sheet))
    print(f"wrote {args.out} ({sheet.shape[1]}x{sheet.shape[0]})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
