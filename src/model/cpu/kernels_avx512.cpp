// The CPU kernels compiled for AVX512 (flags: CMakeLists.txt); see kernels.h.
#include "model/cpu/attention_impl.h"
#include "model/cpu/layer_norm_impl.h"

namespace ii::cpu_kernels {

bool attention_avx512_fp32(const AttentionProblem& problem, ParallelFor parallel) {
  return run_attention<Avx512Fp32>(problem, parallel);
}

void add_layer_norm_avx512_fp32(const AddNormProblem& problem, ParallelFor parallel) {
  run_add_layer_norm<Avx512Fp32>(problem, parallel);
}

}  // namespace ii::cpu_kernels
