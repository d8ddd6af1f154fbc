// One click's selection on a splat scene of a million splats, as the page's click and
// `fill --click` run it (the target: a click to the drawn selection in at most 1 s on
// 2 cores): a floor and a wall of fine splats, a box of another colour standing on the floor,
// clicked from a camera of 1008 x 567 pixels. `select object` is the grown selection alone,
// `fill region` adds the outline taken as a stroke (fill/region.h).
#include <benchmark/benchmark.h>

#include <cmath>

#include "camera/trajectory.h"
#include "edit/select.h"
#include "fill/region.h"
#include "gaussians/gaussians.h"
#include "io/splat_file.h"

namespace {

using namespace ii;

// About 1.2 M splats: the floor (3 x 3 units, 1 M), the wall behind (0.25 M) and a box (0.4 units
// a side) of another colour on the floor.
SplatCloud million_splat_room() {
  SplatCloud c;
  auto add = [&](double x, double y, double z, double r, double g, double b, double size) {
    c.means.insert(c.means.end(), {float(x), float(y), float(z)});
    for (double v : {r, g, b}) c.sh_dc.push_back(float(dc_of_colour(v)));
    c.opacity_logit.push_back(4.f);
    for (int k = 0; k < 3; ++k) c.log_scales.push_back(float(std::log(size)));
    c.rotations.insert(c.rotations.end(), {1.f, 0.f, 0.f, 0.f});
  };
  for (int i = 0; i < 1000; ++i)
    for (int k = 0; k < 1000; ++k) {
      const double x = -1.5 + 0.003 * i, z = -1.5 + 0.003 * k;
      if (std::abs(x) < 0.2 && std::abs(z) < 0.2) continue;
      add(x, 0, z, 0.3 + 0.2 * (x + 1.5) / 3, 0.5, 0.4 + 0.2 * (z + 1.5) / 3, 0.003);
    }
  for (int i = 0; i < 500; ++i)
    for (int k = 0; k < 500; ++k) add(-1.5 + 0.006 * i, 0.003 * k, -1.5, 0.8, 0.8, 0.75, 0.006);
  for (double x = -0.2; x <= 0.2; x += 0.01)
    for (double y = 0.005; y <= 0.4; y += 0.01)
      for (double z = -0.2; z <= 0.2; z += 0.01) add(x, y, z, 0.8, 0.1, 0.1, 0.01);
  c.sh_rest_per_channel = 0;
  return c;
}

Camera room_camera() {
  Camera c;
  c.K = Intrinsics::from_fov(1008, 567, 2 * std::atan(std::tan(25 * M_PI / 180) * 1008 / 567), 50 * M_PI / 180);
  c.c2w = look_at({0, 0.9, 1.6}, {0, 0.1, 0}, {0, 1, 0});
  return c;
}

const SplatCloud& room() {
  static const SplatCloud cloud = million_splat_room();
  return cloud;
}

// The click on the box's front face.
Click box_click(const Camera& camera) {
  const std::optional<PixelOfPoint> hit = pixel_of_point(camera.K, camera.w2c_opencv(), {0.0, 0.2, 0.2});
  return {hit->x + 0.5, hit->y + 0.5};
}

void BM_SelectObject(benchmark::State& state) {
  const Camera camera = room_camera();
  ColouredPoints points;
  const auto colour = [](float dc) { return static_cast<float>(colour_of_dc(dc)); };
  for (size_t i = 0; i < room().size(); ++i) {
    const float* m = &room().means[3 * i];
    const float* dc = &room().sh_dc[3 * i];
    points.points.emplace_back(m[0], m[1], m[2]);
    points.colours.emplace_back(colour(dc[0]), colour(dc[1]), colour(dc[2]));
  }
  for (auto _ : state) {
    const std::vector<uint8_t> selected =
        select_object(camera, "bench", points.points, points.colours, box_click(camera));
    benchmark::DoNotOptimize(selected.data());
  }
  state.counters["splats"] = static_cast<double>(room().size());
}

void BM_FillRegionFromClick(benchmark::State& state) {
  const Camera camera = room_camera();
  for (auto _ : state) {
    const RegionMask region = region_from_clicks(room(), camera, "bench", {box_click(camera)});
    benchmark::DoNotOptimize(region_count(region));
  }
  state.counters["splats"] = static_cast<double>(room().size());
}

BENCHMARK(BM_SelectObject)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_FillRegionFromClick)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace

BENCHMARK_MAIN();
