"""LaMa's generator as the reference code builds and runs it, for the scripts beside this file.

Its module (saicinpainting/training/modules/ffc.py) is imported from an extracted copy of
github.com/advimman/lama without its package's __init__ files, which import the training code;
the two libraries its sibling modules import only for other networks (kornia, pytorch_lightning)
are stood in for by empty modules. Nothing here is LaMa's code; inference follows bin/predict.py
(pad to a multiple of 8 by symmetric reflection, the masked photo and the mask in, the
prediction blended into the photo outside the mask, the padding cut)."""
import importlib
import pathlib
import sys
import types

import numpy as np
import torch


def load_ffc(lama_dir):
    root = pathlib.Path(lama_dir) / "saicinpainting"
    for name in ("kornia", "kornia.geometry", "kornia.geometry.transform"):
        sys.modules.setdefault(name, types.ModuleType(name))
    sys.modules["kornia.geometry.transform"].rotate = None
    lightning = sys.modules.setdefault("pytorch_lightning", types.ModuleType("pytorch_lightning"))
    lightning.seed_everything = lambda *a, **k: None
    for name, path in (("saicinpainting", root), ("saicinpainting.training", root / "training"),
                       ("saicinpainting.training.modules", root / "training" / "modules")):
        package = types.ModuleType(name)
        package.__path__ = [str(path)]
        sys.modules[name] = package
    return importlib.import_module("saicinpainting.training.modules.ffc")


def build_generator(ffc, ngf, n_blocks, n_downsampling=3, seed=0):
    """big-lama's generator (configs/training/big-lama.yaml) at `ngf` and `n_blocks`, with seeded
    random weights and batch-norm statistics (so that every term of the forward pass counts)."""
    torch.manual_seed(seed)
    g = ffc.FFCResNetGenerator(
        input_nc=4, output_nc=3, ngf=ngf, n_downsampling=n_downsampling, n_blocks=n_blocks, add_out_act="sigmoid",
        init_conv_kwargs=dict(ratio_gin=0, ratio_gout=0, enable_lfu=False),
        downsample_conv_kwargs=dict(ratio_gin=0, ratio_gout=0, enable_lfu=False),
        resnet_conv_kwargs=dict(ratio_gin=0.75, ratio_gout=0.75, enable_lfu=False))
    with torch.no_grad():
        for m in g.modules():
            if isinstance(m, torch.nn.BatchNorm2d):
                m.weight.uniform_(0.5, 1.5)
                m.bias.normal_(0, 0.1)
                m.running_mean.normal_(0, 0.1)
                m.running_var.uniform_(0.5, 1.5)
    return g.eval()


def ceil_modulo(x, mod):
    return x if x % mod == 0 else (x // mod + 1) * mod


def predict(generator, image, mask, mod=8):
    """image (H, W, 3) uint8, mask (H, W) uint8 (> 0: the region) -> (H, W, 3) float32 in [0, 1]:
    bin/predict.py's 'inpainted' before it is rounded to bytes."""
    img = image.transpose(2, 0, 1).astype("float32") / 255
    m = (mask[None].astype("float32") / 255)
    h, w = img.shape[1:]
    pad = ((0, 0), (0, ceil_modulo(h, mod) - h), (0, ceil_modulo(w, mod) - w))
    img_t = torch.from_numpy(np.pad(img, pad, mode="symmetric"))[None]
    m_t = torch.from_numpy(np.pad(m, pad, mode="symmetric"))[None]
    m_t = (m_t > 0) * 1
    with torch.no_grad():
        masked = torch.cat([img_t * (1 - m_t), m_t], dim=1)
        predicted = generator(masked)
        inpainted = m_t * predicted + (1 - m_t) * img_t
    return inpainted[0].permute(1, 2, 0).numpy()[:h, :w]
