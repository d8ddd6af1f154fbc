// `instainpaint bench`: speed of the network on this machine, against a straightforward
// float32 LibTorch implementation (materialised attention) measured in the same run.
#include <spdlog/spdlog.h>
#include <fmt/core.h>

#include <fstream>
#include <sstream>

#include "cli/commands.h"
#include "cli/runtime.h"
#include "common/stopwatch.h"
#include "model/network.h"

namespace ii::cli {

namespace {

struct BenchArgs {
  std::vector<std::string> presets = {"small", "base", "release"};
  std::vector<int> sizes = {256, 512};
  int views = 4;
  int repeat = 1;
  bool baseline = true;
  double baseline_max_gb = 6.0;
  RuntimeOptions runtime;
};

// Peak resident memory since the last reset, in GiB (Linux VmHWM).
double peak_rss_gb() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / (1024.0 * 1024.0);
  return 0;
}
void reset_peak_rss() { std::ofstream("/proc/self/clear_refs") << "5"; }

double time_forward(const Network& net, int views, int size, Precision precision, int repeat) {
  const auto images = torch::rand({1, views, 4, size, size}) * 2 - 1;
  const auto plucker = torch::randn({1, views, 6, size, size});
  const auto rays = torch::randn({1, views, size, size, 3});
  torch::InferenceMode guard;
  double best = 1e30;
  for (int r = 0; r < repeat; ++r) {
    Stopwatch w;
    net.forward(images, plucker, rays, rays, precision);
    best = std::min(best, w.ms());
  }
  return best;
}

void run(const BenchArgs& a) {
  const Precision precision = apply_runtime_options(a.runtime);
  fmt::print("network benchmark: {} threads, {} ({} views, best of {})\n", torch::get_num_threads(),
             precision_name(precision), a.views, a.repeat);
  fmt::print("{:<8} {:>5} {:>7} {:>10} {:>9} {:>8} | {:>12} {:>9} {:>8} {:>7}\n", "preset", "size", "tokens",
             "ms", "GFLOP/s", "peak GB", "baseline ms", "GFLOP/s", "peak GB", "ratio");
  for (const std::string& preset : a.presets) {
    const ModelConfig config = ModelConfig::from_preset(preset);
    Network net(config);
    for (int size : a.sizes) {
      const double flops = config.forward_flops(a.views, size, size);
      const int64_t tokens = static_cast<int64_t>(a.views) * (size / config.patch) * (size / config.patch);
      reset_peak_rss();
      net.set_naive_attention(false);
      const double ms = time_forward(net, a.views, size, precision, a.repeat);
      const double peak = peak_rss_gb();
      std::string base = fmt::format("{:>12} {:>9} {:>8} {:>7}", "-", "-", "-", "-");
      // Score matrix of the textbook attention: heads x N x N floats (plus softmax copy).
      const double naive_gb = 2.0 * config.heads * tokens * tokens * 4 / 1e9;
      if (a.baseline && naive_gb <= a.baseline_max_gb) {
        reset_peak_rss();
        net.set_naive_attention(true);
        const double base_ms = time_forward(net, a.views, size, Precision::Float32, a.repeat);
        net.set_naive_attention(false);
        base = fmt::format("{:>12.0f} {:>9.1f} {:>8.2f} {:>6.2f}x", base_ms, flops / base_ms / 1e6,
                           peak_rss_gb(), base_ms / ms);
      } else if (a.baseline) {
        base = fmt::format("{:>12} {:>9} {:>8} {:>7}", "skipped", "-",
                           fmt::format("{:.0f}", naive_gb), "-");
      }
      fmt::print("{:<8} {:>5} {:>7} {:>10.0f} {:>9.1f} {:>8.2f} | {}\n", preset, size, tokens, ms,
                 flops / ms / 1e6, peak, base);
      std::fflush(stdout);
    }
  }
  fmt::print("baseline: float32, unfused, attention with the full score matrix "
             "(skipped when that matrix needs more than {:.0f} GB; its size is shown)\n",
             a.baseline_max_gb);
}

}  // namespace

void add_bench_command(CLI::App& app) {
  auto args = std::make_shared<BenchArgs>();
  auto* cmd = app.add_subcommand("bench", "Time the network (random weights) on this machine");
  cmd->add_option("--presets", args->presets, "Model presets")->delimiter(',')->capture_default_str();
  cmd->add_option("--sizes", args->sizes, "Square input sizes in pixels")->delimiter(',')->capture_default_str();
  cmd->add_option("--views", args->views, "Input views")->capture_default_str();
  cmd->add_option("--repeat", args->repeat, "Runs per configuration (best is reported)")->capture_default_str();
  cmd->add_flag("!--no-baseline", args->baseline, "Skip the float32 textbook baseline");
  cmd->add_option("--baseline-max-gb", args->baseline_max_gb,
                  "Largest attention score matrix the baseline may allocate")
      ->capture_default_str();
  add_runtime_options(cmd, args->runtime);
  cmd->footer("Example: instainpaint bench --presets release --sizes 256");
  cmd->callback([args] { run(*args); });
}

}  // namespace ii::cli
