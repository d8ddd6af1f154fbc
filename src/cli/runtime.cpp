#include "cli/runtime.h"

#include <thread>

namespace ii::cli {

void add_runtime_options(CLI::App* cmd, RuntimeOptions& options) {
  cmd->add_option("--threads", options.threads, "CPU threads (0 = all cores)")->capture_default_str();
  cmd->add_option("--precision", options.precision,
                  "Network precision: bf16 where the CPU has native bf16 (AVX512-BF16/AMX), else fp32")
      ->check(CLI::IsMember({"auto", "fp32", "bf16"}))
      ->capture_default_str();
}

Precision apply_runtime_options(const RuntimeOptions& options) {
  const int threads = options.threads > 0 ? options.threads : static_cast<int>(std::thread::hardware_concurrency());
  torch::set_num_threads(std::max(1, threads));
  if (options.precision == "fp32") return Precision::Float32;
  if (options.precision == "bf16") return Precision::BFloat16;
  return default_cpu_precision();
}

}  // namespace ii::cli
