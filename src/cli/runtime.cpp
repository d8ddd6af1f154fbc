#include "cli/runtime.h"

#include <thread>

#include "model/device.h"

namespace ii::cli {

void add_runtime_options(CLI::App* cmd, RuntimeOptions& options) {
  cmd->add_option("--device", options.device,
                  "Where the work runs: auto (a GPU when LibTorch sees one), cpu, cuda, cuda:N")
      ->capture_default_str();
  cmd->add_option("--threads", options.threads, "CPU threads (0 = all cores)")->capture_default_str();
  cmd->add_option("--precision", options.precision,
                  "Network precision; auto = bf16 on a GPU and on CPUs with native bf16 (AVX512-BF16/AMX), "
                  "else fp32")
      ->check(CLI::IsMember({"auto", "fp32", "bf16"}))
      ->capture_default_str();
}

Runtime apply_runtime_options(const RuntimeOptions& options) {
  const int threads = options.threads > 0 ? options.threads : static_cast<int>(std::thread::hardware_concurrency());
  torch::set_num_threads(std::max(1, threads));
  Runtime r;
  r.device = resolve_device(options.device);
  if (options.precision == "fp32")
    r.precision = Precision::Float32;
  else if (options.precision == "bf16")
    r.precision = Precision::BFloat16;
  else
    r.precision = default_precision(r.device);
  return r;
}

}  // namespace ii::cli
