#pragma once
// One optimisation step of the InstaInpaint recipe (spec §6.4-6.5) and the training state
// around it:
//   network forward on a batch (optionally bf16, optionally recomputing transformer blocks
//   in the backward pass) → per-pixel Gaussian maps, detached into leaf tensors → for each
//   sample and each target camera: render, map C to clamp(2C − 1, −1, 1), loss / (B·M),
//   backward into the leaves (plus, optionally, a depth loss on the inputs' depth / B) →
//   one backward through the network → gradients averaged over processes → per-tensor
//   clipping → AdamW with the warm-up + cosine learning rate.
// The checkpoint holds the trainable tensors under official names (so every model loader
// reads it), the AdamW moments, the step, the RNG state and caller-provided state such as
// the data sampler position; resuming from it reproduces the uninterrupted run exactly.
#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

#include <nlohmann/json.hpp>
#include "common/torch.h"

#include "io/safetensors.h"
#include "model/network.h"
#include "train/losses.h"
#include "train/optimizer.h"
#include "train/parameters.h"
#include "train/sample.h"
#include "train/schedule.h"

namespace ii {

class ProcessGroup;

struct TrainerOptions {
  LrSchedule schedule;
  AdamWOptions adamw;
  double clip_norm = 1.0;  // per tensor
  LossOptions loss;
  Precision precision = Precision::Float32;  // network forward; rendering and losses stay fp32
  bool checkpoint_blocks = false;            // recompute transformer blocks in backward
  torch::Device device = torch::kCPU;
};

struct StepStats {
  int64_t step = 0;  // the step just taken (1-based count of completed steps)
  double loss = 0, mse = 0, perceptual = 0;  // means over all targets of all processes
  double depth = 0;  // depth_loss, mean over the samples with depth maps (0: none); its weighted
                     // mean over all samples is part of `loss`
  double own_view = 0;  // own-view MSE, mean over the input views (0 when its weight is 0); its
                        // weighted mean is part of `loss`
  double lr = 0;
  double grad_norm = 0;  // global norm after zeroing non-finite values, before clipping
  int clipped_tensors = 0, nonfinite_tensors = 0;
  int samples = 0;  // over all processes
  double ms = 0;    // wall time of the step on this process, made of:
  double forward_ms = 0, render_ms = 0, backward_ms = 0;  // network forward; renders + losses + their
                                                           // backward; network backward
  double update_ms = 0;  // gradient allreduce, clipping, AdamW
};

struct EvalStats {
  double loss = 0, mse = 0, perceptual = 0;  // image terms (no depth term)
  std::optional<double> depth;  // depth_loss of the inputs when the sample has depth maps
  double own_psnr = 0;  // each input's own Gaussians at its camera against its image outside its
                        // mask (eval's "own views"), mean over the inputs
  double psnr = 0;  // mean over targets, images mapped to [0, 1]
  int targets = 0;
};

class Trainer {
 public:
  // Trains `network` (its weights are the starting point). `group` is null for one process;
  // with a group, rank 0's starting weights are broadcast to every process.
  Trainer(Network network, TrainerOptions options, std::shared_ptr<ProcessGroup> group = nullptr);
  ~Trainer();

  // One optimisation step on this process's share of the batch: compute_gradients, then
  // the average over processes, clipping and the AdamW update.
  StepStats step(const std::vector<TrainingSample>& batch);
  // The loss gradients of this process's batch alone, left in parameters().tensors()[i].grad()
  // (no averaging, clipping or update). Fills the loss fields of the result.
  StepStats compute_gradients(const std::vector<TrainingSample>& batch);

  // Loss and PSNR of one sample without gradients; `renders`, when given, receives the
  // target renders (M, 3, H, W) in [−1, 1] on the CPU.
  EvalStats evaluate(const TrainingSample& sample, torch::Tensor* renders = nullptr);

  int64_t steps_done() const { return optimizer_->steps(); }
  const TrainerOptions& options() const { return options_; }
  const ImageLoss& loss() const { return loss_; }
  const TrainableParameters& parameters() const { return params_; }
  // The network holding the current weights (folded, no autograd history).
  const Network& network();

  // Continues in a model file's own weight-norm split (see TrainableParameters); returns the
  // number of layers taken. Call before the first step.
  int load_weight_norm(const StateDict& pairs, const std::string& source);

  // Training checkpoint (atomic). `state` is stored as given and returned by load().
  void save(const std::filesystem::path& path, const nlohmann::json& state = {}) const;
  nlohmann::json load(const std::filesystem::path& path);
  // The same from a file already read (`path` names it in messages).
  nlohmann::json load(const SafetensorsFile& file, const std::filesystem::path& path);
  // The model alone, official key names with weight_g / weight_v (atomic).
  void export_model(const std::filesystem::path& path, const nlohmann::json& metadata = {}) const;

 private:
  struct Batch;
  Batch collate(const std::vector<TrainingSample>& samples) const;
  void sync_network();

  Network network_;
  TrainerOptions options_;
  std::shared_ptr<ProcessGroup> group_;
  TrainableParameters params_;
  std::unique_ptr<AdamW> optimizer_;
  ImageLoss loss_;
  bool network_current_ = false;
};

// The training-state format tag stored in checkpoint metadata ("format").
constexpr const char* kTrainingStateFormat = "instainpaint-training-state";

// The model architecture a training checkpoint was written for; Error when `file` is not a
// training checkpoint.
ModelConfig training_checkpoint_config(const SafetensorsFile& file, const std::filesystem::path& path);

}  // namespace ii
