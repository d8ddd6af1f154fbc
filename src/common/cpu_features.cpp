#include "common/cpu_features.h"

#include <cstdlib>

#if defined(__x86_64__) || defined(__i386__)
#include <cpuid.h>
#endif

#include "common/error.h"

namespace ii {

namespace {

CpuFeatures detect() {
  CpuFeatures f;
#if defined(__x86_64__) || defined(__i386__)
  // __builtin_cpu_supports also checks that the OS saves the AVX/AVX-512 registers.
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) f.isa = CpuIsa::Avx2;
  if (f.isa == CpuIsa::Avx2 && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
      __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512dq"))
    f.isa = CpuIsa::Avx512;
  if (f.isa == CpuIsa::Avx512 && __builtin_cpu_supports("avx512bf16")) f.isa = CpuIsa::Avx512Bf16;
  // AMX-BF16 is CPUID leaf 7 EDX bit 22 (clang 14's __builtin_cpu_supports has no name for it).
  unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
  if (__get_cpuid_count(7, 0, &eax, &ebx, &ecx, &edx)) f.amx_bf16 = (edx >> 22) & 1u;
#endif
  if (const char* cap = std::getenv("INSTAINPAINT_MAX_CPU_ISA"); cap && *cap) {
    const CpuIsa limit = parse_cpu_isa(cap, "INSTAINPAINT_MAX_CPU_ISA");
    if (limit < f.isa) f.isa = limit;
    if (limit < CpuIsa::Avx512Bf16) f.amx_bf16 = false;
  }
  return f;
}

}  // namespace

const CpuFeatures& cpu_features() {
  static const CpuFeatures features = detect();
  return features;
}

const char* cpu_isa_name(CpuIsa isa) {
  switch (isa) {
    case CpuIsa::Avx2: return "avx2";
    case CpuIsa::Avx512: return "avx512";
    case CpuIsa::Avx512Bf16: return "avx512_bf16";
    case CpuIsa::Baseline: break;
  }
  return "baseline";
}

CpuIsa parse_cpu_isa(const std::string& name, const std::string& what) {
  for (CpuIsa isa : {CpuIsa::Baseline, CpuIsa::Avx2, CpuIsa::Avx512, CpuIsa::Avx512Bf16})
    if (name == cpu_isa_name(isa)) return isa;
  fail("{}: unknown instruction set '{}' (expected baseline, avx2, avx512 or avx512_bf16)", what, name);
}

}  // namespace ii
