#pragma once
// Precompiled header for every translation unit that uses LibTorch: its headers are
// large, parsing them once keeps builds on two cores short.
#include <torch/torch.h>
