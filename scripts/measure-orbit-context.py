#!/usr/bin/env python3
"""The feed-forward on a capture around its object, by direction: `eval --keep-object
--hold-out-every 8` of each scene, then the held-out views' PSNR banded by the angle of their optical
axis to the reference's (within 30 degrees: the reference's neighbours; 30-60; beyond). Prints a
line per scene with the context the network read. Needs the Python package (make python: .venv-py).

  .venv-py/bin/python scripts/measure-orbit-context.py SCENE [SCENE ...] [--height 256]
      [--cli build/instainpaint] [--out orbit-context]
Example (docs/benchmarks.md, "Feed-forward quality of the default model"):
  .venv-py/bin/python scripts/measure-orbit-context.py ../shared/data/realtrain/custom_coffee_cup \\
      ../shared/data/realtrain/custom_beer_can"""
import argparse
import json
import pathlib
import subprocess
import sys

import numpy as np

import instainpaint as ii


def axis(scene, name):
    """A view's optical axis (OpenGL camera-to-world: the camera looks along -z)."""
    return -np.asarray(scene.camera(name).c2w)[:3, 2]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--height", type=int, default=256)
    ap.add_argument("--cli", default="build/instainpaint")
    ap.add_argument("--out", default="orbit-context")
    args = ap.parse_args()
    for scene_dir in args.scenes:
        out = pathlib.Path(args.out) / pathlib.Path(scene_dir).name
        subprocess.run([args.cli, "eval", "--scene", scene_dir, "--keep-object", "--hold-out-every", "8", "--height",
                        str(args.height), "--no-report", "--out", str(out)], check=True, capture_output=True)
        metrics = json.loads((out / "metrics.json").read_text())
        scene = ii.load_scene(scene_dir)
        reference = axis(scene, metrics["prediction"]["context"][0])
        bands = {"within 30": [], "30-60": [], "beyond 60": []}
        for view in metrics["views"]:
            a = axis(scene, view["name"])
            cos = a @ reference / np.linalg.norm(a) / np.linalg.norm(reference)
            angle = np.degrees(np.arccos(np.clip(cos, -1, 1)))
            bands["within 30" if angle <= 30 else "30-60" if angle <= 60 else "beyond 60"].append(view["psnr"])
        shown = "; ".join(f"{k}: {np.mean(v):.2f} dB ({len(v)} views)" for k, v in bands.items() if v)
        print(f"{pathlib.Path(scene_dir).name}: context {metrics['prediction']['context']}; {shown}; all "
              f"{metrics['mean']['psnr']:.2f} dB", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
