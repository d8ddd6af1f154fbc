#!/usr/bin/env python3
"""Times how Python gets a GPU prediction's Gaussians: `Predictor.predict` on a CUDA device, then its
arrays handed to PyTorch by DLPack (on the device, no copy: checked by the memory's address), beside
what a copy to the host would cost.

Example:  (the module built with -DINSTAINPAINT_PYTHON=ON in build-gpu, as the device check does)
  PYTHONPATH=build-gpu/python scripts/measure-python-handover.py --scene .device/shared/data/statue
"""
import argparse
import sys
import time


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                     epilog="Example:" + __doc__.split("Example:")[1],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scene", required=True, help="a scene with object masks")
    parser.add_argument("--height", type=int, default=512, help="working height (default 512)")
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    import torch
    import instainpaint as ii
    if not torch.cuda.is_available():
        sys.exit("measure-python-handover: no CUDA device")
    scene = ii.load_scene(args.scene)
    predictor = ii.Predictor(device="cuda")
    predictor.predict(scene, height=args.height)  # the first call's set-up is not the hand-over
    for run in range(1, args.runs + 1):
        torch.cuda.synchronize()
        start = time.perf_counter()
        g = predictor.predict(scene, height=args.height)
        predicted = time.perf_counter()
        arrays = [g.means, g.quats, g.scales, g.opacities, g.colors]
        tensors = [torch.from_dlpack(a) for a in arrays]
        handed = time.perf_counter()
        same = all(torch.from_dlpack(a).data_ptr() == t.data_ptr() for a, t in zip(
            [g.means, g.quats, g.scales, g.opacities, g.colors], tensors))
        host = [t.cpu() for t in tensors]
        torch.cuda.synchronize()
        copied = time.perf_counter()
        megabytes = sum(t.numel() * t.element_size() for t in host) / 1e6
        print(f"run {run}: predict {1000 * (predicted - start):.1f} ms ({len(g)} Gaussians on {g.device}); "
              f"the 5 arrays to PyTorch by DLPack {1000 * (handed - predicted):.2f} ms, on {tensors[0].device}, "
              f"the same memory on a second read: {same}; a copy to the host would take "
              f"{1000 * (copied - handed):.1f} ms for {megabytes:.0f} MB")


if __name__ == "__main__":
    main()
