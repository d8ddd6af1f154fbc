// Fuzz targets of the scene-level inputs: nerfstudio transforms.json, LLFF poses_bounds.npy
// (with the SPIn-NeRF label folders), the camera-list JSON, and a mask folder.
#include <cmath>
#include <cstdlib>

#include <fmt/format.h>

#include "camera/box.h"
#include "camera/click.h"
#include "camera/trajectory.h"
#include "common/error.h"
#include "data/scene.h"
#include "fuzz_target.h"
#include "io/image.h"
#include "io/npy.h"

namespace ii::fuzz {
namespace {

namespace fs = std::filesystem;

// ---- nerfstudio ---------------------------------------------------------------------------

// A scene folder with two small images the seeds refer to; the input becomes transforms.json.
const fs::path& nerfstudio_dir() {
  static const fs::path dir = [] {
    const fs::path d = scratch_dir() / "nerfstudio";
    fs::create_directories(d / "images");
    write_png(d / "images" / "a.png", Image(16, 12, 3, 0.5f));
    write_jpeg(d / "images" / "b.jpg", Image(16, 12, 3, 0.25f));
    return d;
  }();
  return dir;
}

const bool nerfstudio = register_target({
    "nerfstudio",
    [] {
      return std::vector<std::string>{
          R"({"fl_x": 20, "fl_y": 20, "cx": 8, "cy": 6, "w": 16, "h": 12, "camera_model": "OPENCV", "k1": 0.01,
"frames": [{"file_path": "images/a.png", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,2],[0,0,0,1]]},
{"file_path": "./images/b", "transform_matrix": [[0,-1,0,1],[1,0,0,0],[0,0,1,2]], "fl_x": 30, "k2": -0.01},
{"file_path": "images/missing.png", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]})",
          R"({"camera_angle_x": 0.9, "frames": [{"file_path": "images\\a.png", "w": 32, "h": 24,
"transform_matrix": [[2,0,0,0],[0,2,0,0],[0,0,2,0],[0,0,0,1]]}]})"};
    },
    [](const uint8_t* data, size_t size) {
      const fs::path& dir = nerfstudio_dir();
      write_file(dir / "transforms.json", data, size);
      SceneOptions options;
      options.format = "nerfstudio";
      load_scene(dir, options);
    }});

// ---- LLFF / SPIn-NeRF ---------------------------------------------------------------------

// One scene folder per image count (so that the real scenes' poses_bounds.npy seeds get past
// the count check): n small images and, with `masks`, a numbered test mask for the first and
// label masks for the rest.
fs::path llff_dir(int64_t n, bool masks) {
  const fs::path dir = scratch_dir() / fmt::format("llff-{}{}", n, masks ? "-masked" : "");
  if (fs::exists(dir)) return dir;
  const fs::path images = dir / "images_4";
  fs::create_directories(images);
  Image mask(16, 12, 1, 0.f);
  mask.at(4, 5) = 1.f;
  for (int64_t k = 0; k < n; ++k) {
    const std::string name = fmt::format("img{:03d}.png", k);
    write_png(images / name, Image(16, 12, 3, 0.5f));
    if (!masks) continue;
    fs::create_directories(images / "label");
    fs::create_directories(images / "test_label");
    write_png(k == 0 ? images / "test_label" / "out_00001.png" : images / "label" / name, mask);
  }
  std::vector<double> rows;
  for (int64_t k = 0; k < n; ++k) {
    const double m[17] = {0, 1, 0, double(k), 48, -1, 0, 0, 0, 64, 0, 0, 1, 0, 40, 0.5, 20};
    rows.insert(rows.end(), m, m + 17);
  }
  write_npy(dir / "poses_bounds.npy", rows, {n, 17});
  return dir;
}

const bool llff = register_target({
    "llff",
    [] {
      return std::vector<std::string>{
          bytes_written_by([&](const fs::path& p) { fs::copy_file(llff_dir(3, true) / "poses_bounds.npy", p); })};
    },
    [](const uint8_t* data, size_t size) {
      // The row count picks the folder; inputs that are no array at all go to the 3-image one,
      // where the reader rejects them.
      const fs::path probe = scratch_dir() / "poses_probe.npy";
      write_file(probe, data, size);
      int64_t n = 3;
      try {
        const NpyArray a = read_npy(probe);
        if (!a.shape.empty() && a.shape[0] >= 2 && a.shape[0] <= 64) n = a.shape[0];
      } catch (const Error&) {
      }
      const fs::path dir = llff_dir(n, true);
      write_file(dir / "poses_bounds.npy", data, size);
      load_scene(dir);
    }});

// ---- camera-list JSON ---------------------------------------------------------------------

const bool camera_json = register_target({
    "camera_json",
    [] {
      std::vector<NamedCamera> cams(2);
      cams[0].name = "front";
      cams[0].camera.K = Intrinsics::from_fov(64, 48, 1.0, 0.8);
      cams[1].camera.K = {32, 32, 40, 41, 15.5, 16.5};
      cams[1].camera.c2w.block<3, 1>(0, 3) = Eigen::Vector3d(1, 2, 3);
      return std::vector<std::string>{
          bytes_written_by([&](const fs::path& p) { write_camera_json(p, cams); }),
          R"({"convention": "opencv", "cameras": [{"width": 10, "height": 8, "fov_x_deg": 60,
"w2c": [[1,0,0,0],[0,1,0,0],[0,0,1,5]]}]})",
          R"([{"name": "a", "width": 4, "height": 4, "fy": 3, "cx": 2, "c2w": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]],
"convention": "opengl"}])"};
    },
    [](const uint8_t* data, size_t size) {
      const fs::path path = scratch_dir() / "cameras.json";
      write_file(path, data, size);
      read_camera_json(path);
    }});

// ---- a box (fill --box, the page's box) ------------------------------------------------------

const bool box = register_target({
    "box",
    [] { return std::vector<std::string>{"0,0.2,0,0.5,0.4,0.5", "1,-2,3e2,1,1,1,0,45.5,-90"}; },
    [](const uint8_t* data, size_t size) {
      const OrientedBox b = parse_box(std::string(reinterpret_cast<const char*>(data), size));
      b.contains(Eigen::Vector3d::Zero());
      b.describe();
    }});

// ---- a click (--click, the page's clicks) ------------------------------------------------------

const bool click = register_target({
    "click",
    [] { return std::vector<std::string>{"512,300", "12.5,-3e1"}; },
    [](const uint8_t* data, size_t size) {
      const Click c = parse_click(std::string(reinterpret_cast<const char*>(data), size), "--click");
      if (!std::isfinite(c.x) || !std::isfinite(c.y)) fail("a click that is not finite was taken");
    }});

// ---- a box on a view (--box X0,Y0,X1,Y1, the page's box tool) -------------------------------

const bool view_box = register_target({
    "view_box",
    [] { return std::vector<std::string>{"217.4,122.7,369.6,346.3", "0,0,1e3,5"}; },
    [](const uint8_t* data, size_t size) {
      const ViewBox b = parse_view_box(std::string(reinterpret_cast<const char*>(data), size), "--box");
      // Taken: four finite numbers, X1 > X0 and Y1 > Y0 (anything else a finding).
      if (!std::isfinite(b[0] + b[1] + b[2] + b[3]) || !(b[2] > b[0]) || !(b[3] > b[1])) std::abort();
    }});

// ---- a mask folder ------------------------------------------------------------------------

// A scene of one 16x12 view; the input is the mask file that a --masks folder holds for it.
const bool mask_folder = register_target({
    "mask_folder",
    [] {
      Image binary(16, 12, 1, 0.f), wide(17, 12, 1, 1.f), colour(16, 12, 3, 0.f);
      binary.at(3, 3) = 1.f;
      colour.at(2, 2, 0) = 1.f;
      return std::vector<std::string>{bytes_written_by([&](const fs::path& p) { write_png(p, binary); }),
                                      bytes_written_by([&](const fs::path& p) { write_png(p, wide, 16); }),
                                      bytes_written_by([&](const fs::path& p) { write_png(p, colour); })};
    },
    [](const uint8_t* data, size_t size) {
      const fs::path scene_dir = llff_dir(2, false);
      const fs::path masks = scratch_dir() / "masks";
      fs::create_directories(masks);
      write_file(masks / "img001.png", data, size);
      SceneOptions options;
      options.mask_dir = masks;
      const Scene scene = load_scene(scene_dir, options);
      load_view_mask(scene.views[1]);
    }});

}  // namespace
}  // namespace ii::fuzz
