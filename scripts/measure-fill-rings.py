#!/usr/bin/env python3
"""Remove and fill from every side: synthetic rooms photographed all around their object (synth
--rings 1), trained whole by `reconstruct`, the object removed by one click on the reference view
(the pixel deepest inside its mask), or by a box (its mask's bounding box grown by 5 % of its side),
and the hole filled; the object-free test views (between the training cameras, all round the ring)
scored inside their object masks (eval --gaussians), banded by the angle between each test camera's
view direction and the reference's: near (under 90 degrees) and opposite (90 or more). Columns:
deletion alone (fill --delete-only) and the fill, for the click and for the box. Prints a Markdown
table; writes OUT/results.json.

  scripts/measure-fill-rings.py [--bin build/instainpaint] [--rooms 3] [--seed 11] [--steps 2000]
                                [--out measure-fill-rings]"""
import argparse
import json
import math
import os
import subprocess
import sys

import numpy as np

import instainpaint as ii
from mask_clicks import deepest_pixel


def run(cmd, log):
    with open(log, "w") as f:
        if subprocess.call(cmd, stdout=f, stderr=subprocess.STDOUT) != 0:
            sys.exit(f"failed: {' '.join(cmd)} (see {log})")


def axis(camera):
    """A camera's viewing direction (its c2w's -z, OpenGL axes)."""
    c2w = np.asarray(camera.c2w)
    return -c2w[:3, 2] / np.linalg.norm(c2w[:3, 2])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="build/instainpaint")
    ap.add_argument("--rooms", type=int, default=3)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--out", default="measure-fill-rings")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    rooms = os.path.join(args.out, "rooms")
    if not os.path.isdir(os.path.join(rooms, "scene_000")):
        run([args.bin, "synth", "--out", rooms, "--scenes", str(args.rooms), "--seed", str(args.seed), "--rings", "1",
             "--views", "24", "--test-views", "8", "--width", "256", "--height", "192", "--object", "procedural",
             "--no-depth"], os.path.join(args.out, "synth.log"))
    results = []
    print("| room | click: deletion near / opposite | click: fill near / opposite | box: deletion near / opposite | "
          "box: fill near / opposite |")
    print("|---|---|---|---|---|")
    for k in range(args.rooms):
        room = os.path.join(rooms, f"scene_{k:03d}")
        work = os.path.join(args.out, f"scene_{k:03d}")
        os.makedirs(work, exist_ok=True)
        splats = os.path.join(work, "room.ply")
        if not os.path.exists(splats):
            run([args.bin, "reconstruct", room, "--steps", str(args.steps), "--checkpoint-every", "0", "--out", splats],
                os.path.join(work, "reconstruct.log"))
        scene = ii.load_scene(room)
        reference = json.load(open(os.path.join(room, "synth.json")))["reference"]
        mask = scene.mask(reference) > 0.5
        x, y = deepest_pixel(mask)
        ys, xs = np.nonzero(mask)
        grow = 0.05 * max(xs.max() - xs.min(), ys.max() - ys.min())
        box = [max(0, xs.min() - grow), max(0, ys.min() - grow), min(mask.shape[1], xs.max() + 1 + grow),
               min(mask.shape[0], ys.max() + 1 + grow)]
        row = {"room": room, "reference": reference, "click": [x, y], "box": [float(v) for v in box]}
        region = {"click": ["--click", f"{x},{y}"], "box": ["--box", ",".join(f"{v:.1f}" for v in box)]}
        for method, extra in (("deleted", ["--delete-only"]), ("filled", []), ("box-deleted", ["--delete-only"]),
                              ("box-filled", [])):
            out = os.path.join(work, f"{method}.ply")
            run([args.bin, "fill", splats, "--scene", room, "--view", reference, "--out", out]
                + region["box" if method.startswith("box") else "click"] + extra, os.path.join(work, f"{method}.log"))
            run([args.bin, "eval", "--scene", room, "--gaussians", out, "--no-report", "--out",
                 os.path.join(work, f"eval-{method}")], os.path.join(work, f"eval-{method}.log"))
            metrics = json.load(open(os.path.join(work, f"eval-{method}", "metrics.json")))
            ref_axis = axis(scene.camera(reference))
            bands = {"near": [], "opposite": []}
            for view in metrics["views"]:
                angle = math.degrees(math.acos(float(np.clip(axis(scene.camera(view["name"])) @ ref_axis, -1, 1))))
                bands["near" if angle < 90 else "opposite"].append(view["masked_psnr"])
            row[method] = {band: float(np.mean(v)) if v else None for band, v in bands.items()}
        results.append(row)
        cells = [f"{row[m]['near']:.2f} / {row[m]['opposite']:.2f}" for m in ("deleted", "filled", "box-deleted",
                                                                              "box-filled")]
        print(f"| scene_{k:03d} | " + " | ".join(cells) + " |", flush=True)
    with open(os.path.join(args.out, "results.json"), "w") as out:
        json.dump(results, out, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
