#pragma once
// What this CPU can run, detected at run time (the same binary runs on AVX2-only CPUs and on
// ones with AVX-512 BF16 or AMX), optionally capped by INSTAINPAINT_MAX_CPU_ISA.
#include <string>

namespace ii {

// Ordered: each level includes the ones before it.
enum class CpuIsa { Baseline, Avx2, Avx512, Avx512Bf16 };

struct CpuFeatures {
  CpuIsa isa = CpuIsa::Baseline;  // the highest level the kernels may use
  bool amx_bf16 = false;          // native bf16 matrix products in LibTorch (oneDNN)
  bool has(CpuIsa level) const { return isa >= level; }
  // bf16 dot products that are native, not emulated: AVX-512 BF16 or AMX.
  bool native_bf16() const { return has(CpuIsa::Avx512Bf16) || amx_bf16; }
};

// Detected once. INSTAINPAINT_MAX_CPU_ISA = avx2 | avx512 | avx512_bf16 | baseline lowers
// the level (to measure or test the kernels of an older CPU here); an unknown value is an
// error naming the variable and the accepted values.
const CpuFeatures& cpu_features();

const char* cpu_isa_name(CpuIsa isa);
// Parses a level name as the variable takes it; throws Error naming `what` otherwise.
CpuIsa parse_cpu_isa(const std::string& name, const std::string& what);

}  // namespace ii
