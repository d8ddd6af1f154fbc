#pragma once
// A small SPIn-NeRF-layout scene with exact ground truth, for the evaluation tests: a wall of
// known Gaussians (in the pose-normalised frame) rendered with render() into
// images/ (2 object-free test views first, then 4 input views), masks in images/label/ and
// images/test_label/, poses_bounds.npy. Also the Gaussians as a splat PLY (truth.ply).
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "data/preprocess.h"
#include "data/scene.h"
#include "io/image.h"
#include "io/npy.h"
#include "io/ply.h"
#include "model/scene_input.h"
#include "gaussians/gaussians.h"
#include "render/rasterizer.h"

namespace ii::test {

constexpr int kSceneWidth = 64, kSceneHeight = 48;
// The object mask of every view: columns [24, 40), rows [16, 32).
constexpr int kMaskX0 = 24, kMaskX1 = 40, kMaskY0 = 16, kMaskY1 = 32;

inline SplatCloud wall_of_splats(float shift_x = 0.f, float shift_z = 0.f) {
  SplatCloud c;
  // Wide enough to fill every view (cameras at normalised z = 0, within ±1 in x and y).
  for (int i = 0; i <= 70; ++i)
    for (int j = 0; j <= 50; ++j) {
      const float x = -3.5f + 0.1f * i, y = -2.5f + 0.1f * j;
      c.means.insert(c.means.end(), {x + shift_x, y, -3.f + shift_z});
      c.normals.insert(c.normals.end(), {0, 0, 0});
      const float rgb[3] = {0.5f + 0.4f * std::sin(2.1f * x), 0.5f + 0.4f * std::cos(1.7f * y),
                            0.5f + 0.3f * std::sin(1.3f * (x + y))};
      for (float v : rgb) c.sh_dc.push_back((v - 0.5f) / 0.28209479f);
      c.opacity_logit.push_back(3.f);
      c.log_scales.insert(c.log_scales.end(), {std::log(0.07f), std::log(0.07f), std::log(0.07f)});
      c.rotations.insert(c.rotations.end(), {1, 0, 0, 0});
    }
  return c;
}

// Renders `cloud` for a view as the evaluation does: working size (here the image's own),
// camera normalised over all the scene's cameras.
inline Image render_view(const Scene& scene, const View& view, const SplatCloud& cloud) {
  PreprocessOptions pre;
  pre.height = kSceneHeight;
  const PreparedView pv = prepare_view(view, pre);
  RenderCamera rc;
  rc.camera = scene_normalization(scene).apply(pv.camera);
  const torch::Tensor rgb = render(gaussians_from_splats(cloud), rc).rgb.contiguous();
  Image out(kSceneWidth, kSceneHeight, 3);
  std::copy(rgb.data_ptr<float>(), rgb.data_ptr<float>() + rgb.numel(), out.pixels.begin());
  return out;
}

inline void write_scene(const std::filesystem::path& dir, bool with_test_views = true) {
  namespace fs = std::filesystem;
  const std::vector<std::string> names = {"00_test", "01_test", "02", "03", "04", "05"};
  fs::create_directories(dir / "images" / "label");
  if (with_test_views) fs::create_directories(dir / "images" / "test_label");
  Image mask(kSceneWidth, kSceneHeight, 1);
  for (int y = kMaskY0; y < kMaskY1; ++y)
    for (int x = kMaskX0; x < kMaskX1; ++x) mask.at(y, x) = 1;
  std::vector<double> rows;
  const double focal = 50;
  for (size_t k = 0; k < names.size(); ++k) {
    // Cameras at z = 3 looking along -z (identity rotation, OpenGL axes), spread in x and y.
    const double cx = 0.3 * std::cos(1.1 * k), cy = 0.2 * std::sin(1.7 * k);
    // LLFF rows: columns (down, right, back) = (-y, x, z) of the OpenGL camera-to-world.
    const double m[3][5] = {
        {0, 1, 0, cx, double(kSceneHeight)}, {-1, 0, 0, cy, double(kSceneWidth)}, {0, 0, 1, 3.0, focal}};
    for (const auto& r : m) rows.insert(rows.end(), r, r + 5);
    rows.push_back(0.5);
    rows.push_back(10.0);
    write_png(dir / "images" / (names[k] + ".png"), Image(kSceneWidth, kSceneHeight, 3, 0.5f));
    const bool is_test = with_test_views && k < 2;
    write_png(dir / "images" / (is_test ? "test_label" : "label") / (names[k] + ".png"), mask);
  }
  write_npy(dir / "poses_bounds.npy", rows, {static_cast<int64_t>(names.size()), 17});

  // Placeholders first (the reader needs the files), then the rendered ground truth.
  const Scene scene = load_scene(dir);
  const SplatCloud cloud = wall_of_splats();
  for (const auto* list : {&scene.views, &scene.test_views})
    for (const View& v : *list) write_png(v.image_path, render_view(scene, v, cloud));
  write_splat_ply(dir / "truth.ply", cloud);
}

}  // namespace ii::test
