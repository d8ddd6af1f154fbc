// The plane sweep of the photos' depth (geometry/stereo_depth.h) at the statue's size at 256 rows:
// five views of seeded noise matched at 128 x 170 pixels, 24 depths each (the page's edit of the
// statue matches four such views).
// `sweep correlation` is one pair of views; `stereo depth` the whole measurement.
#include <benchmark/benchmark.h>

#include "geometry/stereo_depth.h"
#include "geometry/sweep_correlation.h"

namespace {

using namespace ii;

constexpr int kHeight = 128, kWidth = 170, kPlanes = 24;

// A camera looking along -z from (x, y, 0).
Camera camera_at(double x, double y) {
  Camera camera;
  camera.K = Intrinsics::from_fov(kWidth, kHeight, 1.0, 1.0 * kHeight / kWidth);
  camera.c2w(0, 3) = x;
  camera.c2w(1, 3) = y;
  return camera;
}

void BM_SweepCorrelation(benchmark::State& state) {
  torch::manual_seed(5);
  const torch::Tensor reference = torch::rand({kHeight, kWidth}), source = torch::rand({kHeight, kWidth});
  const torch::Tensor depths = torch::linspace(1.5, 4.0, kPlanes).unsqueeze(1).expand({kPlanes, kHeight * kWidth}).contiguous();
  for (auto _ : state)
    benchmark::DoNotOptimize(sweep_correlation(reference, camera_at(0, 0), source, camera_at(0.1, 0.02), depths, 5));
}
BENCHMARK(BM_SweepCorrelation)->Name("sweep correlation")->Unit(benchmark::kMillisecond);

void BM_StereoDepth(benchmark::State& state) {
  torch::manual_seed(6);
  std::vector<Image> photos;
  std::vector<Camera> cameras;
  std::vector<torch::Tensor> guides;
  for (int v = 0; v < 5; ++v) {
    Image photo(2 * kWidth, 2 * kHeight, 3);
    const torch::Tensor noise = torch::rand({static_cast<int64_t>(photo.pixels.size())});
    std::copy(noise.data_ptr<float>(), noise.data_ptr<float>() + noise.numel(), photo.pixels.begin());
    photos.push_back(photo);
    Camera camera = camera_at(0.05 * v, 0.01 * v);
    cameras.push_back(camera.resized(2 * kWidth, 2 * kHeight));
    guides.push_back(torch::full({2 * kHeight, 2 * kWidth}, 2.5f));
  }
  for (auto _ : state) benchmark::DoNotOptimize(stereo_depth(photos, cameras, guides));
}
BENCHMARK(BM_StereoDepth)->Name("stereo depth")->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
