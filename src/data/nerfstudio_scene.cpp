// nerfstudio / instant-ngp scene reader: transforms.json with camera-to-world matrices in
// OpenGL axes and global or per-frame intrinsics.
#include <cmath>
#include <algorithm>
#include <nlohmann/json.hpp>

#include "common/error.h"
#include "common/files.h"
#include "data/scene_readers.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

double number(const nlohmann::json& frame, const nlohmann::json& global, const char* key, double fallback) {
  if (frame.contains(key) && frame[key].is_number()) return frame[key].get<double>();
  if (global.contains(key) && global[key].is_number()) return global[key].get<double>();
  return fallback;
}

fs::path resolve_image(const fs::path& dir, std::string file_path) {
  std::replace(file_path.begin(), file_path.end(), '\\', '/');
  fs::path p = dir / file_path;
  if (p.has_extension() && fs::exists(p)) return p;
  for (const char* ext : {".png", ".jpg", ".jpeg", ".PNG", ".JPG", ".JPEG"}) {
    fs::path q = p;
    q += ext;
    if (fs::exists(q)) return q;
  }
  return p;
}

}  // namespace

Scene load_nerfstudio_scene(const fs::path& dir, const SceneOptions& options) {
  const fs::path file = dir / "transforms.json";
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(read_file_text(file));
  } catch (const nlohmann::json::exception& e) {
    fail_file(file, "invalid JSON: {}", e.what());
  }
  if (!j.is_object() || !j.contains("frames") || !j["frames"].is_array() || j["frames"].empty())
    fail_file(file, "has no frames");

  Scene scene;
  scene.root = dir;
  scene.format = "nerfstudio";
  int missing = 0;
  std::string first_missing;
  for (size_t i = 0; i < j["frames"].size(); ++i) {
    const auto& f = j["frames"][i];
    if (!f.contains("file_path") || !f["file_path"].is_string() || !f.contains("transform_matrix"))
      fail_file(file, "frame {} needs file_path and transform_matrix", i);
    std::string file_path = f["file_path"].get<std::string>();
    if (!options.image_folder.empty()) file_path = options.image_folder + "/" + fs::path(file_path).filename().string();
    View v;
    v.image_path = resolve_image(dir, file_path);
    // Frames whose image is absent (trimmed datasets) are skipped with a warning.
    if (!fs::exists(v.image_path)) {
      if (missing++ == 0) first_missing = v.image_path.string();
      continue;
    }
    v.name = v.image_path.stem().string();
    const auto& m = f["transform_matrix"];
    if (!m.is_array() || (m.size() != 4 && m.size() != 3)) fail_file(file, "frame {}: transform_matrix must be 4x4", i);
    for (int r = 0; r < static_cast<int>(m.size()); ++r) {
      if (!m[r].is_array() || m[r].size() != 4) fail_file(file, "frame {}: transform_matrix must be 4x4", i);
      for (int c = 0; c < 4; ++c) {
        if (!m[r][c].is_number()) fail_file(file, "frame {}: transform_matrix holds a non-number", i);
        v.camera.c2w(r, c) = m[r][c].get<double>();
        if (!std::isfinite(v.camera.c2w(r, c))) fail_file(file, "frame {}: transform_matrix holds NaN or infinity", i);
      }
    }
    const ImageInfo info = probe_image(v.image_path);
    const double w = number(f, j, "w", info.width), h = number(f, j, "h", info.height);
    double fx = number(f, j, "fl_x", 0), fy = number(f, j, "fl_y", 0);
    if (fx <= 0) {
      const double angle_x = number(f, j, "camera_angle_x", 0);
      if (angle_x <= 0) fail_file(file, "frame {}: no focal length (fl_x or camera_angle_x)", i);
      fx = w / (2 * std::tan(angle_x / 2));
    }
    if (fy <= 0) {
      const double angle_y = number(f, j, "camera_angle_y", 0);
      fy = angle_y > 0 ? h / (2 * std::tan(angle_y / 2)) : fx;
    }
    v.camera.K = {static_cast<int>(w), static_cast<int>(h), fx, fy, number(f, j, "cx", w / 2), number(f, j, "cy", h / 2)};
    v.distortion.coeffs = {number(f, j, "k1", 0), number(f, j, "k2", 0), number(f, j, "p1", 0), number(f, j, "p2", 0),
                           number(f, j, "k3", 0)};
    if (info.width != v.camera.K.width || info.height != v.camera.K.height)
      v.camera = v.camera.resized(info.width, info.height);
    scene.views.push_back(std::move(v));
  }
  if (scene.views.empty()) fail_file(file, "none of its {} frames has an image file (first: {})", j["frames"].size(), first_missing);
  if (missing)
    scene.warnings.push_back(fmt::format("{}: {} frames without an image file were skipped (first: {})", file.string(),
                                         missing, first_missing));
  return scene;
}

}  // namespace ii
