#include "synth/synth_writer.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "common/error.h"
#include "common/files.h"
#include "common/parallel.h"
#include "common/stopwatch.h"
#include "common/torch.h"
#include "io/image.h"
#include "io/npy.h"
#include "io/ply.h"
#include "render/rasterizer.h"
#include "synth/random.h"

namespace ii::synth {

namespace fs = std::filesystem;

namespace {

// The object and the background splats some view sees: a splat's opacity has a gradient in a
// view's render exactly when it adds to one of its pixels.
GaussianSet seen_by_views(const GaussianSet& background, const GaussianSet& object, const std::vector<NamedCamera>& views) {
  GaussianSet all;
  all.means = torch::cat({object.means, background.means});
  all.quats = torch::cat({object.quats, background.quats});
  all.scales = torch::cat({object.scales, background.scales});
  auto rgb = [](const GaussianSet& g) { return g.colors.dim() == 3 ? rgb_from_sh_dc(g.colors.select(1, 0)) : g.colors; };
  all.colors = object.colors.dim() == background.colors.dim() ? torch::cat({object.colors, background.colors})
                                                              : torch::cat({rgb(object), rgb(background)});
  all.sh_degree = object.colors.dim() == background.colors.dim() ? background.sh_degree : -1;
  const torch::Tensor opacities = torch::cat({object.opacities.reshape({-1}), background.opacities.reshape({-1})});
  torch::Tensor seen = torch::zeros({all.size()}, torch::kBool);
  for (const NamedCamera& v : views) {
    all.opacities = opacities.detach().clone().requires_grad_(true);
    const RenderOutput out = render(all, {v.camera});
    (out.rgb.sum() + out.alpha.sum()).backward();
    seen = seen.logical_or(all.opacities.grad().abs() > 0);
  }
  seen.narrow(0, 0, object.size()).fill_(true);
  all.opacities = opacities;
  return select_rows(all, seen);
}


constexpr uint64_t kReferenceStream = 99;

// float32 (H, W) array.
void write_depth(const fs::path& path, const Image& depth) {
  NpyArray array;
  array.dtype = "f4";
  array.shape = {depth.height, depth.width};
  array.data.resize(depth.pixels.size() * sizeof(float));
  std::memcpy(array.data.data(), depth.pixels.data(), array.data.size());
  write_npy(path, array);
}

// Depth bounds of a view for poses_bounds.npy: a margin around the depths it sees.
std::pair<double, double> depth_bounds(const Image& depth) {
  double lo = std::numeric_limits<double>::infinity(), hi = 0;
  for (float z : depth.pixels)
    if (z > 0) {
      lo = std::min<double>(lo, z);
      hi = std::max<double>(hi, z);
    }
  if (!(hi > 0)) return {0.1, 10.0};
  return {0.9 * lo, 1.1 * hi};
}

// Pre-activation splat values (3DGS PLY) of RGB Gaussians.
// An existing target may be replaced only if it is an earlier synthetic scene or empty.
void check_replaceable(const fs::path& dir) {
  if (!fs::exists(dir)) return;
  if (!fs::is_directory(dir)) fail_file(dir, "exists and is not a folder");
  if (!fs::exists(dir / "synth.json") && !fs::is_empty(dir))
    fail_file(dir, "exists and is not a synthetic scene (no synth.json): not overwriting it");
}

// Removes the partial folder when writing fails half-way.
struct PartialFolder {
  fs::path path;
  bool done = false;
  ~PartialFolder() {
    std::error_code ignored;
    if (!done) fs::remove_all(path, ignored);
  }
};

}  // namespace

std::array<double, 17> llff_pose_row(const Camera& camera, int downscale, double near, double far) {
  std::array<double, 17> row{};
  const Eigen::Matrix4d& c2w = camera.c2w;
  for (int r = 0; r < 3; ++r) {
    // OpenGL columns (right, up, back) -> LLFF (down, right, back).
    row[r * 5 + 0] = -c2w(r, 1);
    row[r * 5 + 1] = c2w(r, 0);
    row[r * 5 + 2] = c2w(r, 2);
    row[r * 5 + 3] = c2w(r, 3);
  }
  row[0 * 5 + 4] = double(camera.K.height) * downscale;
  row[1 * 5 + 4] = double(camera.K.width) * downscale;
  row[2 * 5 + 4] = camera.K.fx * downscale;
  row[15] = near;
  row[16] = far;
  return row;
}

SynthTask parse_synth_task(const std::string& text, const std::string& what) {
  if (text == "remove") return SynthTask::remove;
  if (text == "insert") return SynthTask::insert;
  fail("{}: unknown task '{}' (expected remove or insert)", what, text);
}

std::string to_string(SynthTask task) { return task == SynthTask::insert ? "insert" : "remove"; }

SynthWriteSummary write_synth_scene(const SynthScene& scene, const fs::path& dir, const SynthWriteOptions& options) {
  if (options.downscale < 1) fail("synth: downscale must be at least 1 (got {})", options.downscale);
  fs::path target = dir.lexically_normal();
  if (target.filename().empty()) target = target.parent_path();  // "scene/"
  if (target.empty()) fail("synth: empty output folder name");
  check_replaceable(target);
  PartialFolder partial_guard{target.parent_path() / (target.filename().string() + ".partial")};
  const fs::path& partial = partial_guard.path;
  fs::remove_all(partial);
  const std::string image_folder = "images_" + std::to_string(options.downscale);
  const fs::path images = partial / image_folder;
  const bool insert = options.task == SynthTask::insert;
  for (const fs::path& p : {images / "label", images / "test_label", partial / "clean"}) fs::create_directories(p);
  if (insert) fs::create_directories(partial / "original");
  if (options.write_depth)
    for (const char* folder : {"depth", "depth_clean"}) fs::create_directories(partial / folder);

  SynthRenderer renderer(scene);
  Stopwatch total_watch;
  double render_ms = 0;
  const int total = static_cast<int>(scene.test_views.size() + scene.views.size());
  int done = 0;
  std::vector<double> rows;  // poses_bounds.npy, in name-sorted order: test views first
  auto add_row = [&](const Camera& camera, const Image& depth) {
    const auto [near, far] = depth_bounds(depth);
    const auto row = llff_pose_row(camera, options.downscale, near, far);
    rows.insert(rows.end(), row.begin(), row.end());
  };

  BackgroundJobs writes(8);
  // Removal: test views and clean/ without the object, inputs with it. Insertion: the reverse.
  using Member = Image SynthViewImages::*;
  const Member with = &SynthViewImages::with_object, without = &SynthViewImages::clean;
  const Member with_depth = &SynthViewImages::depth, without_depth = &SynthViewImages::clean_depth;
  const Member input = insert ? without : with, edited = insert ? with : without;
  const Member input_depth = insert ? without_depth : with_depth, target_depth = insert ? with_depth : without_depth;
  for (const NamedCamera& view : scene.test_views) {
    Stopwatch render_watch;
    auto r = std::make_shared<const SynthViewImages>(renderer.render(view.camera, insert));
    render_ms += render_watch.ms();
    add_row(view.camera, (*r).*target_depth);
    const std::string file = view.name + ".png";
    writes.add([=] { write_png(images / file, (*r).*edited); });
    writes.add([=] { write_png(images / "test_label" / file, r->mask); });
    writes.add([=] { write_png(partial / "clean" / file, (*r).*edited); });
    if (insert) writes.add([=] { write_png(partial / "original" / file, r->clean); });
    if (options.write_depth)
      for (const char* folder : {"depth", "depth_clean"})
        writes.add([=] { write_depth(partial / folder / (view.name + ".npy"), (*r).*target_depth); });
    if (options.progress) options.progress(++done, total);
  }

  SynthWriteSummary summary;
  nlohmann::json fractions = nlohmann::json::object();
  std::shared_ptr<const SynthViewImages> reference_view;
  for (size_t k = 0; k < scene.views.size(); ++k) {
    const NamedCamera& view = scene.views[k];
    Stopwatch render_watch;
    auto r = std::make_shared<const SynthViewImages>(renderer.render(view.camera, true));
    render_ms += render_watch.ms();
    add_row(view.camera, (*r).*input_depth);
    double covered = 0;
    for (float m : r->mask.pixels) covered += m;
    const double fraction = covered / r->mask.pixels.size();
    fractions[view.name] = fraction;
    summary.object_fraction += fraction / scene.views.size();
    if (static_cast<int>(k) == scene.reference) reference_view = r;
    const std::string file = view.name + ".png";
    writes.add([=] { write_png(images / file, (*r).*input); });
    writes.add([=] { write_png(images / "label" / file, r->mask); });
    writes.add([=] { write_png(partial / "clean" / file, (*r).*edited); });
    if (options.write_depth) {
      writes.add([=] { write_depth(partial / "depth" / (view.name + ".npy"), (*r).*input_depth); });
      writes.add([=] { write_depth(partial / "depth_clean" / (view.name + ".npy"), (*r).*target_depth); });
    }
    if (options.progress) options.progress(++done, total);
  }
  writes.finish();
  write_npy(partial / "poses_bounds.npy", rows, {static_cast<int64_t>(total), 17});

  // The edited photo: the reference view as it should look after the edit, degraded like a
  // 2D editor's output would be (insertion: the object is what was painted in).
  const Image reference = degrade_reference((*reference_view).*edited, (*reference_view).*input, reference_view->mask,
                                            options.degrade, mix_seed(scene.seed, kReferenceStream),
                                            &summary.degradation);
  write_png(partial / "reference.png", reference);

  std::vector<NamedCamera> cameras = scene.test_views;
  cameras.insert(cameras.end(), scene.views.begin(), scene.views.end());
  write_camera_json(partial / "cameras.json", cameras);

  if (options.save_gaussians) {
    write_splat_ply(partial / "background.ply", splats_from_gaussians(scene.background));
    write_splat_ply(partial / "object.ply", splats_from_gaussians(scene.object));
    write_splat_ply(partial / "scene.ply", splats_from_gaussians(seen_by_views(scene.background, scene.object, scene.views)));
  }

  summary.views = static_cast<int>(scene.views.size());
  summary.test_views = static_cast<int>(scene.test_views.size());
  summary.reference = scene.views.at(scene.reference).name;
  nlohmann::json names = nlohmann::json::array(), test_names = nlohmann::json::array(),
                 context = nlohmann::json::array();
  for (const NamedCamera& v : scene.views) names.push_back(v.name);
  for (const NamedCamera& v : scene.test_views) test_names.push_back(v.name);
  for (int i : scene.context) context.push_back(scene.views.at(i).name);
  const Intrinsics& K = scene.views.front().camera.K;
  nlohmann::json depth_info = nullptr;  // null: not written
  if (options.write_depth)
    depth_info = {{"folder", "depth"},
                  {"encoding", "<view name>.npy, float32 (H, W)"},
                  {"content", "expected camera z of the image in image_folder, scene units (0: nothing hit)"},
                  {"clean_folder", "depth_clean"},
                  {"clean_content", "the same for the image in clean_folder"}};
  nlohmann::json j = {
      {"format", "instainpaint-synth"},
      {"version", 1},
      {"seed", scene.seed},
      {"task", to_string(options.task)},
      {"generator", options.generator},
      {"width", K.width},
      {"height", K.height},
      {"intrinsics", {{"fx", K.fx}, {"fy", K.fy}, {"cx", K.cx}, {"cy", K.cy}, {"fov_y_deg", K.fov_y() * 180 / M_PI}}},
      {"image_folder", image_folder},
      {"views", names},
      {"test_views", test_names},
      {"reference", summary.reference},
      {"reference_image", "reference.png"},
      {"reference_degradation", summary.degradation},
      {"context", context},
      {"clean_folder", "clean"},
      {"original_folder", insert ? nlohmann::json("original") : nlohmann::json(nullptr)},
      {"depth", depth_info},
      {"mask",
       {{"rule", "object weight (sum of the object's alpha*transmittance in the with-object render) >= threshold"},
        {"threshold", kMaskWeightThreshold},
        {"max_difference_outside", kMaskWeightThreshold + kEarlyStopSlack}}},
      {"object_fraction", fractions},
      {"object_bounds",
       {{"centre", {scene.object_centre.x(), scene.object_centre.y(), scene.object_centre.z()}},
        {"radius", scene.object_radius}}},
      {"scene", scene.description},
  };
  write_file_atomic(partial / "synth.json", j.dump(1) + "\n");

  spdlog::debug("{}: rendering {:.0f} ms, the rest {:.0f} ms", target.string(), render_ms,
                total_watch.ms() - render_ms);
  check_replaceable(target);
  fs::remove_all(target);
  fs::rename(partial, target);
  partial_guard.done = true;
  return summary;
}

nlohmann::json read_synth_json(const fs::path& scene_dir) {
  const fs::path file = scene_dir / "synth.json";
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(read_file_text(file));
  } catch (const nlohmann::json::exception& e) {
    fail_file(file, "not valid JSON: {}", e.what());
  }
  if (!j.is_object() || j.value("format", "") != "instainpaint-synth")
    fail_file(file, "not a synthetic scene description (format is not instainpaint-synth)");
  return j;
}

}  // namespace ii::synth
