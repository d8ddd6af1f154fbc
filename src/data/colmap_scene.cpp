// COLMAP scene reader: a sparse model (binary or text) plus an image folder.
#include <Eigen/Geometry>
#include <algorithm>

#include "common/error.h"
#include "data/scene_readers.h"
#include "io/colmap.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

fs::path find_model_dir(const fs::path& dir) {
  for (const char* sub : {"sparse/0", "sparse", "."})
    if (fs::exists(dir / sub / "cameras.bin") || fs::exists(dir / sub / "cameras.txt")) return dir / sub;
  fail_file(dir, "no COLMAP model found (looked for sparse/0/, sparse/ and the folder itself)");
}

// Pinhole intrinsics and OpenCV-order distortion of a COLMAP camera.
void convert_camera(const ColmapCamera& c, const fs::path& file, Intrinsics& K, Distortion& d) {
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
    fail_file(file, "camera {}: unsupported camera model {} (supported: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV)",
              c.id, c.model);
  }
}

}  // namespace

Scene load_colmap_scene(const fs::path& dir, const SceneOptions& options) {
  const fs::path model_dir = find_model_dir(dir);
  const ColmapModel model = read_colmap_model(model_dir);
  const fs::path image_dir = dir / (options.image_folder.empty() ? "images" : options.image_folder);
  if (model.images.empty())
    fail_file(model_dir, "COLMAP model has no images (images.bin / images.txt missing or empty)");
  if (!fs::is_directory(image_dir)) fail_file(image_dir, "image folder not found");

  Scene scene;
  scene.root = dir;
  scene.format = "colmap";
  std::vector<const ColmapImage*> images;
  for (const auto& kv : model.images) images.push_back(&kv.second);
  std::sort(images.begin(), images.end(), [](auto* a, auto* b) { return a->name < b->name; });
  for (const ColmapImage* im : images) {
    auto cam = model.cameras.find(im->camera_id);
    if (cam == model.cameras.end()) fail_file(model_dir, "image {} refers to missing camera {}", im->name, im->camera_id);
    View v;
    v.image_path = image_dir / im->name;
    if (!fs::exists(v.image_path)) fail_file(v.image_path, "image listed in the COLMAP model is missing");
    v.name = fs::path(im->name).stem().string();
    convert_camera(cam->second, model_dir, v.camera.K, v.distortion);
    // Images may be a downscaled copy (images_4 of a full-size model): scale intrinsics.
    const ImageInfo info = probe_image(v.image_path);
    if (info.width != v.camera.K.width || info.height != v.camera.K.height)
      v.camera = v.camera.resized(info.width, info.height);
    const Eigen::Quaterniond q(im->qvec[0], im->qvec[1], im->qvec[2], im->qvec[3]);
    if (q.norm() < 1e-9) fail_file(model_dir, "image {} has a zero rotation quaternion", im->name);
    Eigen::Matrix4d w2c = Eigen::Matrix4d::Identity();
    w2c.block<3, 3>(0, 0) = q.normalized().toRotationMatrix();
    w2c.block<3, 1>(0, 3) = im->tvec;
    Eigen::Matrix4d c2w = Eigen::Matrix4d::Identity();
    c2w.block<3, 3>(0, 0) = w2c.block<3, 3>(0, 0).transpose();
    c2w.block<3, 1>(0, 3) = -c2w.block<3, 3>(0, 0) * im->tvec;
    v.camera.c2w = opencv_to_opengl(c2w);
    scene.views.push_back(std::move(v));
  }
  return scene;
}

}  // namespace ii
