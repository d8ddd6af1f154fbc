#!/usr/bin/env python3
"""One click in every view of a scene with object masks (SPIn-NeRF scene 1: 60 views): for each
view, `instainpaint masks --click` at the pixel deepest inside that view's own mask (the farthest
from its outline), and the masks it makes compared with the scene's own in every view. With
--drawn, each view's own mask is the drawn region instead (`masks --mask`; the other views
compared). With --box GROW, a box around each view's own mask grown by GROW of its width and height
(0.05: 5 %) instead of the click (`masks --box`; its view's mask compared too). Prints a
row per run (the run's mean recall and precision over the views, or why the click was refused,
and its seconds) and the figures over all runs: mean recall, mean precision, the worst run's
recall, the clicks refused. Writes OUT/summary.json.

  scripts/measure-click-every-view.py SCENE [--segmenter FILE] [--drawn | --box GROW] [--every K] [--out DIR]
      [--cli build/instainpaint] [-- more masks options, e.g. --carve on]
Example (the targets' table of docs/editing.md):
  .venv-py/bin/python scripts/measure-click-every-view.py /work/spinnerf/data/1 --out click-every-view
Needs the Python package (make python: .venv-py) for the scene's masks."""
import argparse
import json
import pathlib
import subprocess
import sys
import time

import numpy as np

import instainpaint as ii
from mask_clicks import deepest_pixel, write_png


def grown_box(mask: np.ndarray, grow: float):
    """The bounding box (edges) of `mask`, grown by `grow` of its width and height about its middle,
    within the picture."""
    ys, xs = np.nonzero(mask > 0.5)
    x0, x1, y0, y1 = xs.min(), xs.max() + 1, ys.min(), ys.max() + 1
    dx, dy = (x1 - x0) * grow / 2, (y1 - y0) * grow / 2
    h, w = mask.shape
    return (round(max(0.0, x0 - dx), 1), round(max(0.0, y0 - dy), 1), round(min(float(w), x1 + dx), 1),
            round(min(float(h), y1 + dy), 1))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("--segmenter", help="masks --segmenter (SAM or MobileSAM file)")
    ap.add_argument("--drawn", action="store_true", help="each view's own mask drawn, in place of the click")
    ap.add_argument("--box", type=float, help="a box around each view's own mask, grown by this fraction")
    ap.add_argument("--every", type=int, default=1, help="every K-th view only (1: all)")
    ap.add_argument("--out", default="click-every-view")
    ap.add_argument("--cli", default="build/instainpaint")
    args, more = ap.parse_known_args()  # the rest (after --) goes to masks
    args.more = [a for a in more if a != "--"]
    scene = ii.load_scene(args.scene)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for view in scene.views[:: args.every]:
        click = deepest_pixel(scene.mask(view))
        if click is None:
            continue
        if args.box is not None:
            box = grown_box(scene.mask(view), args.box)
            marked = ["--box", ",".join(f"{v:g}" for v in box)] + (["--segmenter", args.segmenter] if args.segmenter else [])
        elif args.drawn:
            label = out / f"{view}.drawn.png"
            write_png(label, (scene.mask(view) > 0.5).astype(np.uint8) * 255)
            marked = ["--mask", str(label)]
        else:
            marked = ["--click", f"{click[0]},{click[1]}"] + (["--segmenter", args.segmenter] if args.segmenter else [])
        cmd = [args.cli, "masks", "--scene", args.scene, "--view", view, "--out", str(out / view)] + marked + args.more
        start = time.perf_counter()
        run = subprocess.run(cmd, capture_output=True, text=True)
        seconds = time.perf_counter() - start
        row = {"view": view, "click": click, "seconds": seconds}
        if run.returncode != 0:
            row["refused"] = (run.stderr.strip().splitlines() or ["?"])[-1]
        else:
            report = json.loads((out / view / "masks.json").read_text())
            row["recall"] = report["agreement"]["mean_recall"]
            row["precision"] = report["agreement"]["mean_precision"]
            row["worst_view_recall"] = report["agreement"]["worst_recall"]
            row["worst_view_precision"] = report["agreement"]["worst_precision"]
            own = next(v for v in report["views"] if v["name"] == view)
            row["own_recall"], row["own_precision"] = own.get("recall"), own.get("precision")
            row["clicked_mask"] = report.get("clicked_mask", "")
        rows.append(row)
        shown = (f"refused: {row['refused']}" if "refused" in row
                 else f"recall {row['recall']:.3f} precision {row['precision']:.3f}"
                 + (f" (its own view {row['own_recall']:.3f} / {row['own_precision']:.3f})"
                    if row.get("own_recall") is not None else ""))
        prompt = f"box {','.join(f'{v:g}' for v in box)}" if args.box is not None else f"click {click[0]:.1f},{click[1]:.1f}"
        print(f"{view} {prompt}: {shown} ({seconds:.1f} s)", flush=True)
    done = [r for r in rows if "refused" not in r]
    summary = {
        "scene": args.scene, "segmenter": args.segmenter, "options": args.more, "runs": len(rows),
        "refused": len(rows) - len(done),
        "mean_recall": float(np.mean([r["recall"] for r in done])) if done else None,
        "mean_precision": float(np.mean([r["precision"] for r in done])) if done else None,
        "worst_run_recall": float(min(r["recall"] for r in done)) if done else None,
        "worst_run_precision": float(min(r["precision"] for r in done)) if done else None,
        "median_seconds": float(np.median([r["seconds"] for r in rows])) if rows else None,
        "rows": rows,
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    print(f"{len(rows)} runs, {summary['refused']} refused; mean recall {summary['mean_recall']}, mean precision "
          f"{summary['mean_precision']}, worst run's recall {summary['worst_run_recall']} and precision "
          f"{summary['worst_run_precision']}, median "
          f"{summary['median_seconds']} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
