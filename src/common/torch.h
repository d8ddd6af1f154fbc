#pragma once
// The parts of LibTorch this project builds on: tensors and their factories, autograd (grad, custom
// functions), seeding and grad modes, CUDA queries. Every LibTorch file includes this (it is also the
// precompiled header); the few that need more (nn::functional, nn modules, serialisation) include that
// beside it. <torch/torch.h> would add modules, optimisers, data loaders and the JIT: about 3 s more in
// every translation unit (docs/architecture.md, "Libraries and layers").
#include <torch/csrc/autograd/autograd.h>
#include <torch/csrc/autograd/custom_function.h>
#include <torch/cuda.h>
#include <torch/types.h>
#include <torch/utils.h>
#include <torch/version.h>
