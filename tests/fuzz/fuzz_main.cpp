// libFuzzer entry points for one target, named at compile time (II_FUZZ_TARGET). With
// II_FUZZ_WRITE_SEEDS=<folder> the executable writes the target's hand-made seeds there and
// exits (scripts/fuzz.sh builds the starting corpus that way).
#include <spdlog/spdlog.h>

#include <cstdio>
#include <cstdlib>

#include "common/error.h"
#include "fuzz_target.h"

namespace {
const ii::fuzz::FuzzTarget& the_target() {
  static const ii::fuzz::FuzzTarget* target = [] {
    const ii::fuzz::FuzzTarget* t = ii::fuzz::find_target(II_FUZZ_TARGET);
    if (!t) {
      std::fprintf(stderr, "no fuzz target named %s\n", II_FUZZ_TARGET);
      std::abort();
    }
    return t;
  }();
  return *target;
}
}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);  // readers' warnings would flood the fuzzer's output
  const ii::fuzz::FuzzTarget& target = the_target();
  if (const char* dir = std::getenv("II_FUZZ_WRITE_SEEDS")) {
    const std::vector<std::string> seeds = target.seeds();
    for (size_t k = 0; k < seeds.size(); ++k)
      ii::fuzz::write_file(std::filesystem::path(dir) / ("hand-made-" + std::to_string(k)), seeds[k]);
    std::exit(0);
  }
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    the_target().run(data, size);
  } catch (const ii::Error&) {
    // the expected answer to bad input; any other exception escapes and is a finding
  }
  return 0;
}
