#!/usr/bin/env python3
"""One click in every view on a splat scene, as `fill --click` selects (Gaussians.select): for
each view of the capture with an object mask, the click at the pixel deepest inside that mask; the
splats it selects rendered into every view (drawn where they cover at least half of a pixel: two
renders, on black and on white) and compared with the masks. Prints a row per click (its mean
recall and precision over the views, or why it was refused) and the figures over all clicks.
Writes OUT (JSON).

  scripts/measure-click-splats.py SCENE SPLATS [--segmenter FILE] [--every K] [--out FILE]
Example (docs/editing.md's targets; the splats from `infer --keep-object --refine 3m`):
  .venv-py/bin/python scripts/measure-click-splats.py /work/spinnerf/data/1 scene1/gaussians.ply"""
import argparse
import json
import sys
import time

import numpy as np

import instainpaint as ii
from mask_clicks import deepest_pixel


def coverage(splats: ii.Gaussians, camera) -> np.ndarray:
    """Where `splats` cover at least half of a pixel of `camera`."""
    on_black = splats.render(camera, background=(0, 0, 0))
    on_white = splats.render(camera, background=(1, 1, 1))
    alpha = 1.0 - (on_white - on_black).mean(axis=2)
    return alpha >= 0.5


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("splats")
    ap.add_argument("--segmenter")
    ap.add_argument("--every", type=int, default=1)
    ap.add_argument("--out", default="click-splats.json")
    args = ap.parse_args()
    scene = ii.load_scene(args.scene)
    splats = ii.load_gaussians(args.splats)
    segmenter = ii.Segmenter(args.segmenter) if args.segmenter else None
    masks = {v: scene.mask(v) > 0.5 for v in scene.views}
    rows = []
    for view in scene.views[:: args.every]:
        click = deepest_pixel(masks[view])
        start = time.perf_counter()
        row = {"view": view, "click": click}
        try:
            chosen = splats.select(scene.camera(view), click, view=view, segmenter=segmenter)
        except ii.Error as e:
            row["refused"] = str(e)
        else:
            row["selected"] = int(chosen.sum())
            subset = splats.subset(chosen)
            recall, precision = [], []
            for other in scene.views:
                drawn, truth = coverage(subset, scene.camera(other)), masks[other]
                both = (drawn & truth).sum()
                recall.append(both / max(1, truth.sum()))
                precision.append(both / drawn.sum() if drawn.sum() else 1.0)
            row["recall"], row["precision"] = float(np.mean(recall)), float(np.mean(precision))
        row["seconds"] = time.perf_counter() - start
        rows.append(row)
        shown = (f"refused: {row['refused']}" if "refused" in row else
                 f"{row['selected']} splats, recall {row['recall']:.3f} precision {row['precision']:.3f}")
        print(f"{view} click {click[0]:.1f},{click[1]:.1f}: {shown} ({row['seconds']:.1f} s)", flush=True)
    done = [r for r in rows if "refused" not in r]
    summary = {"scene": args.scene, "splats": args.splats, "segmenter": args.segmenter, "clicks": len(rows),
               "refused": len(rows) - len(done),
               "mean_recall": float(np.mean([r["recall"] for r in done])) if done else None,
               "mean_precision": float(np.mean([r["precision"] for r in done])) if done else None,
               "worst_recall": float(min(r["recall"] for r in done)) if done else None, "rows": rows}
    with open(args.out, "w") as f:
        f.write(json.dumps(summary, indent=1) + "\n")
    print(f"{len(rows)} clicks, {summary['refused']} refused; mean recall {summary['mean_recall']}, mean precision "
          f"{summary['mean_precision']}, worst recall {summary['worst_recall']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
