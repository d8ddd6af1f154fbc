#pragma once
// Training samples (spec §6.1-6.3): from any Scene, a clip of nearby frames;
// inputs at clip positions [0, 4, 9, 14] with the reference (4 or 9) first; 8 supervision
// views from the other clip frames; poses normalised over the clip (translation only);
// resize to cover the working size, then one random crop with exact intrinsics; masks drawn
// instance : random : 3dconsistent = 1 : 2 : 1 on the non-reference inputs (stage 2).
//
// Sample i of a stream is a pure function of (seed, i), so resuming at i reproduces the data.
// Rules beyond the official recipe (which only ever saw 15-frame DL3DV clips):
//  - Scenes with fewer views than the clip length use all their views as the clip; input
//    positions are spread evenly (floor(k (L-1) / (K-1))), the reference is drawn among the
//    interior inputs. When the clip has fewer non-input frames than targets, they repeat.
//  - Instance masks need object masks on every view of the scene; otherwise their share of
//    the mix goes to the other modes.
//  - Synthetic scenes with `<root>/clean/<image file name>` (exact removal ground truth): in
//    stage 2 the reference input and all targets are the clean images and every non-reference
//    input's mask also covers that view's own (dilated) object mask, so the object never shows
//    in an input while the targets lack it. Stage 1 uses the photos as they are.
//  - Scenes with depth maps (synthetic ones) give each input's depth for an optional depth
//    loss: depth_clean/ where the reference and targets are clean, depth/ otherwise; with
//    depth_from_photos, scenes without them give it at points triangulated from their photos.
//  - The reference's mask channel is zero (as inference feeds it; the official training kept
//    the mask there, spec §9.1).
#include <array>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "common/torch.h"

#include "camera/camera.h"
#include "data/masks.h"
#include "data/scene.h"
#include "model/model_input.h"

namespace ii {

enum class TrainStage { Reconstruct, Inpaint };

struct SamplerOptions {
  TrainStage stage = TrainStage::Inpaint;
  int num_inputs = 4, num_targets = 8, clip_length = 15;
  int height = 256, width = 256;           // working size after resize + crop
  std::array<double,3> mask_mix{1, 2, 1};  // instance : random : 3dconsistent
  int max_mask_count = 4;
  // Scenes without depth maps (real captures): each input's depth at points triangulated from the
  // scene's photos (data/photo_points.h; sparse, 0 elsewhere), for the depth loss.
  bool depth_from_photos = false;
  // Working sizes (width, height) taken in turn, one per training step (step_samples consecutive
  // sample indices: the global batch), in place of width x height when not empty: a model run at
  // several sizes is trained at each of them in one run, which training them one after the other
  // did not give (2026-11-27: 200 steps at 256² after 128² lost 2.8 dB at 128²).
  std::vector<std::pair<int, int>> size_cycle;
  int step_samples = 1;
};

// `options` with the working size that sample `index` takes (SamplerOptions::size_cycle).
SamplerOptions options_for_index(const SamplerOptions& options, int64_t index);

struct TrainingSample {
  ModelInput input;                    // num_inputs views, reference first, images (V,4,H,W) in [-1,1] (+ mask)
  torch::Tensor target_images;         // (M, 3, H, W) float32 in [-1,1]
  std::vector<Camera> target_cameras;  // normalised like input.view_cameras, exact intrinsics at H x W
  std::string scene;                   // scene folder name, for logs
  // (V, 1, H, W) float32 z-depth of each input in the normalised camera units, 0 = unknown;
  // undefined when the scene has no depth maps (only synthetic scenes have them) and
  // depth_from_photos is off.
  torch::Tensor input_depths;
};

// Sample i of the stream is a pure function of (seed, i): no hidden RNG state, so resuming at
// index i reproduces the same data. Samples are spread over scenes; a rank of world_size takes
// global indices rank, rank+world_size, ...
TrainingSample make_sample(const std::vector<Scene>& scenes, const SamplerOptions& options, uint64_t seed, int64_t index);

// ---- pieces of make_sample, for tests, tools and custom depth --------------------------

// Which scene global index `index` draws: each run of num_scenes consecutive indices visits
// every scene once, in an order shuffled per run (one "epoch" = one pass over the list).
size_t scene_for_index(size_t num_scenes, uint64_t seed, int64_t index);
// The seed of the random stream of sample `index`.
uint64_t sample_seed(uint64_t seed, int64_t index);

// What a sample drew, in scene.views indices.
struct SampleInfo {
  std::vector<int> clip;     // clip frames, in view order
  std::vector<int> inputs;   // reference first
  std::vector<int> targets;
  std::optional<MaskMode> mask_mode;  // none in stage 1
  int mask_count = 0;
  int resized_width = 0, resized_height = 0;  // before the crop (for the reference view)
  int crop_x = 0, crop_y = 0;
  bool clean_reference = false;  // reference and targets from <root>/clean
  std::string depth_source;      // 3D-consistent masks: "injected", "depth/", "plane"
  std::string input_depth_folder;  // where input_depths came from: "depth", "depth_clean", "photos" or "" (none)
};

// Reference depth for 3D-consistent masks: z-depth in scene units at the view image's own
// size, or nullopt to fall back to the scene's depth/ folder, then to a plane at
// typical_scene_depth (data/masks.h).
using DepthProvider = std::function<std::optional<Image>(const Scene&, const View&)>;

// One sample of one scene from the random stream seeded by `stream_seed`.
TrainingSample make_scene_sample(const Scene& scene, const SamplerOptions& options, uint64_t stream_seed,
                                 const DepthProvider& depth = {}, SampleInfo* info = nullptr);

// Rejects options that cannot make a sample (names the option and the value).
void check_sampler_options(const SamplerOptions& options);

// Decoded, resized images are cached across samples (all threads, least recently used out
// first) up to this many bytes; 0 disables the cache. Default 1 GiB.
void set_sample_image_cache_limit(size_t bytes);

// Background worker threads that prefetch make_sample(...) for the next indices in order.
// Indices are global: this rank returns the indices >= first_index that are congruent to
// rank modulo world_size, ascending. To resume, pass the next_index() of any rank saved at
// the same step (ranks advance together, so rank 0's value works for every rank).
class SampleStream {
 public:
  SampleStream(std::vector<Scene> scenes, SamplerOptions options, uint64_t seed, int64_t first_index,
               int rank = 0, int world_size = 1, int workers = 2, int queue_depth = 4);
  ~SampleStream();                 // stops and joins the workers
  SampleStream(const SampleStream&) = delete;
  SampleStream& operator=(const SampleStream&) = delete;
  TrainingSample next();           // blocks until the next sample in order is ready; rethrows worker errors
  int64_t next_index() const;      // the index next() will return (save it in checkpoints)

 private:
  struct Result {
    std::optional<TrainingSample> sample;
    std::exception_ptr error;
  };
  void work();
  int64_t index_at(int64_t position) const { return first_owned_ + position * stride_; }

  const std::vector<Scene> scenes_;
  const SamplerOptions options_;
  const uint64_t seed_;
  int64_t first_owned_ = 0, stride_ = 1;
  int queue_depth_ = 4;
  mutable std::mutex mutex_;
  std::condition_variable ready_, space_;
  int64_t next_claim_ = 0, next_return_ = 0;  // positions in this rank's sequence
  std::map<int64_t, Result> done_;
  bool stop_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace ii
