#pragma once
// Shared helpers for tests: locating ../shared data and skipping (never silently passing)
// when it is absent.
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "io/ply.h"

namespace ii::test {

// Absolute path of `relative` under the shared folder (../shared beside the repository,
// or $INSTAINPAINT_SHARED).
std::filesystem::path shared_path(const std::string& relative);

// Why the shared file or folder `relative` cannot be used, or "" when it can. One rule for every
// test: under data/<folder>/ the folder counts only when it holds its PROVENANCE.md (an emptied
// folder is as absent as a removed one), and then the path must exist.
std::string shared_missing(const std::string& relative);

// A fresh empty temporary folder, removed at exit of the test process.
std::filesystem::path temp_dir(const std::string& tag);

// Whole-file bytes as a string, and writing a string as a file (for hand-made bad input).
std::string file_bytes(const std::filesystem::path& path);
void write_bytes(const std::filesystem::path& path, const std::string& bytes);
// Copies of `file` cut short (nothing, 100 bytes, half, all but 30 bytes), in `dir`, each with
// the extension of `file`: what a model reader must refuse naming the copy.
std::vector<std::filesystem::path> truncated_copies(const std::filesystem::path& file,
                                                    const std::filesystem::path& dir);
// The raw bytes of a vector of plain values.
template <typename T>
std::string raw(const std::vector<T>& v) {
  return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

// The first bytes of a PNG claiming width x height RGB pixels: what a decompression bomb shows
// a reader before its pixel data (enough for a header probe; no decoder gets further).
std::string png_header(uint32_t width, uint32_t height);
// The process's peak resident memory so far (Linux VmHWM), in MB.
double peak_rss_mb();

// The built `instainpaint` executable (beside the tests' folder), for end-to-end CLI tests.
std::filesystem::path cli_executable();
// Runs a shell command with stdout and stderr to `log`; returns its exit code (-1 when it
// did not exit normally).
int run_command(const std::string& command, const std::filesystem::path& log);

// Seeded random splats for the splat-format tests: positions within ±`extent`, colours (SH DC)
// within ±1.5, log scales in [-7, -1], `rest` SH coefficients per channel within ±0.9, logits
// within ±5, unnormalised rotations.
SplatCloud random_splats(size_t n, int rest, uint32_t seed, float extent);
// The angle in radians between the rotations of two quaternions (any scale, any sign).
double rotation_angle(const float* a, const float* b);

// Runs `fn` and returns the Error message it throws; fails the test if it throws nothing
// or something else.
template <typename Fn>
std::string error_message(Fn&& fn);

}  // namespace ii::test

// Skips the current test, with the reason, when a shared file or folder is missing.
#define II_REQUIRE_SHARED(var, relative)                                                   \
  const std::filesystem::path var = ::ii::test::shared_path(relative);                     \
  if (const std::string why_missing = ::ii::test::shared_missing(relative); !why_missing.empty()) \
  GTEST_SKIP() << why_missing

// Skips the current test without a GPU (no CUDA device, or a LibTorch built without CUDA).
#define II_REQUIRE_CUDA() \
  if (!torch::cuda::is_available()) GTEST_SKIP() << "no CUDA device (or LibTorch without CUDA)"

// Skips the current test when the CLI has not been built; binds its path to `var`.
#define II_REQUIRE_CLI(var)                                         \
  const std::filesystem::path var = ::ii::test::cli_executable();  \
  if (!std::filesystem::exists(var)) GTEST_SKIP() << "not built: " << var.string()

#include "common/error.h"

template <typename Fn>
std::string ii::test::error_message(Fn&& fn) {
  try {
    fn();
  } catch (const ii::Error& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected ii::Error, got another exception: " << e.what();
    return e.what();
  }
  ADD_FAILURE() << "expected ii::Error, nothing was thrown";
  return {};
}
