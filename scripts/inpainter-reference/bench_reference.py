"""Times the reference LaMa on one photo and region: bin/predict.py's steps (lama_reference.predict)
with a big-lama-sized generator (ngf 64, 18 blocks) of seeded random weights, which it also saves
as big-lama's best.ckpt is laid out (for the native command to time on the very same file).
Prints JSON: torch's version, the seconds of each repeat, the peak memory (MB)."""
import argparse
import json
import pathlib
import resource
import sys
import time

import numpy as np
import torch
from PIL import Image

sys.path.insert(0, str(pathlib.Path(__file__).parent))
import lama_reference  # noqa: E402
from make_fixture import lightning_checkpoint  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--lama", required=True)
    ap.add_argument("--image", required=True)
    ap.add_argument("--mask", required=True)
    ap.add_argument("--save", required=True, help="the generator, as best.ckpt")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    generator = lama_reference.build_generator(lama_reference.load_ffc(args.lama), ngf=64, n_blocks=18)
    torch.save(lightning_checkpoint(generator), args.save)
    image = np.array(Image.open(args.image).convert("RGB"))
    mask = np.array(Image.open(args.mask).convert("L"))
    seconds = []
    for _ in range(args.repeat):
        start = time.perf_counter()
        lama_reference.predict(generator, image, mask)
        seconds.append(time.perf_counter() - start)
    print(json.dumps({"torch": torch.__version__, "seconds": seconds,
                      "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))


if __name__ == "__main__":
    main()
