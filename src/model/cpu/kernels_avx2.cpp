// The CPU kernels compiled for AVX2 (flags: CMakeLists.txt); see kernels.h.
#include "model/cpu/attention_impl.h"
#include "model/cpu/layer_norm_impl.h"

namespace ii::cpu_kernels {

bool attention_avx2_fp32(const AttentionProblem& problem, ParallelFor parallel) {
  return run_attention<Avx2Fp32>(problem, parallel);
}

void add_layer_norm_avx2_fp32(const AddNormProblem& problem, ParallelFor parallel) {
  run_add_layer_norm<Avx2Fp32>(problem, parallel);
}

}  // namespace ii::cpu_kernels
