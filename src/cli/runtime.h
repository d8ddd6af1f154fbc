#pragma once
// Device, threads and numeric precision, shared by every command that runs the network.
#include <CLI/CLI.hpp>

#include "model/device.h"

namespace ii::cli {

struct RuntimeOptions {
  std::string device = "auto";      // auto | cpu | cuda | cuda:N
  int threads = 0;                  // 0 = all cores
  std::string precision = "auto";   // auto | fp32 | bf16
};

void add_runtime_options(CLI::App* cmd, RuntimeOptions& options);
// set_up_runtime with the options' values.
Runtime apply_runtime_options(const RuntimeOptions& options);
// Whether a command of this process set up a GPU (main then leaves without LibTorch's CUDA
// teardown: the command has written and synced everything by then).
bool gpu_was_set_up();

}  // namespace ii::cli
