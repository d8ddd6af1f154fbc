// Devices, the execution options of the network, and the GPU fast path against the float32
// CPU path. The GPU tests need a CUDA build of LibTorch and a GPU and are skipped otherwise;
// the refusals they rely on are checked everywhere.
#include <gtest/gtest.h>

#include <fmt/core.h>

#include "common/torch_compat.h"
#include "model/checkpoint.h"
#include "model/cuda_graph.h"
#include "model/device.h"
#include "model/network.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace device_test {

float max_abs(const torch::Tensor& a, const torch::Tensor& b) {
  EXPECT_EQ(a.sizes(), b.sizes());
  return (a.cpu() - b.cpu()).abs().max().item<float>();
}

struct RandomInput {
  torch::Tensor images, plucker, rays_o, rays_d;
};

RandomInput random_input(const ModelConfig& config, int views, int height, int width) {
  torch::manual_seed(3);
  RandomInput in;
  in.images = torch::rand({1, views, config.image_channels, height, width}) * 2 - 1;
  in.plucker = torch::randn({1, views, 6, height, width});
  in.rays_o = torch::randn({1, views, height, width, 3});
  in.rays_d = torch::randn({1, views, height, width, 3});
  return in;
}

TEST(Device, ResolvesItsNamesAndRefusesOthers) {
  EXPECT_EQ(resolve_device("cpu"), torch::Device(torch::kCPU));
  for (const char* bad : {"gpu", "cuda:", "cuda:x", "cudax", "cuda:1234"})
    EXPECT_EQ(test::error_message([&] { resolve_device(bad); }),
              fmt::format("--device: unknown device '{}' (expected auto, cpu, cuda or cuda:N)", bad));
  if (torch::cuda::is_available()) {
    EXPECT_EQ(resolve_device("auto"), torch::Device(torch::kCUDA, 0));
    EXPECT_EQ(resolve_device("cuda:0"), torch::Device(torch::kCUDA, 0));
    EXPECT_EQ(test::error_message([] { resolve_device("cuda:999"); }).rfind("--device cuda:999: only ", 0), 0u);
  } else {
    EXPECT_EQ(resolve_device("auto"), torch::Device(torch::kCPU));
    for (const char* name : {"cuda", "cuda:1"})
      EXPECT_EQ(test::error_message([&] { resolve_device(name); }),
                fmt::format("--device {}: no CUDA device is available to LibTorch (a CPU-only build, or no GPU/driver "
                            "visible)",
                            name));
  }
}

TEST(Device, PrecisionsByNameRoundTripAndOthersAreRefused) {
  for (const auto& [name, precision] : {std::make_pair("fp32", Precision::Float32),
                                        std::make_pair("bf16", Precision::BFloat16)}) {
    EXPECT_EQ(set_up_runtime("cpu", 0, name).precision, precision);
    EXPECT_STREQ(precision_name(precision), name);
  }
  EXPECT_EQ(set_up_runtime("cpu", 0, "auto").precision, default_cpu_precision());
  EXPECT_EQ(test::error_message([] { set_up_runtime("cpu", 0, "fp16"); }),
            "--precision: unknown precision 'fp16' (expected auto, fp32 or bf16)");
}

TEST(Device, PrecisionAndTransfersFollowTheDevice) {
  EXPECT_EQ(default_precision(torch::kCPU), default_cpu_precision());
  EXPECT_EQ(default_precision(torch::Device(torch::kCUDA, 0)), Precision::BFloat16);
  const torch::Tensor t = torch::arange(6).reshape({2, 3});
  // Already there: the same tensor, no copy.
  EXPECT_TRUE(to_device(t, torch::kCPU).is_same(t));
  synchronize(torch::kCPU);  // a no-op that must not throw on the CPU
}

TEST(Device, PeakMemorySeesAnAllocation) {
  reset_peak_memory(torch::kCPU);
  const double before = peak_memory_gb(torch::kCPU);
  EXPECT_GT(before, 0.0);
  {
    const torch::Tensor big = torch::ones({64 * 1024 * 1024});  // 256 MiB, touched
    EXPECT_EQ(big.sum().item<float>(), 64.f * 1024 * 1024);
  }
  EXPECT_GT(peak_memory_gb(torch::kCPU) - before, 0.2);
  if (torch::cuda::is_available()) {
    const torch::Device gpu(torch::kCUDA, 0);
    reset_peak_memory(gpu);
    const torch::Tensor big = torch::ones({64 * 1024 * 1024}, torch::TensorOptions().device(gpu));
    EXPECT_GE(peak_memory_gb(gpu), 0.25);
  }
}

// Every way of computing gives the fast path's values: fused heads and cached bf16 weights
// are exact rearrangements; the textbook and chunked attention (the fused CPU kernel's twin)
// and the unfused residual add + layer norm differ by rounding.
TEST(Network, ExecutionOptionsKeepTheValues) {
  const ModelConfig config = ModelConfig::from_preset("tiny");
  torch::manual_seed(4);  // the weights: unseeded, every run drew others and bf16 passed by chance
  const Network fast(config);
  const RandomInput in = random_input(config, 2, 16, 24);
  torch::NoGradGuard no_grad;
  auto forward = [&](const ExecutionOptions& e, Precision p) {
    Network net = fast;
    net.set_execution(e);
    return net.forward(in.images, in.plucker, in.rays_o, in.rays_d, p).gaussians;
  };
  ExecutionOptions official;
  official.fused_heads = false;
  official.cached_weights = false;
  official.fused_norms = false;
  ExecutionOptions chunked;
  chunked.attention = AttentionForm::Chunked;
  ExecutionOptions textbook = official;
  textbook.attention = AttentionForm::Full;
  ExecutionOptions uncached;
  uncached.cached_weights = false;
  for (Precision p : {Precision::Float32, Precision::BFloat16}) {
    const GaussianMaps ref = forward(ExecutionOptions(), p);
    const GaussianMaps same = forward(uncached, p);
    EXPECT_TRUE(torch::equal(ref.rgb, same.rgb)) << precision_name(p);
    EXPECT_TRUE(torch::equal(ref.xyz, same.xyz)) << precision_name(p);
    const double tolerance = p == Precision::Float32 ? 1e-5 : 2e-2;
    for (const ExecutionOptions& e : {official, textbook, chunked}) {
      const GaussianMaps other = forward(e, p);
      EXPECT_LT(max_abs(ref.rgb, other.rgb), tolerance)
          << precision_name(p) << " attention form " << static_cast<int>(e.attention);
      EXPECT_LT(max_abs(ref.depth, other.depth), tolerance * config.depth_far) << precision_name(p);
      EXPECT_LT(max_abs(ref.rotation, other.rotation), tolerance) << precision_name(p);
    }
  }
}

TEST(GraphedForward, NeedsACudaDevice) {
  const ModelConfig config = ModelConfig::from_preset("tiny");
  const Network net(config);
  const RandomInput in = random_input(config, 2, 16, 24);
  const std::string message = test::error_message(
      [&] { GraphedForward(net, in.images, in.plucker, in.rays_o, in.rays_d, Precision::BFloat16); });
  // A CUDA LibTorch refuses CPU inputs before it touches CUDA, so also on a machine without a driver.
  EXPECT_EQ(message, II_HAS_CUDA_TORCH ? "CUDA graph: the inputs are on cpu, capture needs them on a CUDA device"
                                       : "CUDA graph: this build's LibTorch has no CUDA (inputs on cpu)");
}

// ---- on a GPU ------------------------------------------------------------------------------

// The agreement target: the GPU fast path (bf16, cached weights, fused heads, fused
// attention) against the float32 CPU path on the official fixture.
TEST(NetworkCuda, Bf16FastPathMatchesTheCpuFloat32Path) {
  II_REQUIRE_CUDA();
  II_REQUIRE_SHARED(ckpt, "fixtures/official-tiny/weights.safetensors");
  const StateDict io = read_safetensors_tensors(test::shared_path("fixtures/official-tiny/io.safetensors"));
  Network cpu = load_network(ckpt);
  Network gpu = load_network(ckpt);
  gpu.to(torch::kCUDA);
  torch::NoGradGuard no_grad;
  const torch::Tensor images = io.at("encoder_input").unsqueeze(0), plucker = io.at("plucker").unsqueeze(0);
  const GaussianMaps ref = cpu.forward(images, plucker, io.at("rays_o"), io.at("rays_d_un")).gaussians;
  const GaussianMaps got = gpu.forward(to_device(images, torch::kCUDA), to_device(plucker, torch::kCUDA),
                                       to_device(io.at("rays_o"), torch::kCUDA),
                                       to_device(io.at("rays_d_un"), torch::kCUDA), Precision::BFloat16)
                               .gaussians;
  EXPECT_TRUE(got.rgb.is_cuda());
  // The same bounds as the CPU's bf16 path (parity_test): 8 mantissa bits, two blocks.
  EXPECT_LT(max_abs(got.opacity, ref.opacity), 0.02);
  EXPECT_LT(max_abs(got.rgb, ref.rgb), 0.05);
  EXPECT_LT(max_abs(got.rotation, ref.rotation), 0.15);
  EXPECT_LT(max_abs(got.depth, ref.depth) / ref.depth.abs().max().item<float>(), 0.02);
  // float32 on the GPU is the CPU's float32 up to summation order.
  const GaussianMaps f32 = gpu.forward(images.cuda(), plucker.cuda(), io.at("rays_o").cuda(),
                                       io.at("rays_d_un").cuda(), Precision::Float32)
                               .gaussians;
  EXPECT_LT(max_abs(f32.rgb, ref.rgb), 1e-3);
  EXPECT_LT(max_abs(f32.xyz, ref.xyz), 1e-3);
}

TEST(NetworkCuda, GraphReplayEqualsEagerAndFollowsNewInputs) {
  II_REQUIRE_CUDA();
  if (!GraphedForward::available()) GTEST_SKIP() << "LibTorch without CUDA graphs";
  const ModelConfig config = ModelConfig::from_preset("tiny");
  Network net(config);
  net.to(torch::kCUDA);
  const RandomInput a = random_input(config, 2, 16, 24);
  RandomInput b = random_input(config, 2, 16, 24);
  b.images = b.images.flip(-1);
  torch::InferenceMode guard;
  auto eager = [&](const RandomInput& in) {
    return net.forward(in.images.cuda(), in.plucker.cuda(), in.rays_o.cuda(), in.rays_d.cuda(), Precision::BFloat16)
        .gaussians;
  };
  GraphedForward graph(net, a.images.cuda(), a.plucker.cuda(), a.rays_o.cuda(), a.rays_d.cuda(),
                       Precision::BFloat16);
  for (const RandomInput* in : std::vector<const RandomInput*>{&a, &b, &a}) {
    const GaussianMaps expected = eager(*in);
    const GaussianMaps& got = graph.run(in->images, in->plucker, in->rays_o, in->rays_d);
    EXPECT_LT(max_abs(got.rgb, expected.rgb), 1e-6);
    EXPECT_LT(max_abs(got.xyz, expected.xyz), 1e-5);
  }
  EXPECT_EQ(test::error_message([&] { graph.run(a.images.narrow(1, 0, 1), a.plucker, a.rays_o, a.rays_d); }),
            "CUDA graph: input of shape [1, 1, 4, 16, 24] given, the graph was captured for [1, 2, 4, 16, 24]");
}

}  // namespace device_test
}  // namespace
}  // namespace ii
