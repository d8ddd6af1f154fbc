#include "train/trainer.h"

#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "common/error.h"
#include "common/stopwatch.h"
#include "eval/metrics.h"
#include "io/safetensors.h"
#include "tensor/tensor_file.h"
#include "gaussians/gaussians.h"
#include "render/rasterizer.h"
#include "train/distributed.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

// Checkpoint names of the non-model tensors (model keys keep their official names).
constexpr std::string_view kExpAvg = "optimizer.exp_avg.", kExpAvgSq = "optimizer.exp_avg_sq.",
                           kRng = "rng.cpu_generator";

// The official renderer's output mapping (spec §4.3): (H, W, 3) colour C -> (1, 3, H, W)
// clamp(2C − 1, −1, 1).
torch::Tensor to_signed_image(const torch::Tensor& rgb) {
  return (rgb * 2.0 - 1.0).clamp(-1.0, 1.0).permute({2, 0, 1}).unsqueeze(0);
}

// Input view v's own Gaussians (of one sample's maps) rendered at its own camera: the MSE against
// its image outside its mask, in [-1, 1] (eval's "own views" check, as a loss).
torch::Tensor own_view_mse(const GaussianMaps& m, const TrainingSample& s, int64_t v, const torch::Device& device) {
  const RenderOutput r =
      render(gaussians_from_maps(narrowed(m, 1, v)), RenderCamera{s.input.view_cameras[static_cast<size_t>(v)]});
  const torch::Tensor image = s.input.images[v].to(device);  // RGB (0 inside the mask), then the mask
  const torch::Tensor outside = (image[3] <= 0.5).to(torch::kFloat32);
  const torch::Tensor error = (to_signed_image(r.rgb)[0] - image.narrow(0, 0, 3)).pow(2) * outside;
  return error.sum() / (3.0 * outside.sum().clamp_min(1));
}

// PSNR in dB of an MSE measured in [-1, 1] (images mapped to [0, 1]).
double psnr_of_signed_mse(double mse) { return -10.0 * std::log10(std::max(mse / 4.0, 1e-10)); }

Network& moved_to(Network& network, const torch::Device& device) {
  network.to(device);
  return network;
}

}  // namespace

struct Trainer::Batch {
  torch::Tensor images, plucker, rays_o, rays_d_un;  // (B, V, ...)
};

Trainer::Trainer(Network network, TrainerOptions options, std::shared_ptr<ProcessGroup> group)
    : network_(std::move(network)),
      options_(std::move(options)),
      group_(std::move(group)),
      params_(moved_to(network_, options_.device)),
      loss_(options_.loss) {
  options_.schedule.validate();
  if (options_.device.is_cuda() && !render_has_cuda())
    fail("training on {} needs the CUDA rasterizer kernels, which this build does not have", options_.device.str());
  network_.set_activation_checkpointing(options_.checkpoint_blocks);
  loss_.to(options_.device);
  if (group_) group_->broadcast(params_.tensors(), 0, "the broadcast of the initial weights");
  std::vector<bool> decay;
  for (size_t i = 0; i < params_.names().size(); ++i)
    decay.push_back(official_decays(params_.names()[i], params_.tensors()[i]));
  optimizer_ = std::make_unique<AdamW>(params_.tensors(), decay, options_.adamw);
}

Trainer::~Trainer() = default;

Trainer::Batch Trainer::collate(const std::vector<TrainingSample>& samples) const {
  if (samples.empty()) fail("training step: empty batch");
  const int64_t channels = network_.config().image_channels;
  std::vector<torch::Tensor> images, plucker, rays_o, rays_d_un;
  for (const TrainingSample& s : samples) {
    const torch::Tensor& im = s.input.images;
    if (im.dim() != 4 || im.size(1) < channels)
      fail("training sample from {}: images [{}] do not have the model's {} channels", s.scene,
           fmt::join(im.sizes(), ", "), channels);
    if (s.target_images.size(0) != static_cast<int64_t>(s.target_cameras.size()) || s.target_cameras.empty())
      fail("training sample from {}: {} target images for {} cameras", s.scene, s.target_images.size(0),
           s.target_cameras.size());
    // A 3-channel (stage-1) model reads RGB only.
    images.push_back(im.narrow(1, 0, channels));
    plucker.push_back(s.input.plucker);
    rays_o.push_back(s.input.rays_o);
    rays_d_un.push_back(s.input.rays_d_un);
  }
  const torch::Device d = options_.device;
  try {
    return {torch::stack(images).to(d), torch::stack(plucker).to(d), torch::stack(rays_o).to(d),
            torch::stack(rays_d_un).to(d)};
  } catch (const c10::Error&) {
    fail("training batch: samples have different numbers of views or image sizes");
  }
}

void Trainer::sync_network() {
  if (network_current_) return;
  torch::NoGradGuard no_grad;
  params_.bind(network_);
  network_current_ = true;
}

const Network& Trainer::network() {
  sync_network();
  return network_;
}

StepStats Trainer::step(const std::vector<TrainingSample>& batch) {
  Stopwatch watch;
  StepStats stats = compute_gradients(batch);
  Stopwatch update_clock;
  if (group_) {
    // DDP semantics: each process's loss is the mean over its own targets; averaging the
    // gradients gives the mean over the global batch.
    std::vector<torch::Tensor> grads;
    for (const torch::Tensor& p : params_.tensors())
      if (p.grad().defined()) grads.push_back(p.grad());
    group_->allreduce_mean(grads, "the gradient allreduce");
    const torch::Tensor terms =
        torch::tensor({stats.loss, stats.mse, stats.perceptual, double(stats.samples), stats.depth, stats.own_view},
                      torch::TensorOptions().dtype(torch::kFloat64).device(options_.device));
    group_->allreduce_mean({terms}, "the loss allreduce");
    const torch::Tensor t = terms.cpu();
    stats.loss = t[0].item<double>();
    stats.mse = t[1].item<double>();
    stats.perceptual = t[2].item<double>();
    stats.samples = static_cast<int>(std::lround(t[3].item<double>() * group_->world_size()));
    stats.depth = t[4].item<double>();
    stats.own_view = t[5].item<double>();
  }
  const ClipStats clip = clip_gradients_per_tensor(params_.tensors(), options_.clip_norm);
  stats.lr = options_.schedule.at(optimizer_->steps());
  optimizer_->step(stats.lr);
  stats.step = optimizer_->steps();
  stats.grad_norm = clip.norm;
  stats.clipped_tensors = clip.clipped_tensors;
  stats.nonfinite_tensors = clip.nonfinite_tensors;
  stats.update_ms = update_clock.ms();
  stats.ms = watch.ms();
  return stats;
}

StepStats Trainer::compute_gradients(const std::vector<TrainingSample>& batch) {
  const Batch in = collate(batch);
  optimizer_->zero_grad();
  params_.bind(network_);  // with autograd history back to the trainable tensors
  network_current_ = false;

  // The logged terms are summed where they are computed and read once at the end: reading each
  // view's would make the CPU wait for the GPU before it could queue the next view's render.
  torch::Tensor sums = torch::zeros({5}, torch::TensorOptions().dtype(torch::kFloat64).device(options_.device));
  enum { kLoss, kMse, kPerceptual, kDepth, kOwnView };
  int64_t targets = 0, depth_samples = 0, own_views = 0;
  Stopwatch clock;
  double forward_ms = 0, render_ms = 0;
  for (const TrainingSample& s : batch) targets += static_cast<int64_t>(s.target_cameras.size());
  {
    const NetworkOutput out = network_.forward(in.images, in.plucker, in.rays_o, in.rays_d_un, options_.precision);
    const GaussianMaps& maps = out.gaussians;
    forward_ms = clock.lap();
    // Spec §6.4 memory saving: renders back-propagate one at a time into detached copies of
    // the maps; the network's backward then runs once with the accumulated gradients.
    std::vector<torch::Tensor> roots{maps.xyz, maps.rgb, maps.opacity, maps.scale, maps.rotation};
    // xyz is made from depth, so a depth loss enters through a sixth leaf of its own.
    const double depth_weight = options_.loss.depth_weight;
    const bool supervise_depth =
        depth_weight > 0 &&
        std::any_of(batch.begin(), batch.end(), [](const TrainingSample& s) { return s.input_depths.defined(); });
    if (supervise_depth) roots.push_back(maps.depth);
    std::vector<torch::Tensor> leaves;
    for (const torch::Tensor& r : roots) leaves.push_back(r.detach().requires_grad_(true));
    GaussianMaps detached;
    detached.xyz = leaves[0];
    detached.rgb = leaves[1];
    detached.opacity = leaves[2];
    detached.scale = leaves[3];
    detached.rotation = leaves[4];
    if (supervise_depth) detached.depth = leaves[5];

    const double weight = 1.0 / static_cast<double>(targets);
    for (size_t b = 0; b < batch.size(); ++b) {
      const TrainingSample& s = batch[b];
      if (supervise_depth && s.input_depths.defined()) {
        const torch::Tensor d = depth_loss(detached.depth[static_cast<int64_t>(b)], s.input_depths.to(options_.device));
        (d * (depth_weight / static_cast<double>(batch.size()))).backward();
        sums[kDepth] += d.detach().to(torch::kFloat64);
        ++depth_samples;
      }
      const GaussianMaps per_sample = narrowed(detached, 0, static_cast<int64_t>(b));
      const GaussianSet set = gaussians_from_maps(per_sample);
      const torch::Tensor target_images = s.target_images.to(options_.device);
      for (size_t m = 0; m < s.target_cameras.size(); ++m) {
        const RenderOutput r = render(set, RenderCamera{s.target_cameras[m]});
        const LossTerms t = loss_(to_signed_image(r.rgb), target_images[static_cast<int64_t>(m)].unsqueeze(0));
        (t.total * weight).backward();
        sums.narrow(0, kLoss, 3) += torch::stack({t.total, t.mse, t.perceptual}).detach().to(torch::kFloat64);
      }
      const double own_weight = options_.loss.own_view_weight;
      if (own_weight > 0) {
        const int64_t views = per_sample.xyz.size(1);
        for (int64_t v = 0; v < views; ++v) {
          const torch::Tensor e = own_view_mse(per_sample, s, v, options_.device);
          (e * (own_weight / static_cast<double>(views * static_cast<int64_t>(batch.size())))).backward();
          sums[kOwnView] += e.detach().to(torch::kFloat64);
          ++own_views;
        }
      }
    }
    std::vector<torch::Tensor> grads;
    for (const torch::Tensor& l : leaves) grads.push_back(l.grad().defined() ? l.grad() : torch::zeros_like(l));
    render_ms = clock.lap();
    torch::autograd::backward(roots, grads);
  }

  const torch::Tensor read = sums.cpu();
  const double* sum = read.data_ptr<double>();
  const double loss_sum = sum[kLoss], mse_sum = sum[kMse], perceptual_sum = sum[kPerceptual], depth_sum = sum[kDepth],
               own_sum = sum[kOwnView];
  StepStats stats;
  stats.mse = mse_sum / targets;
  stats.perceptual = perceptual_sum / targets;
  stats.depth = depth_samples > 0 ? depth_sum / depth_samples : 0.0;
  stats.own_view = own_views > 0 ? own_sum / static_cast<double>(own_views) : 0.0;
  stats.loss = loss_sum / targets + options_.loss.depth_weight * depth_sum / static_cast<double>(batch.size()) +
               options_.loss.own_view_weight * stats.own_view;
  stats.samples = static_cast<int>(batch.size());
  stats.step = optimizer_->steps();
  stats.forward_ms = forward_ms;
  stats.render_ms = render_ms;
  stats.backward_ms = clock.lap();
  return stats;
}

EvalStats Trainer::evaluate(const TrainingSample& sample, torch::Tensor* renders) {
  sync_network();
  torch::NoGradGuard no_grad;
  const Batch in = collate({sample});
  const NetworkOutput out = network_.forward(in.images, in.plucker, in.rays_o, in.rays_d_un, options_.precision);
  const GaussianMaps& maps = out.gaussians;
  const GaussianSet set = gaussians_from_maps(maps);
  const torch::Tensor targets = sample.target_images.to(options_.device);
  EvalStats stats;
  const int64_t views = maps.xyz.size(1);
  for (int64_t v = 0; v < views; ++v)
    stats.own_psnr += psnr_of_signed_mse(own_view_mse(maps, sample, v, options_.device).item<double>()) / views;
  if (sample.input_depths.defined())
    stats.depth = depth_loss(out.gaussians.depth[0], sample.input_depths.to(options_.device)).item<double>();
  std::vector<torch::Tensor> images;
  for (size_t m = 0; m < sample.target_cameras.size(); ++m) {
    const torch::Tensor pred = to_signed_image(render(set, RenderCamera{sample.target_cameras[m]}).rgb);
    const torch::Tensor target = targets[static_cast<int64_t>(m)].unsqueeze(0);
    const LossTerms t = loss_(pred, target);
    stats.loss += t.total.item<double>();
    stats.mse += t.mse.item<double>();
    stats.perceptual += t.perceptual.item<double>();
    stats.psnr += psnr((pred + 1) * 0.5, (target + 1) * 0.5).item<double>();
    if (renders) images.push_back(pred[0].cpu());
  }
  stats.targets = static_cast<int>(sample.target_cameras.size());
  for (double* v : {&stats.loss, &stats.mse, &stats.perceptual, &stats.psnr}) *v /= stats.targets;
  if (renders) *renders = torch::stack(images);
  return stats;
}

int Trainer::load_weight_norm(const StateDict& pairs, const std::string& source) {
  network_current_ = false;
  return params_.load_weight_norm(pairs, source);
}

void Trainer::save(const fs::path& path, const nlohmann::json& state) const {
  std::vector<std::pair<std::string, torch::Tensor>> tensors;
  const auto& names = params_.names();
  for (size_t i = 0; i < names.size(); ++i) tensors.emplace_back(names[i], params_.tensors()[i]);
  for (size_t i = 0; i < names.size(); ++i) tensors.emplace_back(std::string(kExpAvg) + names[i], optimizer_->exp_avg()[i]);
  for (size_t i = 0; i < names.size(); ++i) tensors.emplace_back(std::string(kExpAvgSq) + names[i], optimizer_->exp_avg_sq()[i]);
  {
    at::Generator generator = at::detail::getDefaultCPUGenerator();
    std::lock_guard<std::mutex> lock(generator.mutex());
    tensors.emplace_back(std::string(kRng), generator.get_state());
  }
  const nlohmann::json training = {{"step", optimizer_->steps()},
                                   {"perceptual", loss_.perceptual_name()},
                                   {"state", state}};
  write_tensor_file(path, tensors,
                    {{"format", kTrainingStateFormat},
                     {"config", network_.config().to_json().dump()},
                     {"training", training.dump()}});
}

namespace {

// The metadata entry `key` of a training checkpoint, with the errors that say what the file is.
const std::string& training_metadata(const SafetensorsFile& file, const fs::path& path, const std::string& key) {
  auto it = file.metadata.find(key);
  if (it == file.metadata.end())
    fail_file(path, "is not a training checkpoint (no '{}' in its metadata); to start from a model's weights use --init",
              key);
  return it->second;
}

nlohmann::json parse_metadata(const SafetensorsFile& file, const fs::path& path, const std::string& key) {
  const std::string& format = training_metadata(file, path, "format");
  if (format != kTrainingStateFormat)
    fail_file(path, "is not a training checkpoint (format '{}'); to start from a model's weights use --init", format);
  try {
    return nlohmann::json::parse(training_metadata(file, path, key));
  } catch (const nlohmann::json::exception& e) {
    fail_file(path, "damaged metadata '{}': {}", key, e.what());
  }
}

}  // namespace

ModelConfig training_checkpoint_config(const SafetensorsFile& file, const fs::path& path) {
  return ModelConfig::from_json(parse_metadata(file, path, "config"));
}

nlohmann::json Trainer::load(const fs::path& path) { return load(read_safetensors(path), path); }

nlohmann::json Trainer::load(const SafetensorsFile& file, const fs::path& path) {
  const nlohmann::json config = parse_metadata(file, path, "config");
  const nlohmann::json training = parse_metadata(file, path, "training");
  const nlohmann::json ours = network_.config().to_json();
  nlohmann::json theirs = ModelConfig::from_json(config).to_json();
  theirs["preset"] = ours["preset"];  // the name alone does not change the model
  if (theirs != ours) fail_file(path, "was written for another model: {} (this run: {})", config.dump(), ours.dump());

  StateDict model, avg, avg_sq;
  torch::Tensor rng;
  for (const auto& [name, data] : file.tensors) {
    if (name.rfind(kExpAvgSq, 0) == 0) avg_sq[name.substr(kExpAvgSq.size())] = tensor_from_data(data, path);
    else if (name.rfind(kExpAvg, 0) == 0) avg[name.substr(kExpAvg.size())] = tensor_from_data(data, path);
    else if (name == kRng) rng = tensor_from_data(data, path);
    else model[name] = tensor_from_data(data, path);
  }
  params_.load(model, path.string());
  std::vector<torch::Tensor> m, v;
  for (const std::string& name : params_.names()) {
    if (!avg.count(name) || !avg_sq.count(name)) fail_file(path, "has no optimiser moments for {}", name);
    m.push_back(avg.at(name).to(options_.device));
    v.push_back(avg_sq.at(name).to(options_.device));
  }
  int64_t steps = 0;
  try {
    steps = training.at("step").get<int64_t>();
  } catch (const nlohmann::json::exception& e) {
    fail_file(path, "damaged training metadata: {}", e.what());
  }
  optimizer_->load_state(steps, m, v);
  if (rng.defined()) {
    at::Generator generator = at::detail::getDefaultCPUGenerator();
    std::lock_guard<std::mutex> lock(generator.mutex());
    generator.set_state(rng);
  }
  network_current_ = false;
  return training.value("state", nlohmann::json::object());
}

void Trainer::export_model(const fs::path& path, const nlohmann::json& metadata) const {
  std::vector<std::pair<std::string, torch::Tensor>> tensors;
  for (size_t i = 0; i < params_.names().size(); ++i) tensors.emplace_back(params_.names()[i], params_.tensors()[i]);
  std::map<std::string, std::string> meta{{"format", "instainpaint"}, {"config", network_.config().to_json().dump()}};
  for (const auto& [k, v] : metadata.items()) meta[k] = v.is_string() ? v.get<std::string>() : v.dump();
  write_tensor_file(path, tensors, meta);
}

}  // namespace ii
