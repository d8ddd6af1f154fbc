// COLMAP scene reader: a sparse model (binary or text) plus an image folder.
//
// COLMAP stores world-to-camera poses in OpenCV axes (x right, y down, z forward) as a
// quaternion (w, x, y, z) and a translation; intrinsics belong to the camera's own
// width x height, which may be larger than the image files (images_4 of a full-size model).
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "common/error.h"
#include "data/scene_readers.h"
#include "io/colmap.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

fs::path find_model_dir(const fs::path& dir) {
  for (const char* sub : {"sparse/0", "sparse", "."}) {
    const fs::path p = sub == std::string(".") ? dir : dir / sub;
    if (fs::exists(p / "cameras.bin") || fs::exists(p / "cameras.txt")) return p;
  }
  fail_file(dir, "no COLMAP model found (looked for cameras.bin / cameras.txt in sparse/0/, sparse/ and the folder itself)");
}

// The image file of a model entry. Downscaled folders made by LLFF's tools hold PNGs for
// JPG originals, so the same stem with another extension is accepted.
fs::path find_image_file(const fs::path& image_dir, const std::string& name) {
  const fs::path exact = image_dir / name;
  if (fs::exists(exact)) return exact;
  for (const char* ext : {".png", ".jpg", ".jpeg", ".PNG", ".JPG", ".JPEG"}) {
    fs::path p = exact;
    p.replace_extension(ext);
    if (fs::exists(p)) return p;
  }
  fail_file(exact, "image listed in the COLMAP model is missing");
}

// Pinhole intrinsics and OpenCV-order distortion (k1, k2, p1, p2, k3) of a COLMAP camera.
void convert_camera(const ColmapCamera& c, const fs::path& model_dir, Intrinsics& K, Distortion& d) {
  const auto& p = c.params;
  K.width = c.width;
  K.height = c.height;
  if (c.model == "SIMPLE_PINHOLE" || c.model == "SIMPLE_RADIAL" || c.model == "RADIAL") {
    K.fx = K.fy = p[0];
    K.cx = p[1];
    K.cy = p[2];
    if (c.model == "SIMPLE_RADIAL") d.coeffs[0] = p[3];
    if (c.model == "RADIAL") {
      d.coeffs[0] = p[3];
      d.coeffs[1] = p[4];
    }
  } else if (c.model == "PINHOLE" || c.model == "OPENCV") {
    K.fx = p[0];
    K.fy = p[1];
    K.cx = p[2];
    K.cy = p[3];
    if (c.model == "OPENCV")
      for (int k = 0; k < 4; ++k) d.coeffs[k] = p[4 + k];
  } else {
    fail_file(model_dir,
              "camera {}: unsupported camera model {} (supported: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV)",
              c.id, c.model);
  }
  if (!(K.fx > 0) || !(K.fy > 0)) fail_file(model_dir, "camera {}: focal length must be positive", c.id);
}

// Linear-interpolated percentile of sorted values (numpy's default).
double percentile(const std::vector<double>& sorted, double q) {
  const double pos = q / 100.0 * static_cast<double>(sorted.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(pos));
  const size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (pos - static_cast<double>(lo)) * (sorted[hi] - sorted[lo]);
}

// Depth bounds as LLFF's imgs2poses computes them: per image, the 0.1th and 99.9th
// percentiles of the depths of the points it sees (its track entries); the scene keeps the
// smallest near and the largest far. Without tracks, every point in front of a camera
// counts.
void set_depth_bounds(Scene& scene, const ColmapModel& model,
                      const std::map<int, std::pair<Eigen::Matrix3d, Eigen::Vector3d>>& w2c) {
  if (model.points.empty()) return;
  std::map<int, std::vector<double>> depths;
  bool any_track = false;
  for (const auto& [id, p] : model.points)
    for (const auto& [image_id, index] : p.track) {
      auto it = w2c.find(image_id);
      if (it == w2c.end()) continue;
      any_track = true;
      const double z = (it->second.first * p.xyz + it->second.second).z();
      if (z > 0) depths[image_id].push_back(z);
    }
  if (!any_track)
    for (const auto& [image_id, pose] : w2c)
      for (const auto& [id, p] : model.points) {
        const double z = (pose.first * p.xyz + pose.second).z();
        if (z > 0) depths[image_id].push_back(z);
      }
  double near = INFINITY, far = 0;
  for (auto& [image_id, z] : depths) {
    std::sort(z.begin(), z.end());
    near = std::min(near, percentile(z, 0.1));
    far = std::max(far, percentile(z, 99.9));
  }
  if (std::isfinite(near) && near > 0 && far > near) {
    scene.near = near;
    scene.far = far;
  }
}

}  // namespace

void assign_view_names(std::vector<View>& views, const fs::path& base) {
  std::map<std::string, int> stem_count;
  for (const View& v : views) ++stem_count[v.image_path.stem().string()];
  std::map<std::string, const View*> taken;
  for (View& v : views) {
    v.name = v.image_path.stem().string();
    if (stem_count[v.name] > 1) {
      std::string rel = v.image_path.lexically_relative(base).replace_extension().generic_string();
      if (rel.empty() || rel.rfind("..", 0) == 0) rel = v.image_path.stem().string();
      std::replace(rel.begin(), rel.end(), '/', '_');
      v.name = rel;
    }
    auto [it, fresh] = taken.emplace(v.name, &v);
    if (!fresh)
      fail_file(v.image_path, "has the same name '{}' as {}: rename one of them", v.name, it->second->image_path.string());
  }
}

Scene load_colmap_scene(const fs::path& dir, const SceneOptions& options) {
  const fs::path model_dir = find_model_dir(dir);
  const ColmapModel model = read_colmap_model(model_dir);
  if (model.images.empty())
    fail_file(model_dir, "COLMAP model has no images (images.bin / images.txt missing or empty)");
  const fs::path image_dir = choose_image_folder(dir, options, "the COLMAP model");

  Scene scene;
  scene.root = dir;
  scene.format = "colmap";
  std::vector<const ColmapImage*> images;
  for (const auto& kv : model.images) images.push_back(&kv.second);
  std::sort(images.begin(), images.end(), [](auto* a, auto* b) { return a->name < b->name; });
  std::map<int, std::pair<Eigen::Matrix3d, Eigen::Vector3d>> w2c;  // for the depth bounds
  for (const ColmapImage* im : images) {
    auto cam = model.cameras.find(im->camera_id);
    if (cam == model.cameras.end()) fail_file(model_dir, "image {} refers to missing camera {}", im->name, im->camera_id);
    View v;
    v.image_path = find_image_file(image_dir, im->name);
    convert_camera(cam->second, model_dir, v.camera.K, v.distortion);

    // Images may be a downscaled copy of what the model was built from: scale intrinsics
    // (distortion is defined on normalised coordinates and stays).
    const ImageInfo info = probe_image(v.image_path);
    if (info.width != v.camera.K.width || info.height != v.camera.K.height) {
      const double sx = static_cast<double>(info.width) / v.camera.K.width;
      const double sy = static_cast<double>(info.height) / v.camera.K.height;
      if (std::abs(sx - sy) > 0.02 * std::max(sx, sy))
        scene.warnings.push_back(fmt::format("{}: {}x{} is not a uniform rescale of camera {} ({}x{})",
                                             v.image_path.string(), info.width, info.height, cam->first,
                                             v.camera.K.width, v.camera.K.height));
      v.camera = v.camera.resized(info.width, info.height);
    }

    const Eigen::Quaterniond q(im->qvec[0], im->qvec[1], im->qvec[2], im->qvec[3]);
    if (q.norm() < 1e-9) fail_file(model_dir, "image {} has a zero rotation quaternion", im->name);
    const Eigen::Matrix3d R = q.normalized().toRotationMatrix();
    w2c[im->id] = {R, im->tvec};
    // c2w = inverse of the rigid w2c, then OpenCV -> OpenGL axes.
    Eigen::Matrix4d c2w = Eigen::Matrix4d::Identity();
    c2w.block<3, 3>(0, 0) = R.transpose();
    c2w.block<3, 1>(0, 3) = -R.transpose() * im->tvec;
    v.camera.c2w = opencv_to_opengl(c2w);
    scene.views.push_back(std::move(v));
  }
  assign_view_names(scene.views, image_dir);
  set_depth_bounds(scene, model, w2c);
  return scene;
}

}  // namespace ii
