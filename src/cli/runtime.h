#pragma once
// Threads and numeric precision, shared by every command that runs the network.
#include <CLI/CLI.hpp>

#include "model/network.h"

namespace ii::cli {

struct RuntimeOptions {
  int threads = 0;                  // 0 = all cores
  std::string precision = "auto";   // auto | fp32 | bf16
};

void add_runtime_options(CLI::App* cmd, RuntimeOptions& options);
// Sets the thread count; returns the precision to use.
Precision apply_runtime_options(const RuntimeOptions& options);

}  // namespace ii::cli
