#include "train/sample.h"

#include <algorithm>
#include <cmath>
#include <list>
#include <memory>
#include <numeric>
#include <tuple>
#include <unordered_map>

#include "common/error.h"
#include "data/image_ops.h"
#include "data/photo_points.h"
#include "data/preprocess.h"
#include "tensor/image_tensor.h"

namespace ii {

namespace fs = std::filesystem;

// ---- decoded-image cache ---------------------------------------------------------------

namespace {

// Least-recently-used cache of resized images shared by all sampler threads. Two threads
// may decode the same image at once; both results are identical, the second is dropped.
class ImageCache {
 public:
  std::shared_ptr<const Image> get(const std::string& key, const std::function<Image()>& load) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (auto it = entries_.find(key); it != entries_.end()) {
        order_.splice(order_.begin(), order_, it->second.position);
        return it->second.image;
      }
    }
    auto image = std::make_shared<const Image>(load());
    const size_t bytes = image->pixels.size() * sizeof(float);
    std::lock_guard<std::mutex> lock(mutex_);
    if (bytes > limit_ || entries_.count(key)) return image;
    order_.push_front(key);
    entries_[key] = {image, order_.begin(), bytes};
    used_ += bytes;
    evict();
    return image;
  }

  void set_limit(size_t bytes) {
    std::lock_guard<std::mutex> lock(mutex_);
    limit_ = bytes;
    evict();
  }

 private:
  struct Entry {
    std::shared_ptr<const Image> image;
    std::list<std::string>::iterator position;
    size_t bytes = 0;
  };
  void evict() {
    while (used_ > limit_ && !order_.empty()) {
      auto it = entries_.find(order_.back());
      used_ -= it->second.bytes;
      entries_.erase(it);
      order_.pop_back();
    }
  }

  std::mutex mutex_;
  size_t limit_ = size_t(1) << 30;
  size_t used_ = 0;
  std::list<std::string> order_;  // most recent first
  std::unordered_map<std::string, Entry> entries_;
};

ImageCache& image_cache() {
  static ImageCache cache;
  return cache;
}

}  // namespace

void set_sample_image_cache_limit(size_t bytes) { image_cache().set_limit(bytes); }

// ---- seeds and scene order ---------------------------------------------------------------

namespace {

uint64_t splitmix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

uint64_t mix(uint64_t seed, uint64_t value, uint64_t stream) {
  return splitmix64(splitmix64(seed ^ splitmix64(stream)) ^ value);
}

constexpr uint64_t kSampleStream = 1, kSceneOrderStream = 2;

}  // namespace

uint64_t sample_seed(uint64_t seed, int64_t index) {
  if (index < 0) fail("sample index must be non-negative, got {}", index);
  return mix(seed, static_cast<uint64_t>(index), kSampleStream);
}

size_t scene_for_index(size_t num_scenes, uint64_t seed, int64_t index) {
  if (num_scenes == 0) fail("no training scenes");
  if (index < 0) fail("sample index must be non-negative, got {}", index);
  const uint64_t epoch = static_cast<uint64_t>(index) / num_scenes;
  std::vector<size_t> order(num_scenes);
  std::iota(order.begin(), order.end(), size_t(0));
  MaskRng rng(mix(seed, epoch, kSceneOrderStream));
  random_shuffle(order, rng);
  return order[static_cast<uint64_t>(index) % num_scenes];
}

// ---- one sample -------------------------------------------------------------------------

void check_sampler_options(const SamplerOptions& o) {
  if (o.num_inputs < 1) fail("sampler: num_inputs must be at least 1, got {}", o.num_inputs);
  if (o.num_targets < 1) fail("sampler: num_targets must be at least 1, got {}", o.num_targets);
  if (o.clip_length < o.num_inputs + 1)
    fail("sampler: clip_length {} leaves no supervision frame besides {} inputs", o.clip_length, o.num_inputs);
  if (o.height < 8 || o.width < 8) fail("sampler: working size {}x{} is too small", o.width, o.height);
  for (const auto& [w, h] : o.size_cycle)
    if (h < 8 || w < 8) fail("sampler: working size {}x{} of the size cycle is too small", w, h);
  if (o.step_samples < 1) fail("sampler: step_samples must be at least 1, got {}", o.step_samples);
  if (o.max_mask_count < 1) fail("sampler: max_mask_count must be at least 1, got {}", o.max_mask_count);
  for (double w : o.mask_mix)
    if (!std::isfinite(w) || w < 0)
      fail("sampler: mask_mix weights must be finite and non-negative, got ({}, {}, {})", o.mask_mix[0],
           o.mask_mix[1], o.mask_mix[2]);
  if (o.stage == TrainStage::Inpaint && o.mask_mix[0] + o.mask_mix[1] + o.mask_mix[2] <= 0)
    fail("sampler: mask_mix ({}, {}, {}) sums to zero", o.mask_mix[0], o.mask_mix[1], o.mask_mix[2]);
}

namespace {

std::string scene_name(const Scene& scene) {
  fs::path p = scene.root;
  if (p.filename().empty()) p = p.parent_path();
  return p.filename().string();
}

// Resize that covers the working size (height first, as the official code), then a crop at
// the same relative position in every view of the sample.
// A training view's working size (data/preprocess.h) and its exact camera (scene units).
struct ViewGeometry : WorkingSize {
  Camera camera;
};

ViewGeometry view_geometry(const View& view, const SamplerOptions& o, double crop_fx, double crop_fy) {
  const int W = view.camera.K.width, H = view.camera.K.height;
  if (W <= 0 || H <= 0) fail("view {}: camera has no image size", view.name);
  ViewGeometry g;
  static_cast<WorkingSize&>(g) = covering_size(W, H, o.width, o.height, crop_fx, crop_fy);
  g.camera = g.working_camera(view.camera);
  return g;
}

std::string cache_key(const char* kind, const fs::path& file, int width, int height) {
  return fmt::format("{}|{}|{}x{}", kind, file.string(), width, height);
}

Image photo_at_working_size(const View& view, const ViewGeometry& g, const SamplerOptions& o) {
  const auto resized = image_cache().get(cache_key("rgb", view.image_path, g.resized_width, g.resized_height), [&] {
    Image image = resize_area(load_view_image(view), g.resized_width, g.resized_height);
    // Area filtering of float pixels can step a rounding error past the ends of [0, 1].
    for (float& p : image.pixels) p = std::clamp(p, 0.f, 1.f);
    return image;
  });
  return crop(*resized, g.crop_x, g.crop_y, o.width, o.height);
}

// The view's object mask at the resized size (before the crop), or nullopt.
std::shared_ptr<const Image> resized_object_mask(const View& view, const ViewGeometry& g) {
  if (!view.mask_path && !view.mask_from_alpha) return nullptr;
  const fs::path& source = view.mask_path ? *view.mask_path : view.image_path;
  return image_cache().get(cache_key("mask", source, g.resized_width, g.resized_height), [&] {
    auto mask = load_view_mask(view);
    if (!mask) fail("view {}: object mask could not be read", view.name);
    return resize_nearest(*mask, g.resized_width, g.resized_height);
  });
}

// Object mask dilated once with 5x5 at the resized size (spec §6.3), then cropped.
std::optional<Image> object_mask_at_working_size(const View& view, const ViewGeometry& g, const SamplerOptions& o) {
  const auto resized = resized_object_mask(view, g);
  if (!resized) return std::nullopt;
  return crop(dilate_mask(*resized, 1, 5), g.crop_x, g.crop_y, o.width, o.height);
}

fs::path clean_image_path(const Scene& scene, const View& view) {
  return scene.root / "clean" / view.image_path.filename();
}

Image clean_at_working_size(const Scene& scene, const View& view, const ViewGeometry& g, const SamplerOptions& o) {
  View clean = view;
  clean.image_path = clean_image_path(scene, view);
  if (!fs::exists(clean.image_path))
    fail_file(clean.image_path, "missing: the scene has a clean/ folder, every view needs its object-free image");
  return photo_at_working_size(clean, g, o);
}

Image depth_at_working_size(const Image& depth, const View& view, const ViewGeometry& g, const SamplerOptions& o,
                            const char* source) {
  if (depth.channels != 1 || depth.width != view.camera.K.width || depth.height != view.camera.K.height)
    fail("view {}: {} depth is {}x{}x{}, the image is {}x{} (1 channel expected)", view.name, source, depth.width,
         depth.height, depth.channels, view.camera.K.width, view.camera.K.height);
  return crop(resize_nearest(depth, g.resized_width, g.resized_height), g.crop_x, g.crop_y, o.width, o.height);
}

// A depth map of the scene's `folder` (data/masks.h load_view_depth) at the working size, or
// nullopt when the scene has none for this view.
std::optional<Image> stored_depth_at_working_size(const Scene& scene, const View& view, const std::string& folder,
                                                  const ViewGeometry& g, const SamplerOptions& o) {
  const fs::path file = scene.root / folder / (view.name + ".npy");
  if (!fs::exists(file)) return std::nullopt;
  const auto resized = image_cache().get(cache_key("depth", file, g.resized_width, g.resized_height), [&] {
    return resize_nearest(*load_view_depth(scene, view, folder), g.resized_width, g.resized_height);
  });
  return crop(*resized, g.crop_x, g.crop_y, o.width, o.height);
}

// Reference depth at the working size for 3D-consistent masks, and where it came from.
Image reference_depth(const Scene& scene, const View& view, const ViewGeometry& g, const SamplerOptions& o,
                      const std::vector<Camera>& clip_cameras, const DepthProvider& provider, std::string& source) {
  if (provider)
    if (auto depth = provider(scene, view)) {
      source = "injected";
      return depth_at_working_size(*depth, view, g, o, "injected");
    }
  if (auto depth = stored_depth_at_working_size(scene, view, "depth", g, o)) {
    source = "depth/";
    return *depth;
  }
  source = "plane";
  return Image(o.width, o.height, 1, static_cast<float>(typical_scene_depth(scene, view.camera, clip_cameras)));
}

// Input positions inside a clip of `length` frames: [0, 4, 9, 14] for 4 of 15, evenly
// spread otherwise.
std::vector<int> input_positions(int length, int count) {
  if (count == 1) return {(length - 1) / 2};
  std::vector<int> out;
  for (int k = 0; k < count; ++k) out.push_back(static_cast<int>(static_cast<int64_t>(k) * (length - 1) / (count - 1)));
  return out;
}

// A photo in the network's range [-1, 1], (3, H, W).
torch::Tensor rgb_tensor(const Image& image) { return image_to_tensor(image)[0] * 2.0 - 1.0; }

}  // namespace

TrainingSample make_scene_sample(const Scene& scene, const SamplerOptions& o, uint64_t stream_seed,
                                 const DepthProvider& depth_provider, SampleInfo* info_out) {
  check_sampler_options(o);
  const int num_views = static_cast<int>(scene.views.size());
  if (num_views < o.num_inputs + 1)
    fail("scene {}: {} views, training needs at least {} ({} inputs and one supervision view)", scene.root.string(),
         num_views, o.num_inputs + 1, o.num_inputs);
  MaskRng rng(stream_seed);
  SampleInfo info;
  const bool inpaint = o.stage == TrainStage::Inpaint;

  // Draw order is part of the data format: changing it changes every sample of a seed.
  std::array<double, 3> mix = o.mask_mix;
  if (!scene.has_masks()) mix[0] = 0;  // no object masks: instance share goes to the others
  if (inpaint && mix[0] + mix[1] + mix[2] <= 0)
    fail("scene {}: only instance masks are enabled (mask_mix {}, {}, {}) but the scene has no object masks",
         scene.root.string(), o.mask_mix[0], o.mask_mix[1], o.mask_mix[2]);
  const MaskMode mode = draw_mask_mode(inpaint ? mix : std::array<double, 3>{0, 1, 0}, rng);
  const int mask_count = random_int(rng, 1, o.max_mask_count);
  if (inpaint) {
    info.mask_mode = mode;
    info.mask_count = mask_count;
  }

  const int length = std::min(o.clip_length, num_views);
  const int start = random_int(rng, 0, num_views - length);
  for (int k = 0; k < length; ++k) info.clip.push_back(start + k);

  std::vector<int> positions = input_positions(length, o.num_inputs);
  // Reference among the interior inputs (official: clip frame 4 or 9), moved to the front.
  const int first_interior = o.num_inputs >= 3 ? 1 : 0;
  const int last_interior = o.num_inputs >= 3 ? o.num_inputs - 2 : o.num_inputs - 1;
  const int ref_slot = random_int(rng, first_interior, last_interior);
  std::rotate(positions.begin(), positions.begin() + ref_slot, positions.begin() + ref_slot + 1);

  std::vector<int> candidates;
  for (int p = 0; p < length; ++p)
    if (std::find(positions.begin(), positions.end(), p) == positions.end()) candidates.push_back(p);
  random_shuffle(candidates, rng);
  for (int p : positions) info.inputs.push_back(start + p);
  for (int m = 0; m < o.num_targets; ++m) info.targets.push_back(start + candidates[m % candidates.size()]);

  const double crop_fx = random_unit(rng);
  const double crop_fy = random_unit(rng);

  std::vector<Camera> clip_cameras;
  for (int v : info.clip) clip_cameras.push_back(scene.views[v].camera);
  const PoseNormalization normalization = fit_pose_normalization(clip_cameras);

  std::vector<ViewGeometry> input_geometry;
  for (int v : info.inputs) input_geometry.push_back(view_geometry(scene.views[v], o, crop_fx, crop_fy));
  const ViewGeometry& ref_geometry = input_geometry[0];
  info.resized_width = ref_geometry.resized_width;
  info.resized_height = ref_geometry.resized_height;
  info.crop_x = ref_geometry.crop_x;
  info.crop_y = ref_geometry.crop_y;
  info.clean_reference = inpaint && fs::is_directory(scene.root / "clean");

  // Masks of the inputs (index 0 = reference; its channel is zeroed by build_model_input).
  const int K = o.num_inputs;
  std::vector<Image> masks(K, Image(o.width, o.height, 1));
  if (inpaint) {
    if (mode == MaskMode::Random) {
      const Image shared = rectangles_mask(o.width, o.height, random_rectangles(o.width, o.height, mask_count, rng));
      std::fill(masks.begin(), masks.end(), shared);
    } else if (mode == MaskMode::Instance) {
      for (int k = 0; k < K; ++k)
        masks[k] = *object_mask_at_working_size(scene.views[info.inputs[k]], input_geometry[k], o);
    } else {
      const Image ellipses = ellipses_mask(o.width, o.height, random_ellipses(o.width, o.height, mask_count, rng));
      const View& ref_view = scene.views[info.inputs[0]];
      const Image depth = reference_depth(scene, ref_view, ref_geometry, o, clip_cameras, depth_provider,
                                          info.depth_source);
      std::vector<Camera> cameras;
      for (const ViewGeometry& g : input_geometry) cameras.push_back(g.camera);
      masks = carry_mask_through_depth(ellipses, depth, ref_geometry.camera, cameras, 2);
    }
    if (info.clean_reference)
      for (int k = 1; k < K; ++k)
        if (auto object = object_mask_at_working_size(scene.views[info.inputs[k]], input_geometry[k], o))
          masks[k] = mask_union(masks[k], *object);
  }

  std::vector<PreparedView> prepared;
  for (int k = 0; k < K; ++k) {
    const View& view = scene.views[info.inputs[k]];
    PreparedView pv;
    pv.name = view.name;
    pv.rgb = k == 0 && info.clean_reference ? clean_at_working_size(scene, view, input_geometry[k], o)
                                            : photo_at_working_size(view, input_geometry[k], o);
    pv.mask = std::move(masks[k]);
    pv.camera = input_geometry[k].camera;
    prepared.push_back(std::move(pv));
  }

  TrainingSample sample;
  sample.scene = scene_name(scene);
  sample.input = build_model_input(prepared, normalization);
  // Depth of what each input should show: the object-free scene where the reference and the
  // targets are clean, the photos as they are otherwise. All inputs or none.
  const char* depth_folder = info.clean_reference ? "depth_clean" : "depth";
  std::vector<torch::Tensor> depths;
  for (int k = 0; k < K; ++k) {
    const auto depth = stored_depth_at_working_size(scene, scene.views[info.inputs[k]], depth_folder,
                                                    input_geometry[k], o);
    if (!depth) break;
    depths.push_back(image_to_tensor(*depth)[0]);
  }
  if (static_cast<int>(depths.size()) == K) {
    info.input_depth_folder = depth_folder;
  } else if (o.depth_from_photos) {
    // No depth maps (a real capture): the points triangulated from its photos, sparse. The
    // photos show the object, so only where the reference and the targets do too.
    const auto points = photo_points_of_every_view(scene);
    depths.clear();
    for (int k = 0; k < K && !info.clean_reference; ++k)
      depths.push_back(image_to_tensor(points_depth((*points)[static_cast<size_t>(info.inputs[k])],
                                                    input_geometry[k].camera))[0]);
    if (static_cast<int>(depths.size()) == K) info.input_depth_folder = "photos";
  }
  if (static_cast<int>(depths.size()) == K) {
    sample.input_depths = torch::stack(depths) / normalization.scale;
    sample.input_depths.masked_fill_(~torch::isfinite(sample.input_depths) | (sample.input_depths <= 0), 0);
  }
  std::vector<torch::Tensor> targets;
  for (int v : info.targets) {
    const View& view = scene.views[v];
    const ViewGeometry g = view_geometry(view, o, crop_fx, crop_fy);
    targets.push_back(rgb_tensor(info.clean_reference ? clean_at_working_size(scene, view, g, o)
                                                      : photo_at_working_size(view, g, o)));
    sample.target_cameras.push_back(normalization.apply(g.camera));
  }
  sample.target_images = torch::stack(targets).contiguous();
  if (info_out) *info_out = std::move(info);
  return sample;
}

SamplerOptions options_for_index(const SamplerOptions& options, int64_t index) {
  SamplerOptions o = options;
  if (!o.size_cycle.empty()) {
    const auto turn = static_cast<size_t>(index / std::max(1, o.step_samples)) % o.size_cycle.size();
    std::tie(o.width, o.height) = o.size_cycle[turn];
  }
  return o;
}

TrainingSample make_sample(const std::vector<Scene>& scenes, const SamplerOptions& options, uint64_t seed,
                           int64_t index) {
  const Scene& scene = scenes[scene_for_index(scenes.size(), seed, index)];
  return make_scene_sample(scene, options_for_index(options, index), sample_seed(seed, index));
}

// ---- prefetching stream ------------------------------------------------------------------

SampleStream::SampleStream(std::vector<Scene> scenes, SamplerOptions options, uint64_t seed, int64_t first_index,
                           int rank, int world_size, int workers, int queue_depth)
    : scenes_(std::move(scenes)), options_(options), seed_(seed), queue_depth_(queue_depth) {
  if (scenes_.empty()) fail("sample stream: no training scenes");
  check_sampler_options(options_);
  if (world_size < 1 || rank < 0 || rank >= world_size)
    fail("sample stream: rank {} is outside a world of size {}", rank, world_size);
  if (first_index < 0) fail("sample stream: first index must be non-negative, got {}", first_index);
  if (workers < 0 || queue_depth < 1)
    fail("sample stream: need workers >= 0 and queue_depth >= 1, got {} and {}", workers, queue_depth);
  stride_ = world_size;
  first_owned_ = first_index + ((rank - first_index % world_size) % world_size + world_size) % world_size;
  for (int w = 0; w < workers; ++w) threads_.emplace_back([this] { work(); });
}

SampleStream::~SampleStream() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  space_.notify_all();
  for (std::thread& t : threads_) t.join();
}

void SampleStream::work() {
  for (;;) {
    int64_t position = 0;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      space_.wait(lock, [&] { return stop_ || next_claim_ < next_return_ + queue_depth_; });
      if (stop_) return;
      position = next_claim_++;
    }
    Result result;
    try {
      result.sample = make_sample(scenes_, options_, seed_, index_at(position));
    } catch (...) {
      result.error = std::current_exception();
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_.emplace(position, std::move(result));
    }
    ready_.notify_all();
  }
}

TrainingSample SampleStream::next() {
  Result result;
  if (threads_.empty()) {  // no workers: make the sample here
    std::lock_guard<std::mutex> lock(mutex_);
    const int64_t index = index_at(next_return_++);
    next_claim_ = next_return_;
    return make_sample(scenes_, options_, seed_, index);
  }
  {
    std::unique_lock<std::mutex> lock(mutex_);
    ready_.wait(lock, [&] { return done_.count(next_return_) > 0; });
    auto it = done_.find(next_return_);
    result = std::move(it->second);
    done_.erase(it);
    ++next_return_;
  }
  space_.notify_all();
  // The failed index is consumed: asking again moves on to the next sample.
  if (result.error) std::rethrow_exception(result.error);
  return std::move(*result.sample);
}

int64_t SampleStream::next_index() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return index_at(next_return_);
}

}  // namespace ii
