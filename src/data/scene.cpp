#include "data/scene.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <map>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "common/error.h"
#include "data/image_ops.h"
#include "data/scene_readers.h"
#include "data/undistort.h"
#include "io/colmap.h"

namespace ii {

namespace fs = std::filesystem;

bool Scene::has_masks() const {
  return !views.empty() && std::all_of(views.begin(), views.end(), [](const View& v) {
    return v.mask_path.has_value() || v.mask_from_alpha;
  });
}

const View* Scene::find(const std::string& name) const {
  for (const auto* list : {&views, &test_views})
    for (const View& v : *list)
      if (v.name == name) return &v;
  return nullptr;
}

namespace {

std::string detect_format(const fs::path& dir) {
  if (fs::exists(dir / "poses_bounds.npy")) return "llff";
  if (fs::exists(dir / "transforms.json")) return "nerfstudio";
  for (const char* sub : {"sparse/0", "sparse", "."})
    if (fs::exists(dir / sub / "cameras.bin") || fs::exists(dir / sub / "cameras.txt"))
      return "colmap";
  fail_file(dir,
            "cannot tell the scene format: expected poses_bounds.npy (LLFF), transforms.json "
            "(nerfstudio) or a COLMAP model (sparse/0/cameras.bin)");
}

}  // namespace

fs::path choose_image_folder(const fs::path& dir, const SceneOptions& options, const std::string& next_to) {
  if (!options.image_folder.empty()) {
    const fs::path p = dir / options.image_folder;
    if (!fs::is_directory(p)) fail_file(p, "image folder not found");
    return p;
  }
  if (fs::is_directory(dir / "images")) return dir / "images";
  fs::path best;
  int best_factor = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string n = e.path().filename().string();
    if (!e.is_directory() || n.rfind("images_", 0) != 0) continue;
    const int factor = std::atoi(n.c_str() + 7);
    if (factor > 0 && (best_factor == 0 || factor < best_factor)) {
      best_factor = factor;
      best = e.path();
    }
  }
  if (best.empty()) fail_file(dir, "no images/ or images_K/ folder next to {}", next_to);
  return best;
}

Scene load_scene(const fs::path& dir, const SceneOptions& options) {
  if (!fs::is_directory(dir)) fail_file(dir, "scene folder not found");
  const std::string format = options.format == "auto" ? detect_format(dir) : options.format;
  Scene scene;
  if (format == "llff")
    scene = load_llff_scene(dir, options);
  else if (format == "nerfstudio")
    scene = load_nerfstudio_scene(dir, options);
  else if (format == "colmap")
    scene = load_colmap_scene(dir, options);
  else
    fail("unknown scene format '{}' (expected auto, llff, nerfstudio or colmap)", format);

  if (options.mask_dir) {
    const int matched = attach_mask_folder(scene, *options.mask_dir);
    if (matched == 0) fail_file(*options.mask_dir, "no mask file matches any image of the scene");
  }
  if (options.alpha_masks)
    for (View& v : scene.views) {
      v.mask_from_alpha = true;  // asked for explicitly: wins over mask files
      v.mask_path.reset();
    }
  if (options.hold_out_every < 0) fail("hold-out: every N views needs N >= 1, got {}", options.hold_out_every);
  if (options.hold_out_every > 0) {
    std::vector<View> inputs;
    for (size_t i = 0; i < scene.views.size(); ++i) {
      View& v = scene.views[i];
      if (i % static_cast<size_t>(options.hold_out_every) != 0) {
        inputs.push_back(std::move(v));
        continue;
      }
      if (options.hold_out_whole) {
        v.mask_path.reset();
        v.mask_from_alpha = false;
      } else if (!v.mask_path && !v.mask_from_alpha) {
        fail_file(dir, "view {} has no object mask; a held-out view is compared outside its mask (or evaluate a "
                  "reconstruction with --keep-object)", v.name);
      }
      v.shows_object = !options.hold_out_whole;
      scene.test_views.push_back(std::move(v));
    }
    if (inputs.empty()) fail_file(dir, "holding out every view leaves no input view");
    scene.notes.push_back(fmt::format("{} of {} views held out as test views (one in {})",
                                      scene.views.size() - inputs.size(), scene.views.size(),
                                      options.hold_out_every));
    scene.views = std::move(inputs);
  }
  for (const std::string& note : scene.notes) spdlog::info("{}", note);
  for (const std::string& w : scene.warnings) spdlog::warn("{}", w);
  return scene;
}

std::vector<Eigen::Vector3d> load_scene_points(const Scene& scene) {
  std::vector<Eigen::Vector3d> points;
  // Only formats whose poses live in the COLMAP model's world frame (nerfstudio files
  // usually re-orient the world).
  if (scene.format != "llff" && scene.format != "colmap") return points;
  for (const char* sub : {"sparse/0", "sparse", "."}) {
    const fs::path dir = scene.root / sub;
    const bool has_points = fs::exists(dir / "points3D.bin") || fs::exists(dir / "points3D.txt");
    const bool has_cameras = fs::exists(dir / "cameras.bin") || fs::exists(dir / "cameras.txt");
    if (!has_points || !has_cameras) continue;
    for (const auto& [id, point] : read_colmap_model(dir).points) points.push_back(point.xyz);
    break;
  }
  return points;
}

PoseNormalization scene_normalization(const Scene& scene) {
  std::vector<Camera> cameras;
  for (const auto* list : {&scene.views, &scene.test_views})
    for (const View& v : *list) cameras.push_back(v.camera);
  return fit_pose_normalization(cameras);
}

Image load_view_image(const View& view) {
  Image image = read_image_rgb(view.image_path);
  if (image.width != view.camera.K.width || image.height != view.camera.K.height)
    fail_file(view.image_path, "image is {}x{} but its camera describes {}x{}", image.width,
              image.height, view.camera.K.width, view.camera.K.height);
  if (view.distortion.any()) image = undistort_image(image, view.camera.K, view.distortion);
  return image;
}

bool mask_near_size(const Image& mask, int width, int height) {
  // Annotation tools sometimes export masks a few pixels off; more than that is a mismatch.
  const int tolerance = std::max(4, std::max(width, height) / 50);
  return std::abs(mask.width - width) <= tolerance && std::abs(mask.height - height) <= tolerance;
}

Image mask_at_image_size(Image mask, int width, int height, const fs::path& source) {
  if (mask.width == width && mask.height == height) return mask;
  if (!mask_near_size(mask, width, height))
    fail_file(source, "mask is {}x{} but its image is {}x{}", mask.width, mask.height, width, height);
  spdlog::warn("{}: mask is {}x{}, image is {}x{}: resized nearest-neighbour", source.string(), mask.width,
               mask.height, width, height);
  return resize_nearest(mask, width, height);
}

std::optional<Image> load_view_mask(const View& view) {
  Image mask;
  fs::path source;
  if (view.mask_path) {
    source = *view.mask_path;
    mask = read_mask(source);
  } else if (view.mask_from_alpha) {
    source = view.image_path;
    DecodedImage d = decode_image(source);
    if (!d.alpha) fail_file(source, "has no alpha channel to take the object mask from");
    mask = Image(d.alpha->width, d.alpha->height, 1);
    // Alpha 0 marks the object (cut out of the photo); anything opaque is background.
    for (size_t i = 0; i < mask.pixels.size(); ++i) mask.pixels[i] = d.alpha->pixels[i] < 0.5f ? 1.f : 0.f;
  } else {
    return std::nullopt;
  }

  mask = mask_at_image_size(std::move(mask), view.camera.K.width, view.camera.K.height, source);
  if (view.distortion.any()) mask = undistort_mask(mask, view.camera.K, view.distortion);
  return mask;
}

int attach_mask_folder(Scene& scene, const fs::path& mask_dir) {
  if (!fs::is_directory(mask_dir)) fail_file(mask_dir, "mask folder not found");
  std::map<std::string, fs::path> by_stem, by_file_name;
  for (const auto& entry : fs::directory_iterator(mask_dir)) {
    if (!entry.is_regular_file()) continue;
    const fs::path p = entry.path();
    by_stem[p.stem().string()] = p;
    by_file_name[p.filename().string()] = p;
  }
  int matched = 0;
  for (auto* list : {&scene.views, &scene.test_views}) {
    for (View& v : *list) {
      const std::string file = v.image_path.filename().string();
      // COLMAP convention first ("<image file name>.png"), then same stem.
      auto it = by_file_name.find(file + ".png");
      if (it == by_file_name.end()) it = by_stem.find(v.name);
      if (it == by_stem.end()) continue;
      v.mask_path = it->second;
      ++matched;
    }
  }
  return matched;
}

}  // namespace ii
