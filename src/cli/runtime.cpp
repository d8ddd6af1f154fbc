#include "cli/runtime.h"

#include "model/device.h"

namespace ii::cli {

void add_runtime_options(CLI::App* cmd, RuntimeOptions& options) {
  cmd->add_option("--device", options.device,
                  "Where the work runs: auto (a GPU when LibTorch sees one), cpu, cuda, cuda:N")
      ->capture_default_str();
  cmd->add_option("--threads", options.threads,
                  "CPU cores to use (0 = $OMP_NUM_THREADS, else all): LibTorch gets them all on a CPU run and half on "
                  "a GPU run; a quarter decode input files ahead, a quarter write output files behind")
      ->capture_default_str();
  cmd->add_option("--precision", options.precision,
                  "Network precision; auto = bf16 on a GPU and on CPUs with native bf16 (AVX512-BF16/AMX), "
                  "else fp32")
      ->check(CLI::IsMember({"auto", "fp32", "bf16"}))
      ->capture_default_str();
}

namespace {
bool gpu_set_up = false;
}  // namespace

Runtime apply_runtime_options(const RuntimeOptions& options) {
  const Runtime runtime = set_up_runtime(options.device, options.threads, options.precision);
  gpu_set_up = gpu_set_up || runtime.device.is_cuda();
  return runtime;
}

bool gpu_was_set_up() { return gpu_set_up; }

}  // namespace ii::cli
