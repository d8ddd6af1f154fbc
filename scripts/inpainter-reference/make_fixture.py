"""Writes tests/inpaint/fixture/: a small LaMa generator with seeded random weights saved as
big-lama's published checkpoint is laid out, and the reference code's answers.

  lama-small/models/best.ckpt   PyTorch Lightning's layout: {"state_dict": {"generator.model.…",
                                "discriminator.…"}, "callbacks": {ModelCheckpoint: {...}}, ...},
                                zip format (torch.save), as big-lama/models/best.ckpt
  lama-small/config.yaml        the generator's part of big-lama's config.yaml, this size
  big-lama.pt                   the same generator traced to TorchScript (torch.jit.trace, then
                                save), as lama-cleaner's and IOPaint's big-lama.pt is
  reference.safetensors         per case K: image_K (H, W, 3) uint8, mask_K (H, W) uint8,
                                inpainted_K (H, W, 3) float32 (bin/predict.py before rounding)
  cases.json                    the cases' sizes and the generator's

Run by make-fixture.sh under PyPI's torch."""
import argparse
import json
import pathlib
import sys
import types

import numpy as np
import torch
from safetensors.torch import save_file

sys.path.insert(0, str(pathlib.Path(__file__).parent))
import lama_reference  # noqa: E402

NGF, BLOCKS = 8, 2
CASES = [(64, 48), (61, 45)]  # (width, height): a multiple of 8, and one that LaMa pads


def photo(width, height, seed):
    """A smooth colour field with some stripes (so that the convolutions see structure)."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:height, 0:width].astype("float32")
    channels = []
    for c in range(3):
        a, b, p = rng.uniform(0.05, 0.3, 3)
        channels.append(0.5 + 0.35 * np.sin(a * x + b * y + p * 6) + 0.1 * rng.standard_normal((height, width)))
    return (np.clip(np.stack(channels, -1), 0, 1) * 255).round().astype(np.uint8)


def region(width, height):
    """An off-centre ellipse: the object to paint out."""
    y, x = np.mgrid[0:height, 0:width]
    inside = ((x - 0.45 * width) / (0.22 * width)) ** 2 + ((y - 0.55 * height) / (0.25 * height)) ** 2 <= 1
    return inside.astype(np.uint8) * 255


def stand_in_module(name):
    """An empty module registered under `name` and its parents (pickle imports what it names)."""
    parts = name.split(".")
    for k in range(1, len(parts) + 1):
        sys.modules.setdefault(".".join(parts[:k]), types.ModuleType(".".join(parts[:k])))
    return sys.modules[name]


def lightning_checkpoint(generator):
    """The dict PyTorch Lightning 1.x saves: the generator beside the discriminator and the
    losses' weights, the callbacks' states keyed by their classes, the optimisers'."""
    module = stand_in_module("pytorch_lightning.callbacks.model_checkpoint")

    class ModelCheckpoint:  # stands in for Lightning's: pickled by reference, as its name
        pass

    ModelCheckpoint.__module__, ModelCheckpoint.__qualname__ = module.__name__, "ModelCheckpoint"
    module.ModelCheckpoint = ModelCheckpoint
    config = stand_in_module("omegaconf.dictconfig")

    class DictConfig:  # an object pickled with its state, as a saved configuration is
        def __init__(self):
            self.content = {"kind": "ffc_resnet"}

    DictConfig.__module__, DictConfig.__qualname__ = config.__name__, "DictConfig"
    config.DictConfig = DictConfig
    torch.manual_seed(1)
    state = {f"generator.{k}": v for k, v in generator.state_dict().items()}
    state["discriminator.model0.0.ffc.convl2l.weight"] = torch.randn(8, 3, 3, 3)
    state["loss_resnet_pl.impl.encoder.conv1.weight"] = torch.randn(4, 3, 3, 3)
    return {
        "epoch": 39, "global_step": 1000, "pytorch-lightning_version": "1.2.9",
        "state_dict": state,
        "callbacks": {ModelCheckpoint: {"monitor": "val_ssim_fid100_f1_total_mean",
                                        "best_model_score": torch.tensor(0.92), "best_model_path": "models/best.ckpt"}},
        "optimizer_states": [{"state": {}, "param_groups": [{"lr": 0.001, "params": [0, 1]}]}],
        "lr_schedulers": [],
        "hparams": DictConfig(),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--lama", required=True, help="folder holding saicinpainting/")
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    torch.set_num_threads(1)  # the same sums in the same order every run
    ffc = lama_reference.load_ffc(args.lama)
    generator = lama_reference.build_generator(ffc, NGF, BLOCKS)
    out = pathlib.Path(args.out)
    (out / "lama-small" / "models").mkdir(parents=True, exist_ok=True)
    torch.save(lightning_checkpoint(generator), out / "lama-small" / "models" / "best.ckpt")
    with torch.no_grad():
        torch.jit.trace(generator, torch.rand(1, 4, 64, 64)).save(str(out / "big-lama.pt"))
    (out / "lama-small" / "config.yaml").write_text(
        "generator:\n  kind: ffc_resnet\n  input_nc: 4\n  output_nc: 3\n"
        f"  ngf: {NGF}\n  n_downsampling: 3\n  n_blocks: {BLOCKS}\n  add_out_act: sigmoid\n")
    tensors, cases = {}, []
    for k, (w, h) in enumerate(CASES):
        image, mask = photo(w, h, 10 + k), region(w, h)
        inpainted = lama_reference.predict(generator, image, mask)
        tensors[f"image_{k}"] = torch.from_numpy(image)
        tensors[f"mask_{k}"] = torch.from_numpy(mask)
        tensors[f"inpainted_{k}"] = torch.from_numpy(np.ascontiguousarray(inpainted))
        cases.append({"width": w, "height": h})
    save_file(tensors, str(out / "reference.safetensors"))
    (out / "cases.json").write_text(json.dumps(
        {"generator": {"ngf": NGF, "n_blocks": BLOCKS, "n_downsampling": 3, "ratio_global": 0.75},
         "torch": torch.__version__, "cases": cases}, indent=1) + "\n")


if __name__ == "__main__":
    main()
