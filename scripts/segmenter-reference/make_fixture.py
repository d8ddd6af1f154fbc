"""Writes tests/segment/fixture/: small SAM and MobileSAM models with seeded random weights,
saved as their authors save theirs (torch.save of the state dict), and what the reference code
(github facebookresearch/segment-anything, github ChaoningZhang/MobileSAM) answers for a set of
prompts on one image. The native segmenter's parity tests compare against these outputs.

Run by scripts/segmenter-reference/make-fixture.sh, which prepares PyPI's torch in a
project-local environment and extracts the two reference packages from git mirrors.

Each model keeps its published layout (the same module classes, the same state-dict keys) at
sizes small enough for the repository:
  - SAM: ImageEncoderViT at 256 pixels (16 x 16 tokens), 3 blocks, the middle one global, 6 x 6
    windows in the others; prompt and decoder width 32.
  - MobileSAM: TinyViT at 1024 pixels (its forward pass fixes 64 x 64 tokens at the end), widths
    8/16/24/32. The published TinyViT keeps 64 x 64 tokens in its last merge because its widths
    (320, 448, 576) are listed in PatchMerging; at width 32 that merge's stride is set to 1 here
    instead, and the neck (fixed at 256 channels in the class) is rebuilt at width 32.
"""
import argparse
import json
import os
import sys

import numpy as np
import torch
from PIL import Image


def randomise(module, seed):
    """Every weight and statistic seeded and non-trivial (the published initialisations leave
    many at 0 or 1, which would hide a wrongly read tensor)."""
    g = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for name, t in module.state_dict().items():
            if not t.is_floating_point():
                continue
            if name.endswith("running_var"):
                t.copy_(0.5 + torch.rand(t.shape, generator=g))
            elif name.endswith("running_mean"):
                t.copy_(0.2 * torch.randn(t.shape, generator=g))
            elif t.dim() == 1 and name.endswith("weight"):
                t.copy_(1.0 + 0.2 * torch.randn(t.shape, generator=g))
            elif name.endswith("bias") or "rel_pos" in name or "attention_biases" in name:
                t.copy_(0.2 * torch.randn(t.shape, generator=g))
            elif "positional_encoding_gaussian_matrix" in name:
                t.copy_(torch.randn(t.shape, generator=g))
            elif "pos_embed" in name or t.dim() == 2 and ("token" in name or "embed" in name):
                t.copy_(0.5 * torch.randn(t.shape, generator=g))
            else:
                fan_in = max(1, t[0].numel()) if t.dim() > 1 else max(1, t.numel())
                t.copy_(torch.randn(t.shape, generator=g) / fan_in ** 0.5)


DIM = 32  # the prompt encoder's and mask decoder's width


def small_sam_around(m, encoder, image_size):
    """SAM's prompt encoder and mask decoder, small, around `encoder` (of the same package `m`)."""
    grid = image_size // 16
    return m.Sam(
        image_encoder=encoder,
        prompt_encoder=m.PromptEncoder(embed_dim=DIM, image_embedding_size=(grid, grid),
                                       input_image_size=(image_size, image_size), mask_in_chans=8),
        mask_decoder=m.MaskDecoder(
            num_multimask_outputs=3,
            transformer=m.TwoWayTransformer(depth=2, embedding_dim=DIM, mlp_dim=64, num_heads=8),
            transformer_dim=DIM, iou_head_depth=3, iou_head_hidden_dim=24),
        pixel_mean=[123.675, 116.28, 103.53], pixel_std=[58.395, 57.12, 57.375])


def small_sam(sam_pkg):
    from functools import partial
    m = sam_pkg.modeling
    encoder = m.ImageEncoderViT(
        depth=3, embed_dim=32, img_size=256, mlp_ratio=4, num_heads=2, patch_size=16,
        norm_layer=partial(torch.nn.LayerNorm, eps=1e-6), qkv_bias=True, use_rel_pos=True,
        global_attn_indexes=(1,), window_size=6, out_chans=DIM)
    return small_sam_around(m, encoder, 256)


def small_mobile_sam(mobile_pkg):
    m = mobile_pkg.modeling
    from mobile_sam.modeling.tiny_vit_sam import LayerNorm2d
    encoder = m.TinyViT(img_size=1024, in_chans=3, num_classes=10, embed_dims=[8, 16, 24, 32],
                        depths=[1, 1, 2, 1], num_heads=[1, 2, 3, 4], window_sizes=[7, 7, 14, 7],
                        mlp_ratio=2.0, drop_rate=0.0, drop_path_rate=0.0, use_checkpoint=False,
                        mbconv_expand_ratio=2.0, local_conv_size=3, layer_lr_decay=0.8)
    encoder.layers[2].downsample.conv2.c.stride = (1, 1)
    encoder.neck = torch.nn.Sequential(
        torch.nn.Conv2d(32, DIM, kernel_size=1, bias=False), LayerNorm2d(DIM),
        torch.nn.Conv2d(DIM, DIM, kernel_size=3, padding=1, bias=False), LayerNorm2d(DIM))
    return small_sam_around(m, encoder, 1024)


def fixture_image(h=48, w=64):
    """A smooth picture with two shapes (PNG-friendly, and something to segment)."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    img = np.stack([120 + 80 * np.sin(x / 9.0), 90 + 60 * np.cos(y / 7.0), 60 + x + y], axis=-1)
    disc = (x - 20) ** 2 + (y - 22) ** 2 < 11 ** 2
    img[disc] = [230, 40, 40]
    box = (x > 38) & (x < 58) & (y > 8) & (y < 30)
    img[box] = [30, 200, 90]
    return np.clip(img, 0, 255).astype(np.uint8)


# The prompts asked of both models, in the original image's pixels (SamPredictor.predict's).
CASES = [
    {"name": "point", "points": [[20, 22]], "labels": [1], "multimask": True},
    {"name": "points_and_negative", "points": [[20, 22], [46, 18], [5, 40]], "labels": [1, 1, 0],
     "multimask": True},
    {"name": "box", "box": [36, 6, 60, 32], "multimask": False},
    {"name": "box_and_point", "box": [8, 8, 34, 36], "points": [[20, 22]], "labels": [1],
     "multimask": True},
    {"name": "previous_mask", "points": [[21, 23]], "labels": [1], "mask_from": "point",
     "multimask": False},
]


# What is kept of the large maps (every STRIDE-th row and column): the repository holds the fixture.
STRIDE = {"sam": 1, "mobile_sam": 4}


def answer_cases(predictor, image, out, prefix):
    s = STRIDE[prefix]
    predictor.set_image(image)
    out[f"{prefix}.features"] = predictor.features[0, :, ::s, ::s].contiguous()
    low_res_of = {}
    for case in CASES:
        kwargs = {"multimask_output": case["multimask"], "return_logits": True}
        if "points" in case:
            kwargs["point_coords"] = np.array(case["points"], dtype=np.float64)
            kwargs["point_labels"] = np.array(case["labels"])
        if "box" in case:
            kwargs["box"] = np.array(case["box"], dtype=np.float64)
        if "mask_from" in case:
            low, scores = low_res_of[case["mask_from"]]
            kwargs["mask_input"] = low[int(np.argmax(scores))][None, :, :]
        logits, scores, low = predictor.predict(**kwargs)
        low_res_of[case["name"]] = (low, scores)
        key = f"{prefix}.{case['name']}"
        out[key + ".logits"] = torch.from_numpy(logits.astype(np.float32))
        out[key + ".iou"] = torch.from_numpy(scores.astype(np.float32))
        out[key + ".low_res"] = torch.from_numpy(np.ascontiguousarray(low[:, ::s, ::s]).astype(np.float32))


def fixture_model(model, seed, path, predictor, image, out, prefix):
    """`model` with seeded random weights, saved at `path` as the authors save theirs, and its
    reference answers to CASES on `image` in `out` under `prefix`."""
    randomise(model, seed)
    model.eval()
    torch.save(model.state_dict(), path)
    answer_cases(predictor(model), image, out, prefix)
    return model


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--segment-anything", required=True, help="folder holding segment_anything/")
    ap.add_argument("--mobile-sam", required=True, help="folder holding mobile_sam/")
    ap.add_argument("--out", required=True)
    ap.add_argument("--statue", help="shared/data/statue: also the MobileSAM model's mask of IMG_2707 for one click, "
                                     "for the test of the whole masks command")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    torch.set_num_threads(1)  # the same sums whatever the machine
    from safetensors.torch import save_file

    image = fixture_image()
    Image.fromarray(image).save(os.path.join(args.out, "image.png"))
    out = {}

    sys.path.insert(0, args.segment_anything)
    import segment_anything
    fixture_model(small_sam(segment_anything), 1, os.path.join(args.out, "sam_vit_small.pth"),
                  segment_anything.SamPredictor, image, out, "sam")
    # Pillow's bilinear resize as SamPredictor.set_image uses it, up and down (odd sizes).
    from segment_anything.utils.transforms import ResizeLongestSide
    for size in (37, 131):
        resized = ResizeLongestSide(size).apply_image(image)
        out[f"resize.{size}"] = torch.from_numpy(np.ascontiguousarray(resized))
    sys.path.pop(0)

    sys.path.insert(0, args.mobile_sam)
    import mobile_sam
    mobile = fixture_model(small_mobile_sam(mobile_sam), 2, os.path.join(args.out, "mobile_sam_small.pt"),
                           mobile_sam.SamPredictor, image, out, "mobile_sam")

    if args.statue:
        # The masks command's click 301.5,259.5 (pixel centres at +0.5) is SAM's point (301, 259).
        photo = np.array(Image.open(os.path.join(args.statue, "images_2", "IMG_2707.png")).convert("RGB"))
        predictor = mobile_sam.SamPredictor(mobile)
        predictor.set_image(photo)
        masks, scores, _ = predictor.predict(point_coords=np.array([[301.0, 259.0]]), point_labels=np.array([1]),
                                             multimask_output=True)
        best = int(np.argmax(scores))
        Image.fromarray((masks[best] * 255).astype(np.uint8)).save(os.path.join(args.out, "statue_IMG_2707_click.png"))
        # The same for the Python package's test, which reads no PNG.
        np.savez_compressed(os.path.join(args.out, "statue_IMG_2707_click.npz"), mask=masks[best])
        out["mobile_sam.statue.iou"] = torch.from_numpy(scores.astype(np.float32))

    save_file({k: v.contiguous() for k, v in out.items()}, os.path.join(args.out, "reference.safetensors"),
              metadata={"torch": torch.__version__, "stride": json.dumps(STRIDE)})
    with open(os.path.join(args.out, "cases.json"), "w") as f:
        json.dump({"torch": torch.__version__, "stride": STRIDE, "cases": CASES}, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
