#!/usr/bin/env python3
"""Times the *official* InstaInpaint network's forward pass on the CPU.

The counterpart of `build/instainpaint bench --presets release --sizes 256 --baseline none`:
random weights, batch 1, V views of SIZE x SIZE, each view a 4-channel image (RGB in [-1,1] +
mask) and a 6-channel Plücker map, under torch.autocast("cpu", bfloat16) (or fp32) and
torch.no_grad(). One untimed warm-up call, then --repeat timed calls; prints one line per call
and a summary line with the best time.

    python3 scripts/official_cpu_forward.py --official /tmp/official \
        --views 4 --size 256 --threads 2 --repeat 2 --precision bf16

--official is an extracted checkout of github.com/dhmbb2/InstaInpaint (commit 08659e4): a
folder holding instainpaint/models/*.py. The official code is fetched separately and never
copied into or committed with this project (scripts/measure-official-cpu.sh extracts it from a
git mirror into a temporary folder).

The network is built exactly as instainpaint/evaluate.py builds it (mvencoder_base with depth 0,
ExtraTokenEmbed as identity, AeGaussianTransformer with 24 weight-normed blocks, 16 heads,
GaussianMlpUpsampler with five 1024-wide heads; its constants EMBED_DIM, PATCH_SIZE,
TRANSFORMER_DEPTH, DEPTH_BIAS, MODEL_INPUT_CHANNELS are read from evaluate.py), and the forward
follows evaluate.py's test_one_iteration: encoder (cls token prepended, normed, dropped),
transformer, upsampler, then xyz = o + depth * d_un in fp32. Nothing in the official files is
edited; only these run-time substitutions are made before importing them:

* flash_attn (CUDA only) is replaced by a stub module whose flash_attn_qkvpacked_func computes
  plain attention, softmax(q k^T / sqrt(d)) v, with torch.matmul and softmax (the full score
  matrix, heads x N x N, is materialised: 16 x 4096 x 4096 at 4 views of 256²);
* torch < 2.1's nn.LayerNorm has no `bias` argument: a subclass that accepts it (the official
  norms have no affine parameters at all, so it changes nothing) is put in its place.

Weight norm is kept, so as in the official code every Linear's weight is recomputed as
g * v / |v| (and cast to bf16 by autocast) on every call.
"""
import argparse
import ast
import inspect
import math
import os
import resource
import sys
import time
import types

import torch
import torch.nn.functional as F

RELEASE = dict(EMBED_DIM=1024, PATCH_SIZE=8, TRANSFORMER_DEPTH=24, DEPTH_BIAS=-4, MODEL_INPUT_CHANNELS=4)


def plain_attention_qkvpacked(qkv, dropout_p=0.0, softmax_scale=None, causal=False, **unused):
    """flash_attn_qkvpacked_func's contract: qkv (B, N, 3, H, d) -> (B, N, H, d)."""
    if causal:
        raise NotImplementedError("the official network never asks for causal attention")
    q, k, v = qkv.permute(2, 0, 3, 1, 4).unbind(0)  # each (B, H, N, d)
    scale = softmax_scale if softmax_scale is not None else 1.0 / math.sqrt(q.shape[-1])
    attn = torch.softmax(torch.matmul(q * scale, k.transpose(-2, -1)), dim=-1)
    if dropout_p > 0.0:
        attn = F.dropout(attn, p=dropout_p)
    return torch.matmul(attn, v).transpose(1, 2)


def install_substitutes():
    stub = types.ModuleType("flash_attn")
    stub.flash_attn_qkvpacked_func = plain_attention_qkvpacked
    sys.modules["flash_attn"] = stub

    if "bias" not in inspect.signature(torch.nn.LayerNorm.__init__).parameters:

        class LayerNorm(torch.nn.LayerNorm):
            def __init__(self, normalized_shape, eps=1e-5, elementwise_affine=True, bias=True, **kw):
                if elementwise_affine and not bias:
                    raise NotImplementedError("LayerNorm with a weight but no bias needs torch >= 2.1")
                super().__init__(normalized_shape, eps=eps, elementwise_affine=elementwise_affine, **kw)

        torch.nn.LayerNorm = LayerNorm


def release_constants(official):
    """The integer constants evaluate.py hard-codes for the release model."""
    constants = dict(RELEASE)
    path = os.path.join(official, "instainpaint", "evaluate.py")
    if os.path.exists(path):
        for node in ast.parse(open(path).read()).body:
            if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name):
                name = node.targets[0].id
                if name in constants:
                    constants[name] = ast.literal_eval(node.value)
    return constants


def build(official, views):
    sys.path.insert(0, os.path.abspath(official))
    from instainpaint.models.aegaussian_decoder import AeGaussianTransformer
    from instainpaint.models.gaussian_decoder import GaussianMlpUpsampler
    from instainpaint.models.multiview_encoder import ExtraTokenEmbed, mvencoder_base

    c = release_constants(official)
    # Arguments as in instainpaint/evaluate.py, test_lrm().
    mvencoder = mvencoder_base(type="plucker", with_bg=False, in_chans=c["MODEL_INPUT_CHANNELS"], depth=0,
                               embed_dim=c["EMBED_DIM"], patch_size=c["PATCH_SIZE"], use_pos_embed=False,
                               emb_use_bias=False, norm_use_bias=False, norm_use_affine=False,
                               input_image_num=views, temporal_subsampling=False, temporal_subsample_freq=8)
    extra = ExtraTokenEmbed(embed_dim=c["EMBED_DIM"], input_image_num=views, use_time_embed=False,
                            use_triplane=False, triplane_num_tokens=32**2 * 3)
    decoder = AeGaussianTransformer(embed_dim=c["EMBED_DIM"], depth=c["TRANSFORMER_DEPTH"], attn_use_bias=False,
                                    norm_use_bias=False, norm_use_affine=False, use_weight_norm=True)
    upsampler = GaussianMlpUpsampler(mlp_dim=1024, token_dim=c["EMBED_DIM"], patch_size=c["PATCH_SIZE"],
                                     depth_bias=c["DEPTH_BIAS"], norm_use_bias=False, norm_use_affine=False,
                                     use_weight_norm=True, input_image_num=views)
    modules = [m.eval().requires_grad_(False) for m in (mvencoder, extra, decoder, upsampler)]
    return modules, c


def forward(modules, images, plucker, rays_o, rays_d_un, dtype):
    """evaluate.py's test_one_iteration + encode_plucker_rays, from ready Plücker maps."""
    mvencoder, extra, decoder, upsampler = modules
    B, V, C, H, W = images.shape
    with torch.autocast("cpu", dtype=torch.bfloat16, enabled=dtype == torch.bfloat16):
        tokens = mvencoder(images.reshape(B * V, C, H, W).to(dtype), plucker.reshape(B * V, 6, H, W).to(dtype))
        tokens = tokens[:, 1:, :]  # drop the cls token
        tokens = tokens.reshape(B, V, tokens.shape[1], -1).flatten(1, 2)
        tokens = decoder(extra(tokens))
        gaussians = upsampler(tokens, None, None, images)
    gaussians = {k: v.float() for k, v in gaussians.items()}
    gaussians["xyz"] = rays_o + rays_d_un * gaussians["depth"]
    return gaussians


def forward_flops(c, views, size, upsampler_dim=1024):
    """Same count as ModelConfig::forward_flops (src/model/config.cpp)."""
    D, p2 = c["EMBED_DIM"], c["PATCH_SIZE"] ** 2
    N = views * (size // c["PATCH_SIZE"]) ** 2
    f = 2 * N * D * (c["MODEL_INPUT_CHANNELS"] + 6) * p2
    f += c["TRANSFORMER_DEPTH"] * (2 * N * D * D * (3 + 1 + 2 * 4) + 4 * N * N * D)
    f += sum(2 * N * (D * upsampler_dim + upsampler_dim * p2 * ch) for ch in (1, 3, 1, 3, 4))
    return f


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--official", required=True, help="extracted official checkout (holds instainpaint/)")
    ap.add_argument("--views", type=int, default=4)
    ap.add_argument("--size", type=int, default=256, help="square input size in pixels")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=2, help="timed runs after one warm-up")
    ap.add_argument("--precision", choices=["bf16", "fp32"], default="bf16")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    if a.repeat < 1 or a.threads < 1 or a.views < 1:
        ap.error("--repeat, --threads and --views must be at least 1")
    if not os.path.isfile(os.path.join(a.official, "instainpaint", "models", "utils.py")):
        sys.exit(f"--official {a.official}: no instainpaint/models/utils.py there (extract the official repo first)")

    torch.set_num_threads(a.threads)
    torch.manual_seed(a.seed)
    install_substitutes()
    modules, c = build(a.official, a.views)
    if a.size % c["PATCH_SIZE"]:
        sys.exit(f"--size {a.size} is not a multiple of the patch size {c['PATCH_SIZE']}")
    dtype = torch.bfloat16 if a.precision == "bf16" else torch.float32

    # The inputs `instainpaint bench` feeds (src/cli/bench.cpp, random_inputs).
    V, S = a.views, a.size
    images = torch.rand(1, V, 4, S, S) * 2 - 1
    plucker = torch.randn(1, V, 6, S, S)
    rays = torch.randn(1, V, S, S, 3).permute(0, 1, 4, 2, 3)

    params = sum(p.numel() for m in modules for p in m.parameters())
    tokens = V * (S // c["PATCH_SIZE"]) ** 2
    print(f"official InstaInpaint network (torch {torch.__version__}), {params / 1e6:.1f}M parameters, "
          f"{V}x{S}x{S} -> {tokens} tokens, {a.precision}, {torch.get_num_threads()} threads, "
          f"attention: plain matmul/softmax (flash-attn replaced)", flush=True)
    best = math.inf
    with torch.no_grad():
        for r in range(a.repeat + 1):
            t = time.perf_counter()
            out = forward(modules, images, plucker, rays, rays, dtype)
            s = time.perf_counter() - t
            label = "warm-up" if r == 0 else f"run {r}/{a.repeat}"
            if r > 0:
                best = min(best, s)
            print(f"{label}: {s:.2f} s", flush=True)
    assert out["xyz"].shape == (1, V, 3, S, S) and torch.isfinite(out["xyz"]).all()
    peak_gb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e9  # KiB on Linux
    gflops = forward_flops(c, V, S) / best / 1e9 if best < math.inf else 0.0
    print(f"official release {V}x{S}x{S} {a.precision} threads={a.threads}: best {best:.1f} s "
          f"({gflops:.1f} GFLOP/s, peak RSS {peak_gb:.1f} GB)")


if __name__ == "__main__":
    main()
