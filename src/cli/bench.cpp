// `instainpaint bench`: speed of the network (random weights) on this machine, against a
// baseline implementation measured in the same run: on a GPU the official code's way of
// computing (eager, weights cast on every call as autocast does, the heads one by one), on
// the CPU a straightforward float32 one (attention with the full score matrix).
// `bench --attention`: one global attention call in each of its forms.
#include <fmt/core.h>

#include <algorithm>
#include <functional>
#include <optional>

#include "cli/commands.h"
#include "cli/runtime.h"
#include "cli/size_option.h"
#include "common/error.h"
#include "common/stopwatch.h"
#include "common/torch_compat.h"
#include "model/attention.h"
#include "model/cpu/dispatch.h"
#include "model/cuda_graph.h"
#include "model/device.h"
#include "model/network.h"

namespace ii::cli {

namespace {

struct BenchArgs {
  std::vector<std::string> presets = {"small", "base", "release"};
  std::vector<std::string> sizes = {"256", "512"};
  int views = 4;
  int repeat = 0;  // 0 = 1 on the CPU, 20 on a GPU
  std::string baseline = "auto";
  bool cuda_graph = true;
  double baseline_max_gb = 6.0;
  bool attention = false;
  bool profile = false;
  int64_t tokens = 16384, heads = 16, head_dim = 64;
  RuntimeOptions runtime;
};

struct Inputs {
  torch::Tensor images, plucker, rays;
};

Inputs random_inputs(int views, const InputSize& s, const torch::Device& device) {
  Inputs in;
  in.images = (torch::rand({1, views, 4, s.height, s.width}) * 2 - 1).to(device);
  in.plucker = torch::randn({1, views, 6, s.height, s.width}).to(device);
  in.rays = torch::randn({1, views, s.height, s.width, 3}).to(device);
  return in;
}

// Best of `repeat` timed calls of `step`, each waited for; after one untimed warm-up call on a
// GPU, and on a CPU when several calls are asked for (one call of a large model can take minutes).
template <class Step>
double best_ms(const torch::Device& device, int repeat, Step&& step) {
  if (device.is_cuda() || repeat > 1) {
    step();
    synchronize(device);
  }
  double best = 1e30;
  for (int r = 0; r < repeat; ++r) {
    Stopwatch w;
    step();
    synchronize(device);
    best = std::min(best, w.ms());
  }
  return best;
}

double time_forward(const Network& net, const Inputs& in, Precision precision, const torch::Device& device,
                    int repeat) {
  torch::InferenceMode guard;
  return best_ms(device, repeat, [&] { net.forward(in.images, in.plucker, in.rays, in.rays, precision); });
}

// The official implementation's way of computing, in this code: eager, bf16 weights cast on
// every call (autocast), the five heads one by one; attention as in the fast path (on a GPU
// the official code also calls LibTorch's fused kernels).
ExecutionOptions official_equivalent() {
  ExecutionOptions o;
  o.fused_heads = false;
  o.cached_weights = false;
  o.fused_norms = false;
  return o;
}

ExecutionOptions textbook() {
  ExecutionOptions o = official_equivalent();
  o.attention = AttentionForm::Full;
  return o;
}

// The fast path as it was before the fused CPU kernels: attention by the chunked LibTorch
// calls, residual add and layer norm as separate operations.
ExecutionOptions unfused() {
  ExecutionOptions o;
  o.attention = AttentionForm::Chunked;
  o.fused_norms = false;
  return o;
}

ExecutionOptions baseline_execution(const std::string& baseline) {
  if (baseline == "official") return official_equivalent();
  if (baseline == "unfused") return unfused();
  return textbook();
}

// Each stage's share of one call, largest first.
void print_profile(const std::string& what, const StageProfile& profile) {
  auto stages = profile.ms;
  std::sort(stages.begin(), stages.end(), [](const auto& a, const auto& b) { return a.second > b.second; });
  const double total = profile.total();
  fmt::print("  {} stages, {:.1f} ms:\n", what, total);
  for (const auto& [stage, ms] : stages)
    fmt::print("    {:<26} {:>10.1f} ms {:>5.1f} %\n", stage, ms, 100.0 * ms / total);
}

// The textbook attention's score matrix: heads x N x N floats, plus the softmax copy, in GB.
double full_attention_gb(int64_t heads, int64_t tokens) {
  return 2.0 * heads * static_cast<double>(tokens) * tokens * 4 / 1e9;
}

// One attention call (q, k, v strided as the network makes them) in each form that runs here.
void run_attention(const BenchArgs& a, const Runtime& rt) {
  const int repeat = a.repeat > 0 ? a.repeat : 3;
  const auto dtype = rt.precision == Precision::Float32 ? torch::kFloat32 : torch::kBFloat16;
  torch::manual_seed(0);
  const torch::Tensor qkv =
      torch::randn({1, a.tokens, 3, a.heads, a.head_dim}).to(rt.device, dtype).permute({2, 0, 3, 1, 4});
  const torch::Tensor q = qkv[0], k = qkv[1], v = qkv[2];
  const double flops = 4.0 * a.heads * static_cast<double>(a.tokens) * a.tokens * a.head_dim;
  fmt::print("attention benchmark on {}: {}, {} tokens, {} heads of {} ({:.1f} GFLOP per call), best of {} after a "
             "warm-up\n",
             rt.device.is_cuda() ? rt.device.str() : fmt::format("cpu, {} threads", torch::get_num_threads()),
             precision_name(rt.precision), a.tokens, a.heads, a.head_dim, flops / 1e9, repeat);
  torch::InferenceMode guard;
  fmt::print("{:<44} {:>10} {:>9} {:>11}\n", "form", "ms", "GFLOP/s", "vs chunked");
  const double chunked_ms = best_ms(rt.device, repeat, [&] { return chunked_attention(q, k, v); });
  auto print_row = [&](const std::string& form, double ms) {
    fmt::print("{:<44} {:>10.1f} {:>9.1f} {:>10.2f}x\n", form, ms, flops / ms / 1e6, chunked_ms / ms);
    std::fflush(stdout);
  };
  auto row = [&](const std::string& form, const std::function<torch::Tensor()>& call) {
    print_row(form, best_ms(rt.device, repeat, call));
  };
  auto skipped = [](const std::string& form, const std::string& why) { fmt::print("{:<44} {}\n", form, why); };
  print_row("chunked (LibTorch calls; the reference twin)", chunked_ms);
  if (rt.device.is_cpu()) {
    // Every kernel set this CPU has for the dtype, the one the network uses first (AMX beside
    // AVX-512 BF16, AVX-512 beside AVX2: the same run compares them).
    if (const auto isa = fused_cpu_attention_isa(q, k, v)) {
      for (CpuIsa other : {CpuIsa::Amx, CpuIsa::Avx512Bf16, CpuIsa::Avx512, CpuIsa::Avx2})
        if (other <= *isa && cpu_kernels::kernel_takes(other, q.scalar_type()))
          row(fmt::format("fused CPU kernel ({}){}", cpu_isa_name(other), other == *isa ? "" : ", not used"),
              [&] { return fused_cpu_attention(q, k, v, other); });
    } else
      skipped("fused CPU kernel", fmt::format("does not apply here (instruction set {})",
                                              cpu_isa_name(cpu_features().isa)));
  }
  if (compat::has_fused_sdpa)
    row("LibTorch scaled_dot_product_attention", [&] { return compat::fused_sdpa(q, k, v); });
  else
    skipped("LibTorch scaled_dot_product_attention", "not in LibTorch " TORCH_VERSION);
  const double full_gb = full_attention_gb(a.heads, a.tokens);
  if (full_gb > a.baseline_max_gb)
    skipped("full score matrix", fmt::format("skipped (needs {:.0f} GB, --baseline-max-gb {:.0f})", full_gb,
                                             a.baseline_max_gb));
  else
    row("full score matrix", [&] { return naive_attention(q, k, v); });
}

void run(const BenchArgs& a) {
  const Runtime rt = apply_runtime_options(a.runtime);
  if (a.attention) return run_attention(a, rt);
  if (a.profile && rt.device.is_cuda())
    fail("--profile measures the CPU (on a GPU, stages do not wait for each other: use nsys or ncu)");
  const bool gpu = rt.device.is_cuda();
  const int repeat = a.repeat > 0 ? a.repeat : (gpu ? 20 : 1);
  const std::string baseline = a.baseline == "auto" ? (gpu ? "official" : "textbook") : a.baseline;
  const bool graphs = gpu && a.cuda_graph && GraphedForward::available();
  std::vector<InputSize> sizes;
  for (const std::string& s : a.sizes) sizes.push_back(parse_size(s, "--sizes"));
  for (const std::string& preset : a.presets) {
    const int patch = ModelConfig::from_preset(preset).patch;
    for (const InputSize& size : sizes)
      if (size.width % patch || size.height % patch)
        fail("--sizes: {}x{} is not a multiple of the {} model's patch size {}", size.width, size.height, preset,
             patch);
  }

  fmt::print("network benchmark on {}: {} ({} views, best of {}{})\n",
             gpu ? rt.device.str() : fmt::format("cpu, {} threads", torch::get_num_threads()),
             precision_name(rt.precision), a.views, repeat, gpu || repeat > 1 ? " after a warm-up" : "");
  fmt::print("{:<8} {:>9} {:>7} {:>9} {:>9} {:>8} | {:>11} {:>8} {:>7}{}\n", "preset", "size", "tokens", "ms",
             "GFLOP/s", "peak GB", "baseline ms", "peak GB", "ratio",
             graphs ? fmt::format(" | {:>9} {:>9} {:>7}", "graph ms", "GFLOP/s", "ratio") : "");
  for (const std::string& preset : a.presets) {
    const ModelConfig config = ModelConfig::from_preset(preset);
    Network net(config);
    net.to(rt.device);
    for (const InputSize& size : sizes) {
      const Inputs in = random_inputs(a.views, size, rt.device);
      const double flops = config.forward_flops(a.views, size.height, size.width);
      const int64_t tokens =
          static_cast<int64_t>(a.views) * (size.width / config.patch) * (size.height / config.patch);
      reset_peak_memory(rt.device);
      net.set_execution(ExecutionOptions());
      const double ms = time_forward(net, in, rt.precision, rt.device, repeat);
      const double peak = peak_memory_gb(rt.device);
      // One more call, after the timed ones, with its stages timed.
      auto profile = [&](Precision p) {
        StageProfile stages;
        net.set_profile(&stages);
        time_forward(net, in, p, rt.device, 1);
        net.set_profile(nullptr);
        return stages;
      };
      std::vector<std::pair<std::string, StageProfile>> profiles;
      if (a.profile) profiles.emplace_back("fast path", profile(rt.precision));

      std::string base = fmt::format("{:>11} {:>8} {:>7}", "-", "", "-");
      std::optional<double> base_ms;
      const double naive_gb = full_attention_gb(config.heads, tokens);
      if (baseline == "textbook" && naive_gb > a.baseline_max_gb) {
        base = fmt::format("{:>11} {:>8} {:>7}", "skipped", fmt::format("{:.0f}", naive_gb), "-");
      } else if (baseline != "none") {
        reset_peak_memory(rt.device);
        net.set_execution(baseline_execution(baseline));
        // The official code runs bf16 (or float32) attention, whatever ours runs.
        const Precision p = baseline == "textbook" ? Precision::Float32 : rt.precision;
        base_ms = time_forward(net, in, p, rt.device, repeat);
        if (a.profile) profiles.emplace_back("baseline", profile(p));
        net.set_execution(ExecutionOptions());
        base = fmt::format("{:>11.1f} {:>8.2f} {:>6.2f}x", *base_ms, peak_memory_gb(rt.device), *base_ms / ms);
      }

      std::string graph;
      if (graphs) {
        GraphedForward g(net, in.images, in.plucker, in.rays, in.rays, rt.precision);
        const double graph_ms =
            best_ms(rt.device, repeat, [&] { g.run(in.images, in.plucker, in.rays, in.rays); });
        graph = fmt::format(" | {:>9.1f} {:>9.1f} {:>7}", graph_ms, flops / graph_ms / 1e6,
                            base_ms ? fmt::format("{:.2f}x", *base_ms / graph_ms) : "-");
      }
      fmt::print("{:<8} {:>9} {:>7} {:>9.1f} {:>9.1f} {:>8.2f} | {}{}\n", preset,
                 fmt::format("{}x{}", size.width, size.height), tokens, ms, flops / ms / 1e6, peak, base, graph);
      for (const auto& [what, stages] : profiles) print_profile(what, stages);
      std::fflush(stdout);
    }
  }
  if (baseline == "official")
    fmt::print("baseline: the official code's way of computing (eager, weights converted on every call as autocast "
               "does, the five heads one by one, the same attention kernels)\n");
  else if (baseline == "unfused")
    fmt::print("baseline: the fast path with the chunked attention (LibTorch calls) and the residual add and layer "
               "norm apart, as before the fused CPU kernels\n");
  else if (baseline == "textbook")
    fmt::print("baseline: float32, unfused, attention with the full score matrix "
               "(skipped when that matrix needs more than {:.0f} GB; its size is shown)\n",
               a.baseline_max_gb);
  if (graphs) fmt::print("graph: the fast path captured once as a CUDA graph and replayed (inputs copied in)\n");
  fmt::print("peak GB: {}\n", gpu ? "the most GPU memory LibTorch's allocator handed out during the runs"
                                  : "the process's peak resident memory during the runs");
}

}  // namespace

void add_bench_command(CLI::App& app) {
  auto args = std::make_shared<BenchArgs>();
  auto* cmd = app.add_subcommand("bench", "Time the network (random weights) on this machine");
  cmd->add_option("--presets", args->presets, "Model presets")->delimiter(',')->capture_default_str();
  cmd->add_option("--sizes", args->sizes, "Input sizes in pixels: N for N x N, or WIDTHxHEIGHT")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--views", args->views, "Input views")->capture_default_str()->check(CLI::Range(1, 64));
  cmd->add_option("--repeat", args->repeat, "Timed runs per configuration, best reported (0 = 1 on a CPU, 20 on a GPU)")
      ->capture_default_str()
      ->check(CLI::Range(0, 10000));
  cmd->add_option("--baseline", args->baseline,
                  "What the fast path is compared with: official (the official code's way of computing), textbook "
                  "(float32, full attention score matrix), unfused (chunked attention, residual add and layer norm "
                  "apart: before the fused CPU kernels), none; auto = official on a GPU, textbook on a CPU")
      ->check(CLI::IsMember({"auto", "official", "textbook", "unfused", "none"}))
      ->capture_default_str();
  cmd->add_flag("!--no-cuda-graph", args->cuda_graph, "On a GPU, skip the CUDA graph column");
  cmd->add_option("--baseline-max-gb", args->baseline_max_gb,
                  "Largest attention score matrix the textbook baseline may allocate")
      ->capture_default_str();
  cmd->add_flag("--profile", args->profile,
                "On the CPU: after each row, the time per stage (layer norms, each linear, attention, GELU, "
                "residual adds, heads) of one more call of the fast path and of the baseline, summed over blocks");
  cmd->add_flag("--attention", args->attention,
                "Time one global attention call instead of the network: the chunked form, the fused CPU kernel, "
                "LibTorch's fused kernel (LibTorch 2.x), the full score matrix");
  cmd->add_option("--tokens", args->tokens, "With --attention: tokens (queries = keys)")
      ->capture_default_str()
      ->check(CLI::Range(int64_t{1}, int64_t{1} << 20));
  cmd->add_option("--heads", args->heads, "With --attention: heads")->capture_default_str()->check(CLI::Range(1, 256));
  cmd->add_option("--head-dim", args->head_dim, "With --attention: dimension of a head")
      ->capture_default_str()
      ->check(CLI::Range(1, 1024));
  add_runtime_options(cmd, args->runtime);
  cmd->footer(
      "Examples: instainpaint bench --presets release --sizes 256\n"
      "          instainpaint bench --attention --tokens 16384   (release model's attention at 4 x 512²)\n"
      "          instainpaint bench --presets release --sizes 256 --baseline unfused --profile\n"
      "          instainpaint bench --device cuda --presets release --sizes 512,904x512   (the GPU speed targets' sizes)");
  cmd->callback([args] { run(*args); });
}

}  // namespace ii::cli
