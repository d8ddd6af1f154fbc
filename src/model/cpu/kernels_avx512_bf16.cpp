// The CPU kernels compiled for AVX512 + BF16 (flags: CMakeLists.txt); see kernels.h.
#include "model/cpu/attention_impl.h"
#include "model/cpu/layer_norm_impl.h"

namespace ii::cpu_kernels {

bool attention_avx512_bf16(const AttentionProblem& problem, ParallelFor parallel) {
  return run_attention<Avx512Bf16>(problem, parallel);
}

void add_layer_norm_avx512_bf16(const AddNormProblem& problem, ParallelFor parallel) {
  run_add_layer_norm<Avx512Bf16>(problem, parallel);
}

}  // namespace ii::cpu_kernels
