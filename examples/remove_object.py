#!/usr/bin/env python3
"""Remove the object of a masked scene and save its splats and an orbit video.

    python examples/remove_object.py ../shared/data/statue out/ --reference inpainted.png

The scene needs object masks (SPIn-NeRF layout, or --masks FOLDER). Without --reference the
reference view is filled by OpenCV's Telea method, a stand-in for a real 2D inpainter.
"""
import argparse
import pathlib
import sys
import time

import instainpaint as ii


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scene", help="scene folder (LLFF/SPIn-NeRF, nerfstudio or COLMAP) with object masks")
    parser.add_argument("out", help="output folder")
    parser.add_argument("--masks", help="object masks folder (default: the scene's own)")
    parser.add_argument("--reference", help="the reference view inpainted by a 2D inpainter (PNG/JPEG)")
    parser.add_argument("--checkpoint", help="model weights (default: the built-in model)")
    parser.add_argument("--height", type=int, default=256, help="working height in pixels (default 256)")
    parser.add_argument("--refine", default="fast", help='refinement: fast, balanced, best, "90s", steps, or 0')
    parser.add_argument("--frames", type=int, default=48, help="orbit video frames (default 48)")
    args = parser.parse_args()

    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    scene = ii.load_scene(args.scene, masks=args.masks)
    print(scene)
    predictor = ii.Predictor(args.checkpoint)
    start = time.perf_counter()
    gaussians = predictor.predict(scene, reference=args.reference, height=args.height)
    print(f"{len(gaussians)} Gaussians from views {', '.join(gaussians.context)} "
          f"in {time.perf_counter() - start:.1f} s ({predictor.device}, {predictor.precision})")
    if args.refine not in ("", "0"):
        def progress(p):
            if p["step"] % 50 == 0 or p["fraction"] >= 1:
                print(f"  refine {p['fraction']:4.0%}  step {p['step']}  loss {p['loss']:.4f}  "
                      f"{p['gaussians']} Gaussians  ETA {p['eta_s']:.0f} s", flush=True)
        gaussians = gaussians.refine(scene, preset=args.refine, progress=progress)
    gaussians.save(out / "gaussians.ply")
    gaussians.save(out / "gaussians.spz")
    gaussians.render_video(scene, out / "orbit.mp4", frames=args.frames, height=args.height)
    print(f"wrote {out / 'gaussians.ply'}, {out / 'gaussians.spz'} and {out / 'orbit.mp4'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
