// LLFF / SPIn-NeRF scene reader.
//
// poses_bounds.npy holds one row of 17 numbers per image (in name-sorted order): a 3x5
// matrix [R | t | (H, W, f)] with rotation columns in LLFF order (down, right, back),
// then the near and far depth bounds. H, W, f describe the full-resolution images; the
// downscaled folders (images_K) scale them.
#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include <fmt/ranges.h>

#include "common/error.h"
#include "data/scene_readers.h"
#include "io/npy.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

bool is_image_file(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  static const std::set<std::string> known = {".png", ".jpg", ".jpeg", ".bmp", ".tga"};
  return known.count(ext) > 0;
}

std::vector<fs::path> sorted_images(const fs::path& dir) {
  std::vector<fs::path> files;
  if (!fs::is_directory(dir)) return files;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_regular_file() && is_image_file(e.path())) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}

// Masks in `folder` matched to images by file name, then by stem.
std::map<std::string, fs::path> masks_by_stem(const fs::path& folder) {
  std::map<std::string, fs::path> out;
  for (const fs::path& p : sorted_images(folder)) out[p.stem().string()] = p;
  return out;
}

}  // namespace

Scene load_llff_scene(const fs::path& dir, const SceneOptions& options) {
  const fs::path poses_file = dir / "poses_bounds.npy";
  const NpyArray poses = read_npy(poses_file);
  if (poses.shape.size() != 2 || poses.shape[1] != 17)
    fail_file(poses_file, "expected an N x 17 array, got shape {}", fmt::join(poses.shape, " x "));
  const auto values = poses.as_double();
  for (double v : values)
    if (!std::isfinite(v)) fail_file(poses_file, "contains NaN or infinite values");

  const fs::path image_dir = choose_image_folder(dir, options, "poses_bounds.npy");
  const std::vector<fs::path> images = sorted_images(image_dir);
  const size_t n = static_cast<size_t>(poses.shape[0]);
  if (images.size() != n)
    fail_file(image_dir, "holds {} images but {} has {} poses", images.size(),
              poses_file.filename().string(), n);

  Scene scene;
  // SPIn-NeRF: the first T sorted images are object-free test views, T = #test masks.
  const auto test_masks = masks_by_stem(image_dir / "test_label");
  const auto train_masks = masks_by_stem(image_dir / "label");
  const size_t test_count = test_masks.size();
  if (test_count >= n)
    fail_file(image_dir / "test_label", "has {} masks but the scene has only {} images", test_count, n);
  // Public copies of the benchmark name test masks by number (out_00001.png ...): when no
  // test-mask stem is an image stem, the k-th mask in name order belongs to the k-th image.
  const bool test_masks_by_order =
      test_count > 0 && std::none_of(test_masks.begin(), test_masks.end(), [&](const auto& kv) {
        return std::any_of(images.begin(), images.end(), [&](const fs::path& p) { return p.stem() == kv.first; });
      });
  if (test_masks_by_order && !train_masks.empty() && train_masks.size() != n - test_count &&
      train_masks.size() != n)
    fail_file(image_dir / "test_label",
              "{} masks are named after no image and cannot be paired with images by order: label/ has {} masks, "
              "and {} + {} is not the scene's {} images",
              test_count, train_masks.size(), test_count, train_masks.size(), n);
  if (test_masks_by_order)
    scene.notes.push_back(fmt::format("{}: {} masks are named after no image; paired with the first {} images in "
                                      "name order ({} -> {}, ...)",
                                      (image_dir / "test_label").string(), test_count, test_count,
                                      test_masks.begin()->second.filename().string(),
                                      images.front().filename().string()));
  if (!train_masks.empty() && train_masks.size() != n - test_count && train_masks.size() != n)
    fail_file(image_dir / "label", "has {} masks for {} training views", train_masks.size(),
              n - test_count);

  scene.root = dir;
  scene.format = "llff";
  double near = INFINITY, far = 0;
  for (size_t k = 0; k < n; ++k) {
    const double* row = &values[k * 17];
    auto m = [&](int r, int c) { return row[r * 5 + c]; };  // the 3x5 matrix, row-major
    const double H = m(0, 4), W = m(1, 4), f = m(2, 4);
    if (H <= 0 || W <= 0 || f <= 0)
      fail_file(poses_file, "row {}: image size / focal ({}, {}, {}) must be positive", k, H, W, f);
    near = std::min(near, row[15]);
    far = std::max(far, row[16]);

    View view;
    view.image_path = images[k];
    view.name = images[k].stem().string();
    // LLFF rotation columns are (down, right, back); OpenGL wants (right, up, back).
    Eigen::Matrix4d c2w = Eigen::Matrix4d::Identity();
    for (int r = 0; r < 3; ++r) {
      c2w(r, 0) = m(r, 1);
      c2w(r, 1) = -m(r, 0);
      c2w(r, 2) = m(r, 2);
      c2w(r, 3) = m(r, 3);
    }
    view.camera.c2w = c2w;
    const ImageInfo info = probe_image(images[k]);
    const double sx = info.width / W, sy = info.height / H;
    if (std::abs(sx - sy) > 0.02 * sx)
      scene.warnings.push_back(fmt::format("{}: {}x{} is not a uniform downscale of {}x{} from {}",
                                           images[k].string(), info.width, info.height, W, H,
                                           poses_file.filename().string()));
    view.camera.K = {info.width, info.height, f * sx, f * sy, info.width / 2.0, info.height / 2.0};

    const bool is_test = k < test_count;
    const auto& masks = is_test ? test_masks : train_masks;
    if (is_test && test_masks_by_order) view.mask_path = std::next(test_masks.begin(), k)->second;
    else if (auto it = masks.find(view.name); it != masks.end()) view.mask_path = it->second;
    else if (!masks.empty() && (is_test || train_masks.size() == n - test_count))
      fail_file(is_test ? image_dir / "test_label" : image_dir / "label", "no mask for image {}",
                images[k].filename().string());
    (is_test ? scene.test_views : scene.views).push_back(std::move(view));
  }
  scene.near = near;
  scene.far = far;
  return scene;
}

}  // namespace ii
