"""Times the reference SamPredictor (segment-anything or MobileSAM under PyPI's torch) on one
photo: set_image (the resize, normalisation and image encoder) and predict for one click, with
a model of a published layout and seeded random weights, which it also saves (torch.save of the
state dict, as the authors publish theirs) for the native segmenter to be timed on the same file.
Run by scripts/measure-segmenter.sh."""
import argparse
import json
import sys
import time

import numpy as np
import torch
from PIL import Image


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--package", required=True, help="folder holding segment_anything/ or mobile_sam/")
    ap.add_argument("--layout", required=True, choices=["vit_t", "vit_b", "vit_l", "vit_h"])
    ap.add_argument("--image", required=True)
    ap.add_argument("--click", required=True, help="X,Y")
    ap.add_argument("--save", help="write the model's weights here")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    sys.path.insert(0, args.package)
    if args.layout == "vit_t":
        from mobile_sam import SamPredictor, sam_model_registry
    else:
        from segment_anything import SamPredictor, sam_model_registry
    torch.manual_seed(0)
    model = sam_model_registry[args.layout]()
    model.eval()
    if args.save:
        torch.save(model.state_dict(), args.save)
    predictor = SamPredictor(model)
    image = np.array(Image.open(args.image).convert("RGB"))
    x, y = (float(v) for v in args.click.split(","))
    encode, decode = [], []
    for _ in range(args.repeat):
        t = time.perf_counter()
        predictor.set_image(image)
        encode.append(time.perf_counter() - t)
        t = time.perf_counter()
        with torch.no_grad():
            predictor.predict(point_coords=np.array([[x - 0.5, y - 0.5]]), point_labels=np.array([1]),
                              multimask_output=True)
        decode.append(time.perf_counter() - t)
    print(json.dumps({"layout": args.layout, "torch": torch.__version__, "threads": args.threads,
                      "encode_s": encode, "decode_s": decode}))


if __name__ == "__main__":
    main()
