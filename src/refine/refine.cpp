#include "refine/refine.h"

#include <torch/optim/adam.h>

#include <cmath>

#include "common/error.h"
#include "common/stopwatch.h"
#include "data/masks.h"
#include "eval/metrics.h"
#include "model/scene_input.h"
#include "render/rasterizer.h"
#include "tensor/image_tensor.h"

namespace ii {

namespace {

// One view as the loss needs it: the photo (1, 3, H, W) with unsupervised pixels zeroed, the
// supervised pixels (1, 1, H, W).
struct Target {
  RenderCamera camera;
  torch::Tensor rgb, weight;
};

}  // namespace

RefineResult refine_gaussians(const GaussianSet& start, const std::vector<RefineView>& views,
                              const RefineOptions& options) {
  if (views.empty()) fail("refine: no views to refine against");
  if (options.steps < 0) fail("refine: the number of steps must be 0 or more, got {}", options.steps);
  if (start.sh_degree >= 0) fail("refine: the Gaussians must have RGB colours (as the network predicts them)");
  if (options.sh_degree < 0 || options.sh_degree > 3)
    fail("refine: the SH degree must be 0 to 3, got {}", options.sh_degree);
  const torch::Device device = start.means.device();
  std::vector<Target> targets;
  for (const RefineView& v : views) {
    if (v.mask && (v.mask->width != v.rgb.width || v.mask->height != v.rgb.height || v.mask->channels != 1))
      fail("refine: the mask of view {} does not fit its {}x{} image", v.name, v.rgb.width, v.rgb.height);
    Target t;
    t.camera.camera = v.camera;
    t.rgb = image_to_tensor(v.rgb).to(device);
    t.weight = v.mask ? (image_to_tensor(*v.mask) <= 0.5).to(torch::kFloat32).to(device)
                      : torch::ones({1, 1, v.rgb.height, v.rgb.width}, torch::TensorOptions(device));
    t.rgb = t.rgb * t.weight;
    if (t.weight.sum().item<double>() > 0) targets.push_back(std::move(t));  // a view masked everywhere says nothing
  }
  if (targets.empty()) fail("refine: every view is masked everywhere");

  // 3DGS's parametrisation: raw positions, log scales, raw quaternions, opacity logits, colours.
  const torch::TensorOptions f32 = torch::TensorOptions(device).dtype(torch::kFloat32);
  torch::Tensor means = start.means.to(f32).detach().clone().requires_grad_(true);
  torch::Tensor log_scales = start.scales.to(f32).clamp_min(1e-12).log().detach().requires_grad_(true);
  torch::Tensor quats = start.quats.to(f32).detach().clone().requires_grad_(true);
  torch::Tensor logits =
      torch::logit(start.opacities.to(f32).reshape({-1}).clamp(1e-6, 1 - 1e-6)).detach().requires_grad_(true);
  // Degree 0 keeps the network's RGB colours; higher degrees start from the same colour (the
  // DC term) with zero view dependence.
  const bool sh = options.sh_degree > 0;
  torch::Tensor colours = sh ? sh_dc_from_rgb(start.colors.to(f32)).unsqueeze(1).detach().requires_grad_(true)
                             : start.colors.to(f32).detach().clone().requires_grad_(true);
  torch::Tensor sh_rest;
  if (sh) {
    const int64_t rest = (options.sh_degree + 1) * (options.sh_degree + 1) - 1;
    sh_rest = torch::zeros({start.size(), rest, 3}, f32).requires_grad_(true);
  }

  const double extent = std::max(visible_bounds(start).radius, 1e-6);
  auto group = [](torch::Tensor t, double lr) {
    return torch::optim::OptimizerParamGroup({std::move(t)},
                                             std::make_unique<torch::optim::AdamOptions>(
                                                 torch::optim::AdamOptions(lr).eps(1e-15)));
  };
  std::vector<torch::optim::OptimizerParamGroup> groups;
  groups.push_back(group(means, options.position_lr * extent));
  groups.push_back(group(log_scales, options.scale_lr));
  groups.push_back(group(quats, options.rotation_lr));
  groups.push_back(group(logits, options.opacity_lr));
  groups.push_back(group(colours, options.colour_lr));
  if (sh) groups.push_back(group(sh_rest, options.colour_lr / 20));
  torch::optim::Adam adam(std::move(groups), torch::optim::AdamOptions(1e-3));

  auto current = [&] {
    GaussianSet g;
    g.means = means;
    g.scales = log_scales.exp();
    g.quats = quats;
    g.opacities = torch::sigmoid(logits);
    g.colors = sh ? torch::cat({colours, sh_rest}, 1) : colours;
    g.sh_degree = sh ? options.sh_degree : -1;
    return g;
  };

  // Views in a seeded order, each once per pass.
  MaskRng rng(options.seed);
  std::vector<size_t> order;
  RefineResult result;
  Stopwatch watch;
  for (int step = 0; step < options.steps; ++step) {
    if (order.empty()) {
      for (size_t i = 0; i < targets.size(); ++i) order.push_back(i);
      random_shuffle(order, rng);
    }
    const Target& t = targets[order.back()];
    order.pop_back();
    adam.zero_grad();
    // Unsupervised pixels are zero in both images: no gradient flows from them, and the SSIM
    // windows that reach into them see the same values on both sides.
    const torch::Tensor rgb = render(current(), t.camera).rgb.permute({2, 0, 1}).unsqueeze(0) * t.weight;
    const torch::Tensor supervised = t.weight.sum().clamp_min(1);
    const torch::Tensor l1 = ((rgb - t.rgb).abs() * t.weight).sum() / (3 * supervised);
    const torch::Tensor loss = (1 - options.ssim_weight) * l1 +
                               options.ssim_weight * (1 - masked_ssim(rgb, t.rgb, t.weight).mean());
    loss.backward();
    adam.step();
    result.losses.push_back(loss.item<double>());
    if (options.progress) options.progress(step + 1, options.steps, result.losses.back());
  }
  result.ms_per_step = options.steps > 0 ? watch.ms() / options.steps : 0;

  torch::NoGradGuard no_grad;
  GaussianSet refined = current();
  const torch::Tensor keep = refined.opacities >= 1.0 / 255;
  result.dropped = refined.size() - keep.sum().item<int64_t>();
  for (torch::Tensor* t : {&refined.means, &refined.scales, &refined.quats, &refined.opacities, &refined.colors})
    *t = t->index({keep}).detach();
  result.gaussians = refined;
  return result;
}

std::vector<RefineView> refinement_views(const Scene& scene, const Prediction& prediction,
                                         const SceneInputOptions& options) {
  const int reference = prediction.input.context[0];
  std::vector<int> indices = {reference};
  for (int i = 0; i < static_cast<int>(scene.views.size()); ++i)
    if (i != reference) indices.push_back(i);
  std::vector<PreparedView> prepared = prepare_masked_views(scene, indices, options, "view --refine compares with");
  std::vector<RefineView> views;
  for (size_t i = 0; i < prepared.size(); ++i) {
    PreparedView& pv = prepared[i];
    RefineView v;
    v.name = pv.name;
    v.rgb = i == 0 ? prediction.input.views[0].rgb : std::move(pv.rgb);
    if (i > 0 && !options.keep_object) v.mask = std::move(pv.mask);
    v.camera = prediction.input.normalization.apply(pv.camera);
    views.push_back(std::move(v));
  }
  return views;
}

GaussianSet refine_prediction(const Scene& scene, const Prediction& prediction, const SceneInputOptions& options,
                              const GaussianSet& start, const RefineOptions& refine, nlohmann::json& report) {
  const std::vector<RefineView> views = refinement_views(scene, prediction, options);
  RefineResult r = refine_gaussians(start, views, refine);
  nlohmann::json names = nlohmann::json::array();
  for (const RefineView& v : views) names.push_back(v.name);
  report = {{"steps", refine.steps},
            {"ms_per_step", r.ms_per_step},
            {"views", names},
            {"losses", r.losses},
            {"dropped", r.dropped},
            {"sh_degree", refine.sh_degree}};
  return std::move(r.gaussians);
}

}  // namespace ii
