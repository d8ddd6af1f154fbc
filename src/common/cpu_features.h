#pragma once
// What this CPU can run, detected at run time (the same binary runs on AVX2-only CPUs and on
// ones with AVX-512 BF16 or AMX), optionally capped by INSTAINPAINT_MAX_CPU_ISA.
#include <string>

namespace ii {

// Ordered: each level includes the ones before it. Amx: AMX-TILE and AMX-BF16 beside AVX-512
// BF16, with the tile registers enabled by the operating system for this process.
enum class CpuIsa { Baseline, Avx2, Avx512, Avx512Bf16, Amx };

struct CpuFeatures {
  CpuIsa isa = CpuIsa::Baseline;  // the highest level the kernels may use
  bool amx_bf16 = false;          // the CPU has AMX-BF16 (LibTorch's oneDNN uses it for bf16 products)
  bool has(CpuIsa level) const { return isa >= level; }
  // bf16 dot products that are native, not emulated: AVX-512 BF16 or AMX.
  bool native_bf16() const { return has(CpuIsa::Avx512Bf16) || amx_bf16; }
};

// Detected once (on Linux, asking the kernel for the AMX tile state once, as every AMX user
// must). INSTAINPAINT_MAX_CPU_ISA = amx | avx512_bf16 | avx512 | avx2 | baseline lowers the
// level (to measure or test the kernels of an older CPU here); an unknown value is an error
// naming the variable and the accepted values.
const CpuFeatures& cpu_features();

const char* cpu_isa_name(CpuIsa isa);
// Parses a level name as the variable takes it; throws Error naming `what` otherwise.
CpuIsa parse_cpu_isa(const std::string& name, const std::string& what);

}  // namespace ii
