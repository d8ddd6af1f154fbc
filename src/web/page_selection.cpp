#include "web/page_selection.h"

#include <algorithm>

#include "common/stopwatch.h"
#include "edit/scene_masks.h"
#include "fill/region.h"
#include "io/image.h"
#include "io/splat_file.h"

namespace ii {

using json = nlohmann::json;

namespace {

// A mask as the page draws it: runs of its pixels, row by row, alternately outside and inside.
json mask_runs(const Image& mask) {
  json runs = json::array();
  bool inside = false;
  int64_t run = 0;
  for (const float v : mask.pixels) {
    if ((v > 0.5f) != inside) runs.push_back(run), run = 0, inside = !inside;
    ++run;
  }
  runs.push_back(run);
  return runs;
}

int64_t mask_pixels(const Image& mask) {
  return std::count_if(mask.pixels.begin(), mask.pixels.end(), [](float v) { return v > 0.5f; });
}

// The answer's count and the mask as the page draws it.
json selection_answer(int64_t selected, int64_t total, const Image& mask) {
  return {{"selected", selected}, {"total", total},       {"pixels", mask_pixels(mask)},
          {"width", mask.width},  {"height", mask.height}, {"runs", mask_runs(mask)}};
}

}  // namespace

std::shared_ptr<const SplatCloud> PageSelection::splats(const std::filesystem::path& ply) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (splats_file_ != ply || !splats_) {
    splats_ = std::make_shared<const SplatCloud>(read_splats(ply));
    splats_file_ = ply;
  }
  return splats_;
}

json PageSelection::select_splats(const std::filesystem::path& ply, const Camera& camera,
                                  const std::vector<Click>& clicks) {
  Stopwatch watch;
  const std::shared_ptr<const SplatCloud> cloud = splats(ply);
  const double read_ms = watch.lap();
  const RegionMask region = region_from_clicks(*cloud, camera, "the page's view", clicks);
  const double select_ms = watch.lap();
  std::vector<Eigen::Vector3d> points;
  for (size_t i = 0; i < region.size(); ++i)
    if (region[i]) points.emplace_back(cloud->means[3 * i], cloud->means[3 * i + 1], cloud->means[3 * i + 2]);
  const int side = std::max(camera.K.width, camera.K.height);
  const Image mask = selection_mask(camera, points, std::vector<uint8_t>(points.size(), 1), std::max(1, side / 300), 0);
  json answer = selection_answer(static_cast<int64_t>(points.size()), static_cast<int64_t>(cloud->size()), mask);
  answer["ms"] = {{"read", read_ms}, {"select", select_ms}, {"draw", watch.lap()}};
  return answer;
}

void PageSelection::set_reconstruction(const GaussianSet& reconstruction) {
  std::lock_guard<std::mutex> lock(mutex_);
  reconstruction_ = reconstruction;
  points_.reset();
}

std::optional<json> PageSelection::select_on_view(const View& view, const Camera& camera,
                                                  const std::vector<Click>& clicks) {
  Stopwatch watch;
  std::shared_ptr<const ColouredPoints> points;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!points_) {
      if (!reconstruction_) return std::nullopt;
      const torch::Tensor opaque = reconstruction_->opacities.reshape({-1}).gt(0.5).nonzero().squeeze(1);
      points_ = std::make_shared<const ColouredPoints>(coloured_points(*reconstruction_, opaque));
    }
    points = points_;
  }
  const std::vector<uint8_t> selected = select_objects(camera, view.name, points->points, points->colours, clicks);
  const double select_ms = watch.lap();
  // The selection's image carved to the object by the view's photo, as `masks --click` does.
  const Image mask =
      selection_masks({camera}, [&](size_t) { return load_view_image(view); }, points->points, selected)[0].mask;
  json answer = selection_answer(std::count(selected.begin(), selected.end(), uint8_t{1}),
                                 static_cast<int64_t>(selected.size()), mask);
  answer["ms"] = {{"select", select_ms}, {"carve", watch.lap()}};
  return answer;
}

}  // namespace ii
