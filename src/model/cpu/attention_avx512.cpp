// Compiled with this instruction set's flags (CMakeLists.txt); see attention_kernels.h.
#include "model/cpu/attention_kernel_impl.h"

namespace ii::cpu_attention {

void attention_avx512_fp32(const Problem& problem, ParallelFor parallel) { run_attention<Avx512Fp32>(problem, parallel); }

}  // namespace ii::cpu_attention
