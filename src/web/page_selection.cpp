#include "web/page_selection.h"

#include <algorithm>

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "common/stopwatch.h"
#include "edit/box_select.h"
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

PageSelection::~PageSelection() {
  stopping_ = true;
  if (encoder_.joinable()) encoder_.join();
}

void PageSelection::set_segmenter(std::shared_ptr<const Segmenter> segmenter) {
  std::lock_guard<std::mutex> lock(mutex_);
  segmenter_ = std::move(segmenter);
  encoded_.reset();
  encoded_key_.clear();
  view_encodings_.clear();
}

std::shared_ptr<const SegmenterImage> PageSelection::view_encoding(const View& view, double& encode_ms) {
  Stopwatch watch;
  const std::string key = "view " + view.name;
  std::promise<std::shared_ptr<const SegmenterImage>> made;
  Encoding pending;  // made or being made by another thread
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto found = view_encodings_.find(key);
    if (found != view_encodings_.end())
      pending = found->second;
    else
      view_encodings_.emplace(key, made.get_future().share());
  }
  if (pending.valid()) {  // the time waited for it: none when it was ready
    const bool ready = pending.wait_for(std::chrono::seconds(0)) == std::future_status::ready;
    std::shared_ptr<const SegmenterImage> e = pending.get();
    encode_ms = ready ? 0 : watch.ms();
    return e;
  }
  try {
    auto e = std::make_shared<const SegmenterImage>(segmenter_->encode(load_view_image(view)));
    made.set_value(e);
    encode_ms = watch.ms();
    return e;
  } catch (...) {
    made.set_exception(std::current_exception());
    std::lock_guard<std::mutex> lock(mutex_);
    view_encodings_.erase(key);  // a later click tries again
    throw;
  }
}

void PageSelection::encode_views_behind(std::vector<View> views, std::function<bool()> busy, ComputeThread& compute) {
  if (!segmenter_ || encoder_.joinable()) return;
  encoder_ = std::thread([this, views = std::move(views), busy = std::move(busy), &compute] {
    Stopwatch watch;
    int encoded = 0;
    for (const View& view : views) {
      while (!stopping_ && busy()) std::this_thread::sleep_for(std::chrono::milliseconds(50));
      if (stopping_) return;
      try {
        compute.run([&] {
          double ms = 0;
          view_encoding(view, ms);
        });
        ++encoded;
      } catch (const std::exception& e) {
        spdlog::warn("segmenter: view {} was not encoded behind the page: {}", view.name, e.what());
      }
    }
    spdlog::info("segmenter: {} views' photos encoded behind the page in {:.1f} s", encoded, watch.ms() / 1000);
  });
}

int PageSelection::views_encoded() const {
  std::lock_guard<std::mutex> lock(mutex_);
  int ready = 0;
  for (const auto& [key, encoding] : view_encodings_)
    ready += encoding.wait_for(std::chrono::seconds(0)) == std::future_status::ready;
  return ready;
}

std::shared_ptr<const SegmenterImage> PageSelection::encoding(const std::string& key, const std::function<Image()>& make,
                                                              double& encode_ms) {
  encode_ms = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (encoded_ && encoded_key_ == key) return encoded_;
  }
  Stopwatch watch;
  auto encoded = std::make_shared<const SegmenterImage>(segmenter_->encode(make()));
  encode_ms = watch.ms();
  std::lock_guard<std::mutex> lock(mutex_);
  encoded_ = encoded;
  encoded_key_ = key;
  return encoded;
}

namespace {

// What identifies the page's view of the splats: the file and every number of the camera.
std::string view_key(const std::filesystem::path& ply, const Camera& camera) {
  std::string key = ply.string();
  for (const double v : {camera.K.fx, camera.K.fy, camera.K.cx, camera.K.cy}) key += fmt::format(",{}", v);
  key += fmt::format(",{}x{}", camera.K.width, camera.K.height);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) key += fmt::format(",{}", camera.c2w(r, c));
  return key;
}

}  // namespace

json PageSelection::select_splats(const std::filesystem::path& ply, const Camera& camera,
                                  const std::vector<Click>& clicks, const std::vector<Click>& not_clicks) {
  Stopwatch watch;
  const std::shared_ptr<const SplatCloud> cloud = splats(ply);
  const double read_ms = watch.lap();
  if (segmenter_) {
    check_clicks_inside(camera, "the page's view", clicks, not_clicks);
    double encode_ms = 0;
    const auto encoded = encoding(view_key(ply, camera), [&] { return splats_seen(*cloud, camera); }, encode_ms);
    watch.lap();
    const ClickedMask clicked = mask_from_clicks(*segmenter_, *encoded, clicks, not_clicks);
    const double decode_ms = watch.lap();
    const RegionMask region = region_under_stroke(*cloud, camera, clicked.mask);
    json answer = selection_answer(region_count(region), static_cast<int64_t>(cloud->size()), clicked.mask);
    answer["how"] = "segmenter";
    answer["scores"] = clicked.scores;
    answer["ms"] = {{"read", read_ms}, {"encode", encode_ms}, {"decode", decode_ms}, {"select", watch.lap()}};
    return answer;
  }
  if (!not_clicks.empty()) fail("points that are not the object need serve --segmenter");
  const RegionMask region = region_from_clicks(*cloud, camera, "the page's view", clicks);
  const double select_ms = watch.lap();
  std::vector<Eigen::Vector3d> points;
  for (size_t i = 0; i < region.size(); ++i)
    if (region[i]) points.emplace_back(cloud->means[3 * i], cloud->means[3 * i + 1], cloud->means[3 * i + 2]);
  const int side = std::max(camera.K.width, camera.K.height);
  const Image mask = selection_mask(camera, points, std::vector<uint8_t>(points.size(), 1), std::max(1, side / 300), 0);
  json answer = selection_answer(static_cast<int64_t>(points.size()), static_cast<int64_t>(cloud->size()), mask);
  answer["how"] = "colour growth";
  answer["ms"] = {{"read", read_ms}, {"select", select_ms}, {"draw", watch.lap()}};
  return answer;
}

void PageSelection::set_reconstruction(const GaussianSet& reconstruction) {
  std::lock_guard<std::mutex> lock(mutex_);
  reconstruction_ = reconstruction;
  points_.reset();
}

std::optional<json> PageSelection::select_on_view(const View& view, const Camera& camera,
                                                  const std::vector<Click>& clicks, const std::vector<Click>& not_clicks,
                                                  std::optional<double> scene_far, const std::optional<ViewBox>& box) {
  Stopwatch watch;
  if (box && !segmenter_) {
    // GrabCut in the box on the view's photo, as `masks --box` makes the region.
    check_clicks_inside(view.camera, view.name, clicks, not_clicks);
    const Image mask = object_in_box(load_view_image(view), view.name, *box, clicks, not_clicks);
    json answer = selection_answer(std::count(mask.pixels.begin(), mask.pixels.end(), 1.f),
                                   static_cast<int64_t>(mask.pixels.size()), mask);
    answer["how"] = "GrabCut in the box";
    answer["ms"] = {{"grabcut", watch.lap()}};
    return answer;
  }
  if (segmenter_) {
    check_clicks_inside(view.camera, view.name, clicks, not_clicks);
    double encode_ms = 0;
    const auto encoded = view_encoding(view, encode_ms);
    watch.lap();
    const ClickedMask clicked = mask_from_prompt(*segmenter_, *encoded, clicks, not_clicks, box);
    json answer = selection_answer(clicked.pixels, static_cast<int64_t>(clicked.mask.pixels.size()), clicked.mask);
    answer["how"] = "segmenter";
    answer["scores"] = clicked.scores;
    answer["ms"] = {{"encode", encode_ms}, {"decode", watch.lap()}};
    return answer;
  }
  if (!not_clicks.empty()) fail("points that are not the object need a box around it, or serve --segmenter");
  std::shared_ptr<const ColouredPoints> points;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!points_) {
      if (!reconstruction_) return std::nullopt;
      points_ = std::make_shared<const ColouredPoints>(opaque_points(*reconstruction_));
    }
    points = points_;
  }
  // The selection's image carved to the object by the view's photo: what `masks --click` makes of
  // the same click (edit/scene_masks.h's outline_of_clicks in the same reconstruction).
  const ClickedOutline outline = outline_of_clicks(view, camera, *points, clicks, scene_far);
  json answer = selection_answer(std::count(outline.selected.begin(), outline.selected.end(), uint8_t{1}),
                                 static_cast<int64_t>(outline.selected.size()), outline.mask);
  answer["how"] = "colour growth";
  answer["ms"] = {{"select and carve", watch.lap()}};
  return answer;
}

}  // namespace ii
