// Rasterizer speed on network-like scenes: one Gaussian per input pixel of 4 views (as the
// model predicts them), rendered from a view between the inputs.
//   262 144 Gaussians (4 x 256 x 256) at 256 x 256, and
//   1 851 392 Gaussians (4 x 512 x 904) at 512 x 904 (the release evaluation size),
// forward only and forward + backward, on 2 threads; plus the speed-up over the direct
// reference renderer on a small scene.
#include <benchmark/benchmark.h>

#include <ATen/Parallel.h>
#include <Eigen/Geometry>

#include <cmath>
#include <cstdlib>
#include <map>

#include "common/memory.h"
#include "render/rasterizer.h"

namespace {

using namespace ii;

// 2 threads as the targets are stated; II_BENCH_THREADS overrides (e.g. 1 for per-core cost).
const int kThreads = std::getenv("II_BENCH_THREADS") ? std::atoi(std::getenv("II_BENCH_THREADS")) : 2;

// OpenGL camera at `eye` looking at the origin.
Camera look_at(const Eigen::Vector3d& eye, int width, int height, double fov_y) {
  Camera c;
  const double fy = height / (2 * std::tan(fov_y / 2));
  c.K.width = width;
  c.K.height = height;
  c.K.fx = c.K.fy = fy;
  c.K.cx = width / 2.0;
  c.K.cy = height / 2.0;
  const Eigen::Vector3d back = eye.normalized();
  const Eigen::Vector3d right = Eigen::Vector3d::UnitY().cross(back).normalized();
  c.c2w.setIdentity();
  c.c2w.block<3, 1>(0, 0) = right;
  c.c2w.block<3, 1>(0, 1) = back.cross(right);
  c.c2w.block<3, 1>(0, 2) = back;
  c.c2w.block<3, 1>(0, 3) = eye;
  return c;
}

Eigen::Vector3d orbit(double angle) { return {2.5 * std::sin(angle), 0.4, 2.5 * std::cos(angle)}; }

// Per input pixel a Gaussian on a bumpy surface about 2.5 units away, pixel-sized,
// placed along the pixel's ray as the network does (xyz = o + depth * d_un).
GaussianSet network_like_scene(int width, int height) {
  torch::manual_seed(0);
  std::vector<torch::Tensor> means, scales;
  for (int v = 0; v < 4; ++v) {
    const Camera cam = look_at(orbit(-0.45 + 0.3 * v), width, height, 0.9);
    const auto j = torch::arange(width, torch::kFloat32).repeat({height});
    const auto i = torch::arange(height, torch::kFloat32).repeat_interleave(width);
    const auto dx = (j + 0.5 - cam.K.cx) / cam.K.fx, dy = -(i + 0.5 - cam.K.cy) / cam.K.fy;
    const auto d_cam = torch::stack({dx, dy, -torch::ones_like(dx)}, 1);
    Eigen::Matrix3f R = cam.rotation().cast<float>();
    const auto Rt = torch::from_blob(R.data(), {3, 3}, torch::kFloat32).clone();  // column-major = R^T row-major
    const auto d_world = torch::matmul(d_cam, Rt);
    const auto depth = 2.5 - 0.6 * torch::sin(3 * dx) * torch::cos(2 * dy) + 0.05 * torch::rand_like(dx);
    const Eigen::Vector3f o = cam.center().cast<float>();
    means.push_back(torch::tensor({o.x(), o.y(), o.z()}) + depth.unsqueeze(1) * d_world);
    scales.push_back((depth / cam.K.fx).unsqueeze(1) * (0.5 + torch::rand({width * height, 3})));
  }
  GaussianSet g;
  const int64_t n = int64_t(4) * width * height;
  g.means = torch::cat(means);
  g.scales = torch::cat(scales).clamp(1e-4, 0.3);
  g.quats = torch::randn({n, 4});
  g.opacities = torch::sigmoid(torch::randn({n}) + 1.0);
  g.colors = torch::rand({n, 3});
  return g;
}

struct Setup {
  GaussianSet g;
  RenderCamera cam;
};

const Setup& setup(int width, int height) {
  static std::map<std::pair<int, int>, Setup> cache;
  auto it = cache.find({width, height});
  if (it == cache.end()) {
    Setup s;
    s.g = network_like_scene(width, height);
    s.cam.camera = look_at(orbit(0.0), width, height, 0.9);
    it = cache.emplace(std::make_pair(width, height), std::move(s)).first;
  }
  return it->second;
}

void run_render(benchmark::State& state, int width, int height, bool backward) {
  at::set_num_threads(kThreads);
  const Setup& s = setup(width, height);
  GaussianSet g = s.g;
  if (backward)
    for (torch::Tensor* t : {&g.means, &g.quats, &g.scales, &g.opacities, &g.colors})
      *t = t->detach().set_requires_grad(true);
  double coverage = 0;
  for (auto _ : state) {
    const RenderOutput out = render(g, s.cam);
    if (backward) (out.rgb.sum() + out.depth.sum()).backward();
    coverage = out.alpha.mean().item<double>();
  }
  state.counters["gaussians"] = static_cast<double>(g.size());
  state.counters["mean_alpha"] = coverage;
  state.counters["threads"] = kThreads;
}

void BM_Forward_262k_256x256(benchmark::State& s) { run_render(s, 256, 256, false); }
void BM_ForwardBackward_262k_256x256(benchmark::State& s) { run_render(s, 256, 256, true); }
void BM_Forward_1851k_904x512(benchmark::State& s) { run_render(s, 904, 512, false); }
void BM_ForwardBackward_1851k_904x512(benchmark::State& s) { run_render(s, 904, 512, true); }

// Small scene (4 x 32 x 32 = 4096 Gaussians at 64 x 64): tiled renderer vs the reference.
void run_small(benchmark::State& state, bool reference) {
  at::set_num_threads(kThreads);
  static const GaussianSet g = network_like_scene(32, 32);
  RenderCamera cam;
  cam.camera = look_at(orbit(0.0), 64, 64, 0.9);
  for (auto _ : state) {
    const RenderOutput out = reference ? render_reference(g, cam) : render(g, cam);
    benchmark::DoNotOptimize(out.rgb.data_ptr());
  }
}
void BM_Small_4k_64x64_Tiled(benchmark::State& s) { run_small(s, false); }
void BM_Small_4k_64x64_Reference(benchmark::State& s) { run_small(s, true); }

BENCHMARK(BM_Forward_262k_256x256)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_ForwardBackward_262k_256x256)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_Forward_1851k_904x512)->Unit(benchmark::kMillisecond)->MinTime(3.0);
BENCHMARK(BM_ForwardBackward_1851k_904x512)->Unit(benchmark::kMillisecond)->MinTime(3.0);
BENCHMARK(BM_Small_4k_64x64_Tiled)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Small_4k_64x64_Reference)->Unit(benchmark::kMillisecond)->Iterations(2);

}  // namespace

int main(int argc, char** argv) {
  ii::keep_large_allocations();  // as the instainpaint executable does
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
