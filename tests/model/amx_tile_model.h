#pragma once
// The AMX attention kernel's loops (model/cpu/attention_amx_impl.h) on a model of the tiles, so
// that they are tested on every CPU with AVX2, not only where AMX exists.
#include <cstdint>

#include "model/cpu/kernels.h"

namespace ii::test {

// attention_amx_bf16 with the tile instructions done by the model, the softmax in AVX2; run
// only where the CPU has AVX2 (the file is compiled for it). Serial: the model's tiles are one set.
bool attention_amx_bf16_on_tile_model(const cpu_kernels::AttentionProblem& problem, cpu_kernels::ParallelFor parallel);

// How many tile instructions the last run issued outside a configure ... release pair, where
// the hardware would fault.
int64_t tile_model_unconfigured_uses();

}  // namespace ii::test
