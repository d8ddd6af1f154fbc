// nerfstudio / instant-ngp scene reader: transforms.json with camera-to-world matrices in
// OpenGL axes and global or per-frame intrinsics (a frame's value wins over the global one).
#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include <Eigen/LU>
#include <Eigen/SVD>

#include "common/error.h"
#include "common/files.h"
#include "data/scene_readers.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

using nlohmann::json;

class Reader {
 public:
  explicit Reader(fs::path file) : file_(std::move(file)) {}

  // A number from the frame, else from the top level, else `fallback`. A key that is
  // present but not a number is an error, not silently ignored.
  double number(const json& frame, size_t index, const char* key, double fallback) const {
    for (const json* scope : {&frame, &root}) {
      auto it = scope->find(key);
      if (it == scope->end() || it->is_null()) continue;
      if (!it->is_number())
        fail_file(file_, "{}'{}' must be a number, got {}", where(scope == &frame, index), key, it->dump());
      return it->get<double>();
    }
    return fallback;
  }

  std::string string(const json& frame, const char* key) const {
    for (const json* scope : {&frame, &root}) {
      auto it = scope->find(key);
      if (it != scope->end() && it->is_string()) return it->get<std::string>();
    }
    return {};
  }

  // instant-ngp's boolean flags, per frame or global.
  bool flag(const json& frame, const char* key) const {
    for (const json* scope : {&frame, &root}) {
      auto it = scope->find(key);
      if (it != scope->end() && it->is_boolean() && it->get<bool>()) return true;
    }
    return false;
  }

  static std::string where(bool in_frame, size_t index) {
    return in_frame ? fmt::format("frame {}: ", index) : std::string();
  }

  const fs::path& file() const { return file_; }
  json root;

 private:
  fs::path file_;
};

// file_path is relative to the json's folder, may use backslashes (Windows exports) and
// may lack the extension (NeRF-synthetic "./train/r_0").
fs::path resolve_image(const fs::path& dir, std::string file_path, const std::string& image_folder) {
  std::replace(file_path.begin(), file_path.end(), '\\', '/');
  fs::path p = dir / file_path;
  // A user-chosen folder (e.g. nerfstudio's downscaled images_2/) holds the same file names.
  if (!image_folder.empty()) p = dir / image_folder / p.filename();
  if (p.has_extension() && fs::exists(p)) return p;
  for (const char* ext : {".png", ".jpg", ".jpeg", ".PNG", ".JPG", ".JPEG"}) {
    fs::path q = p;
    q += ext;
    if (fs::exists(q)) return q;
  }
  return p;
}

Eigen::Matrix4d read_matrix(const Reader& r, const json& m, size_t i) {
  // 4x4, or 3x4 without the constant last row.
  if (!m.is_array() || (m.size() != 4 && m.size() != 3))
    fail_file(r.file(), "frame {}: transform_matrix must be a 4x4 (or 3x4) array", i);
  Eigen::Matrix4d c2w = Eigen::Matrix4d::Identity();
  for (size_t row = 0; row < m.size(); ++row) {
    if (!m[row].is_array() || m[row].size() != 4)
      fail_file(r.file(), "frame {}: transform_matrix must be a 4x4 (or 3x4) array", i);
    for (size_t col = 0; col < 4; ++col) {
      if (!m[row][col].is_number()) fail_file(r.file(), "frame {}: transform_matrix holds a non-number", i);
      c2w(row, col) = m[row][col].get<double>();
    }
  }
  if (!c2w.allFinite()) fail_file(r.file(), "frame {}: transform_matrix holds NaN or infinity", i);
  if (!c2w.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1), 1e-9))
    fail_file(r.file(), "frame {}: transform_matrix's last row must be 0 0 0 1", i);
  return c2w;
}

}  // namespace

Scene load_nerfstudio_scene(const fs::path& dir, const SceneOptions& options) {
  Reader r(dir / "transforms.json");
  try {
    r.root = json::parse(read_file_text(r.file()));
  } catch (const json::exception& e) {
    fail_file(r.file(), "invalid JSON: {}", e.what());
  }
  if (!r.root.is_object()) fail_file(r.file(), "must hold a JSON object");
  auto frames_it = r.root.find("frames");
  if (frames_it == r.root.end() || !frames_it->is_array() || frames_it->empty()) fail_file(r.file(), "has no frames");
  const json& frames = *frames_it;

  Scene scene;
  scene.root = dir;
  scene.format = "nerfstudio";
  size_t missing = 0;
  std::string first_missing;
  for (size_t i = 0; i < frames.size(); ++i) {
    const json& f = frames[i];
    if (!f.is_object() || !f.contains("file_path") || !f["file_path"].is_string() || !f.contains("transform_matrix"))
      fail_file(r.file(), "frame {} needs file_path and transform_matrix", i);

    // Only pinhole projections with OpenCV-style distortion map onto our cameras.
    const std::string model = r.string(f, "camera_model");
    if (!model.empty() && model != "OPENCV" && model != "PINHOLE" && model != "SIMPLE_PINHOLE")
      fail_file(r.file(), "frame {}: unsupported camera_model {} (supported: PINHOLE, OPENCV)", i, model);
    if (r.flag(f, "is_fisheye"))
      fail_file(r.file(), "frame {}: fisheye cameras are not supported", i);

    View v;
    v.image_path = resolve_image(dir, f["file_path"].get<std::string>(), options.image_folder);
    // Trimmed datasets list frames whose images were removed (instant-ngp's fox lists 67
    // frames, its repository keeps 50): a user expects the rest to load, so missing frames
    // are skipped with a warning; only a scene with no image at all is an error.
    if (!fs::exists(v.image_path)) {
      if (missing++ == 0) first_missing = v.image_path.string();
      continue;
    }
    v.camera.c2w = read_matrix(r, f["transform_matrix"], i);

    const ImageInfo info = probe_image(v.image_path);
    // w, h describe the images the intrinsics belong to; absent = the image's own size.
    const double w = r.number(f, i, "w", info.width), h = r.number(f, i, "h", info.height);
    if (!(w >= 1 && h >= 1 && w <= 1e6 && h <= 1e6))
      fail_file(r.file(), "frame {}: image size {}x{} is not plausible", i, w, h);
    double fx = r.number(f, i, "fl_x", 0), fy = r.number(f, i, "fl_y", 0);
    if (fx <= 0) {
      const double angle_x = r.number(f, i, "camera_angle_x", 0);
      if (angle_x > 0 && angle_x < M_PI) fx = w / (2 * std::tan(angle_x / 2));
    }
    if (fy <= 0) {
      const double angle_y = r.number(f, i, "camera_angle_y", 0);
      if (angle_y > 0 && angle_y < M_PI) fy = h / (2 * std::tan(angle_y / 2));
    }
    // One focal given: square pixels.
    if (fx <= 0) fx = fy;
    if (fy <= 0) fy = fx;
    if (!(fx > 0) || !std::isfinite(fx) || !std::isfinite(fy))
      fail_file(r.file(), "frame {}: no focal length (fl_x, fl_y, camera_angle_x or camera_angle_y)", i);
    v.camera.K = {static_cast<int>(std::lround(w)), static_cast<int>(std::lround(h)), fx, fy,
                  r.number(f, i, "cx", w / 2), r.number(f, i, "cy", h / 2)};

    // nerfstudio's k3, k4 multiply r^6, r^8 in the radial polynomial; OpenCV's 5-coefficient
    // model has k3 (r^6) but no r^8 term.
    if (r.number(f, i, "k4", 0) != 0)
      fail_file(r.file(), "frame {}: distortion k4 (r^8 term) is not supported", i);
    v.distortion.coeffs = {r.number(f, i, "k1", 0), r.number(f, i, "k2", 0), r.number(f, i, "p1", 0),
                           r.number(f, i, "p2", 0), r.number(f, i, "k3", 0)};

    if (info.width != v.camera.K.width || info.height != v.camera.K.height) {
      const double sx = static_cast<double>(info.width) / w, sy = static_cast<double>(info.height) / h;
      if (std::abs(sx - sy) > 0.02 * std::max(sx, sy))
        scene.warnings.push_back(fmt::format("{}: {}x{} is not a uniform rescale of the {}x{} in {}",
                                             v.image_path.string(), info.width, info.height, w, h,
                                             r.file().filename().string()));
      v.camera = v.camera.resized(info.width, info.height);
    }

    // Some exporters leave a scale in the rotation; our cameras need a pure rotation.
    const Eigen::Matrix3d R = v.camera.rotation();
    if (!(R.transpose() * R).isApprox(Eigen::Matrix3d::Identity(), 1e-4)) {
      const Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
      if (svd.singularValues().minCoeff() < 1e-6 || R.determinant() <= 0)
        fail_file(r.file(), "frame {}: transform_matrix has no valid rotation", i);
      v.camera.c2w.block<3, 3>(0, 0) = svd.matrixU() * svd.matrixV().transpose();
      scene.warnings.push_back(
          fmt::format("{}: frame {}: rotation was not orthonormal; using the nearest rotation", r.file().string(), i));
    }
    scene.views.push_back(std::move(v));
  }
  if (scene.views.empty())
    fail_file(r.file(), "none of its {} frames has an image file (first: {})", frames.size(), first_missing);
  if (missing)
    scene.warnings.push_back(fmt::format("{}: {} of {} frames have no image file and were skipped (first: {})",
                                         r.file().string(), missing, frames.size(), first_missing));
  assign_view_names(scene.views, dir);
  return scene;
}

}  // namespace ii
