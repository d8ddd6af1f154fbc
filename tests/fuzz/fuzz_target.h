#pragma once
// Fuzz targets: each parser of outside input driven by arbitrary bytes. The target files
// (io_targets.cpp, scene_targets.cpp) register them by name; every libFuzzer executable
// (fuzz_main.cpp, one per target, sanitizer build with clang) links them all and runs its
// own, and the regression test of the normal suite (fuzz_regression_test.cpp) replays every
// target's hand-made seeds and every input a fuzzer once failed on
// (tests/fuzz/regressions/<target>/).
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace ii::fuzz {

struct FuzzTarget {
  std::string name;
  // Minimal valid inputs made by hand (with the project's writers where there is one); the
  // regression test requires each to be accepted.
  std::function<std::vector<std::string>()> seeds;
  // Parses the bytes; bad input must end in ii::Error, anything else is a finding.
  std::function<void(const uint8_t* data, size_t size)> run;
};

// Registers at static initialisation: `static const bool registered = register_target({...});`
bool register_target(FuzzTarget target);
const std::vector<FuzzTarget>& targets();
const FuzzTarget* find_target(const std::string& name);

// A folder of this process's own under $TMPDIR (or /tmp), removed at exit.
const std::filesystem::path& scratch_dir();
// Plain (non-atomic) whole-file write: the fuzz loop writes its input tens of thousands of
// times a second.
void write_file(const std::filesystem::path& path, const uint8_t* data, size_t size);
void write_file(const std::filesystem::path& path, const std::string& bytes);
// The bytes a writer of the project produces, for seeds: `write(path)` fills a temporary file.
std::string bytes_written_by(const std::function<void(const std::filesystem::path&)>& write);

}  // namespace ii::fuzz
