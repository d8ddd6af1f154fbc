#include "common/cpu_features.h"

#include <cstdlib>

#if defined(__x86_64__) || defined(__i386__)
#include <cpuid.h>
#endif
#if defined(__linux__) && defined(__x86_64__)
#include <sys/syscall.h>
#include <unistd.h>
#endif

#include "common/error.h"

namespace ii {

namespace {

#if defined(__x86_64__) || defined(__i386__)
// Whether the operating system saves the AMX tile state (XCR0 bits 17 and 18) and, on Linux,
// lets this process use it: since Linux 5.16 a process asks once (ARCH_REQ_XCOMP_PERM for
// XFEATURE_XTILEDATA); a tile instruction without that permission is a fault.
bool amx_enabled_by_os() {
  unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
  if (!__get_cpuid(1, &eax, &ebx, &ecx, &edx) || !((ecx >> 27) & 1u)) return false;  // OSXSAVE
  unsigned xcr0 = 0, high = 0;
  __asm__ volatile("xgetbv" : "=a"(xcr0), "=d"(high) : "c"(0));
  if (((xcr0 >> 17) & 3u) != 3u) return false;
#if defined(__linux__) && defined(__x86_64__)
  constexpr long kArchReqXcompPerm = 0x1023, kXfeatureXtiledata = 18;
  if (syscall(SYS_arch_prctl, kArchReqXcompPerm, kXfeatureXtiledata) != 0) return false;
#endif
  return true;
}
#endif

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
  // AMX-TILE is bit 24.
  const bool amx_tile = __get_cpuid_count(7, 0, &eax, &ebx, &ecx, &edx) && ((edx >> 24) & 1u);
  f.amx_bf16 = amx_tile && ((edx >> 22) & 1u);
  if (f.isa == CpuIsa::Avx512Bf16 && f.amx_bf16 && amx_enabled_by_os()) f.isa = CpuIsa::Amx;
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
    case CpuIsa::Amx: return "amx";
    case CpuIsa::Baseline: break;
  }
  return "baseline";
}

CpuIsa parse_cpu_isa(const std::string& name, const std::string& what) {
  for (CpuIsa isa : {CpuIsa::Baseline, CpuIsa::Avx2, CpuIsa::Avx512, CpuIsa::Avx512Bf16, CpuIsa::Amx})
    if (name == cpu_isa_name(isa)) return isa;
  fail("{}: unknown instruction set '{}' (expected baseline, avx2, avx512, avx512_bf16 or amx)", what, name);
}

}  // namespace ii
