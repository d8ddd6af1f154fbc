#include "refine/refine.h"

#include <algorithm>
#include <cmath>

#include <Eigen/LU>
#include <fmt/format.h>

#include "common/error.h"
#include "common/stopwatch.h"
#include "data/masks.h"
#include "eval/metrics.h"
#include "model/scene_input.h"
#include "refine/adam.h"
#include "render/projection.h"
#include "render/rasterizer.h"
#include "tensor/camera_projection.h"
#include "tensor/image_tensor.h"

namespace ii {

namespace {

// One view at one resolution as the loss needs it: the photo (1, 3, H, W) with unsupervised
// pixels zeroed, the supervised pixels (1, 1, H, W).
struct Level {
  RenderCamera camera;
  torch::Tensor rgb, weight;
  bool any = false;  // some pixel supervised
  // Usable for the loss: something supervised, and no smaller than SSIM's 11x11 window.
  bool usable() const { return any && camera.camera.K.width >= 11 && camera.camera.K.height >= 11; }
};

// A view at full, half and quarter resolution. A coarse pixel is supervised only when all of
// the pixels it averages are, so masked pixels never reach the loss at any level.
struct Target {
  std::string name;
  std::array<Level, 3> levels;
  bool may_hold_out = true;  // RefineView::may_hold_out
  torch::Tensor scored;      // (1, 1, H, W): the full size's pixels a held-out score reads (the image's own)
};

Level half_of(const Level& fine) {
  Level l;
  const Intrinsics& K = fine.camera.camera.K;
  l.camera = fine.camera;
  l.camera.camera.K.width = K.width / 2;  // the odd last column and row are dropped
  l.camera.camera.K.height = K.height / 2;
  for (double* v : {&l.camera.camera.K.fx, &l.camera.camera.K.fy, &l.camera.camera.K.cx, &l.camera.camera.K.cy})
    *v /= 2;
  if (K.width < 2 || K.height < 2) return l;  // nothing supervised
  l.weight = (torch::avg_pool2d(fine.weight, 2) >= 1 - 1e-6).to(torch::kFloat32);
  l.rgb = torch::avg_pool2d(fine.rgb, 2) * l.weight;
  l.any = l.weight.sum().item<double>() > 0;
  return l;
}

double elapsed_s(const Stopwatch& clock) { return clock.ms() / 1000; }

// New Gaussians where a view's supervised pixels are not covered (RefineOptions::cover).
GaussianSet cover_uncovered(const GaussianSet& start, const std::vector<Target>& targets) {
  torch::NoGradGuard no_grad;
  const torch::Device device = start.means.device();
  std::vector<torch::Tensor> means, scales, colours;
  for (const Target& t : targets) {
    const Level& l = t.levels[2];
    if (!l.any) continue;
    const RenderOutput out = render(start, l.camera);
    const torch::Tensor alpha = out.alpha.squeeze(2).to(torch::kCPU);
    const torch::Tensor open = (alpha < 0.5).logical_and(l.weight[0][0].to(torch::kCPU) > 0.5);
    if (open.sum().item<int64_t>() == 0) continue;
    const torch::Tensor seen = out.depth.squeeze(2).to(torch::kCPU).index({alpha >= 0.5});
    // The median depth of what this view sees; with nothing seen, the extent of the start set.
    const double depth = seen.numel() > 0 ? seen.median().item<double>()
                                          : std::max(1e-3, 2 * visible_bounds(start).radius);
    const torch::Tensor pixels = open.nonzero();
    const torch::Tensor v = pixels.select(1, 0).to(torch::kFloat64), u = pixels.select(1, 1).to(torch::kFloat64);
    means.push_back(unproject(l.camera.camera, v, u, torch::full_like(u, depth)).to(torch::kFloat32));
    const double sigma = depth / l.camera.camera.K.fx;  // one quarter-resolution pixel at that depth
    scales.push_back(torch::full({pixels.size(0), 3}, sigma, torch::kFloat32));
    const torch::Tensor rgb = l.rgb[0].to(torch::kCPU).permute({1, 2, 0});
    colours.push_back(rgb.index({pixels.select(1, 0), pixels.select(1, 1)}));
  }
  GaussianSet added;
  if (means.empty()) return added;
  added.means = torch::cat(means).to(device);
  added.scales = torch::cat(scales).to(device);
  added.colors = torch::cat(colours).to(device);
  const int64_t n = added.means.size(0);
  added.quats = torch::tensor({1.f, 0.f, 0.f, 0.f}, torch::TensorOptions(device)).repeat({n, 1});
  added.opacities = torch::full({n}, 0.5f, torch::TensorOptions(device));
  return added;
}

// The view-space (NDC) gradient of each Gaussian's projected centre, from its world gradient:
// the part across the viewing direction, divided by the projection's scale (fx / z pixels per
// unit, W / 2 pixels per NDC unit); the path through the covariance is left out.
torch::Tensor view_space_gradient(const torch::Tensor& means, const torch::Tensor& grad, const Camera& camera) {
  const auto [R, t] = rotation_and_translation(camera.w2c_opencv(), means.options());
  const torch::Tensor z = (means.matmul(R.t()) + t).select(1, 2).clamp_min(1e-6);
  const torch::Tensor g = grad.matmul(R.t());
  const torch::Tensor gx = g.select(1, 0) * z * (camera.K.width / (2 * camera.K.fx));
  const torch::Tensor gy = g.select(1, 1) * z * (camera.K.height / (2 * camera.K.fy));
  return (gx * gx + gy * gy).sqrt();
}

}  // namespace

bool refine_requested(const RefineOptions& options) { return options.time_budget_s > 0 || options.steps > 0; }

std::string refine_length(const RefineOptions& options) {
  if (options.time_budget_s > 0) {
    const double s = options.time_budget_s;
    return s >= 60 && std::fmod(s, 60) == 0 ? fmt::format("{} minute{}", s / 60, s == 60 ? "" : "s")
                                            : fmt::format("{} s", s);
  }
  return fmt::format("{} step{}", options.steps, options.steps == 1 ? "" : "s");
}

RefineOptions refine_setting(const std::string& text) {
  RefineOptions o;
  if (text == "fast" || text == "balanced" || text == "best") {
    o.time_budget_s = text == "fast" ? 60 : text == "balanced" ? 540 : 1200;
    return o;
  }
  // A number of steps, or a time: digits with an optional fraction and the unit s or m.
  size_t used = 0;
  double value = -1;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  const std::string unit = used > 0 ? text.substr(used) : "";
  const bool digits_only = !text.empty() && text.find_first_not_of("0123456789") == std::string::npos;
  if (digits_only && text.size() <= 6) {
    o.steps = std::stoi(text);
    return o;
  }
  if (used > 0 && std::isdigit(static_cast<unsigned char>(text[0])) && (unit == "s" || unit == "m") &&
      value > 0 && value <= 24 * 3600) {
    o.time_budget_s = unit == "m" ? value * 60 : value;
    if (o.time_budget_s <= 24 * 3600) return o;
  }
  fail("refine: '{}' is not a refinement: use fast, balanced or best, a time such as 90s or 2m (up to 24 hours), or a "
       "number of steps",
       text);
}

namespace {

// `s`'s colours as `k` SH coefficients: RGB as the DC term, missing coefficients zero.
torch::Tensor as_sh(const GaussianSet& s, int64_t k) {
  torch::Tensor c = s.sh_degree < 0 ? sh_dc_from_rgb(s.colors).unsqueeze(1) : s.colors;
  if (c.size(1) < k) c = torch::cat({c, torch::zeros({c.size(0), k - c.size(1), 3}, c.options())}, 1);
  return c.narrow(1, 0, k);
}

// `g` drawn in front of the fixed set: one set, colours in the form of the richer of the two
// (RGB as SH DC, missing SH coefficients zero); `g` itself when nothing is fixed.
GaussianSet with_fixed(const GaussianSet& g, const GaussianSet& fixed) {
  if (fixed.size() == 0) return g;
  GaussianSet out;
  out.means = torch::cat({g.means, fixed.means});
  out.scales = torch::cat({g.scales, fixed.scales});
  out.quats = torch::cat({g.quats, fixed.quats});
  out.opacities = torch::cat({g.opacities.reshape({-1}), fixed.opacities.reshape({-1}).to(g.opacities.dtype())});
  if (g.sh_degree < 0 && fixed.sh_degree < 0) {
    out.colors = torch::cat({g.colors, fixed.colors});
    out.sh_degree = -1;
  } else {
    const int degree = std::max(g.sh_degree, fixed.sh_degree);
    const int64_t k = (degree + 1) * (degree + 1);
    out.colors = torch::cat({as_sh(g, k), as_sh(fixed, k)});
    out.sh_degree = degree;
  }
  return out;
}

}  // namespace

namespace {

void check_refine_options(const GaussianSet& start_set, const std::vector<RefineView>& views,
                          const RefineOptions& options) {
  if (views.empty()) fail("refine: no views to refine against");
  if (options.steps < 0) fail("refine: the number of steps must be 0 or more, got {}", options.steps);
  if (!(options.time_budget_s >= 0)) fail("refine: the time budget must be 0 or more seconds, got {}", options.time_budget_s);
  if (options.sh_degree < 0 || options.sh_degree > 3)
    fail("refine: the SH degree must be 0 to 3, got {}", options.sh_degree);
  if (options.first_step < 0 || !(options.first_fraction >= 0 && options.first_fraction < 1))
    fail("refine: a run continues from step 0 or later and before its end, got step {} at {:.0f} %",
         options.first_step, 100 * options.first_fraction);
}

// Each view with something to supervise, at full, half and quarter size; masked pixels weigh 0.
std::vector<Target> refinement_targets(const std::vector<RefineView>& views, const torch::Device& device) {
  std::vector<Target> targets;
  for (const RefineView& v : views) {
    if (v.mask && (v.mask->width != v.rgb.width || v.mask->height != v.rgb.height || v.mask->channels != 1))
      fail("refine: the mask of view {} does not fit its {}x{} image", v.name, v.rgb.width, v.rgb.height);
    Target t;
    t.name = v.name;
    t.may_hold_out = v.may_hold_out;
    Level& full = t.levels[0];
    full.camera.camera = v.camera;
    full.rgb = image_to_tensor(v.rgb).to(device);
    full.weight = v.mask ? (image_to_tensor(*v.mask) <= 0.5).to(torch::kFloat32).to(device)
                         : torch::ones({1, 1, v.rgb.height, v.rgb.width}, torch::TensorOptions(device));
    t.scored = full.weight;
    if (v.mask && v.in_mask) {
      if (v.in_mask->width != v.rgb.width || v.in_mask->height != v.rgb.height || v.in_mask->channels != 3)
        fail("refine: what view {} fits inside its mask does not fit its {}x{} image", v.name, v.rgb.width,
             v.rgb.height);
      full.rgb = torch::where(full.weight > 0.5, full.rgb, image_to_tensor(*v.in_mask).to(device));
      full.weight = torch::ones_like(full.weight);
    }
    full.rgb = full.rgb * full.weight;
    full.any = full.weight.sum().item<double>() > 0;
    if (!full.any) continue;  // a view masked everywhere says nothing
    t.levels[1] = half_of(full);
    t.levels[2] = half_of(t.levels[1]);
    targets.push_back(std::move(t));
  }
  if (targets.empty()) fail("refine: every view is masked everywhere");
  return targets;
}

// 3DGS's parametrisation of the Gaussians being optimised: raw positions, log scales, raw
// quaternions, opacity logits, colours (RGB, or SH DC with the higher coefficients beside).
struct Parameters {
  torch::Tensor means, log_scales, quats, logits, colours, sh_rest;
  bool sh = false;

  // Degree 0 keeps the network's RGB colours; higher degrees start from the same colour (the
  // DC term) with zero view dependence, or from the start's own coefficients when it has SH (a
  // run continued).
  Parameters(const GaussianSet& start, int sh_degree, const torch::TensorOptions& f32) : sh(sh_degree > 0) {
    means = start.means.to(f32).detach().clone().requires_grad_(true);
    log_scales = start.scales.to(f32).clamp_min(1e-12).log().detach().requires_grad_(true);
    quats = start.quats.to(f32).detach().clone().requires_grad_(true);
    logits = torch::logit(start.opacities.to(f32).reshape({-1}).clamp(1e-6, 1 - 1e-6)).detach().requires_grad_(true);
    const int64_t k = (sh_degree + 1) * (sh_degree + 1);
    const torch::Tensor start_sh = as_sh(start, std::max<int64_t>(k, 1)).to(f32);
    colours = sh ? start_sh.narrow(1, 0, 1).detach().clone().requires_grad_(true)
            : start.sh_degree < 0 ? start.colors.to(f32).detach().clone().requires_grad_(true)
                                  : rgb_from_sh_dc(start_sh.select(1, 0)).detach().requires_grad_(true);
    if (sh) sh_rest = start_sh.narrow(1, 1, k - 1).detach().clone().requires_grad_(true);
  }

  GaussianSet gaussians(int degree) const {
    GaussianSet g;
    g.means = means;
    g.scales = log_scales.exp();
    g.quats = quats;
    g.opacities = torch::sigmoid(logits);
    g.colors = sh ? torch::cat({colours, sh_rest}, 1) : colours;
    g.sh_degree = sh ? degree : -1;
    return g;
  }
};

// Clones, splits and prunes as `decision` says, in the parameters and the optimiser's rows.
void densify(Parameters& p, RowAdam& adam, const DensifyDecision& d, RefineResult& result) {
  torch::NoGradGuard no_grad;
  result.cloned += d.clone.sum().item<int64_t>();
  result.split += d.split.sum().item<int64_t>();
  result.pruned += d.prune.sum().item<int64_t>();
  // New rows: the clones; each split Gaussian's two children, smaller. A clone and its
  // parent share the parent's opacity o: both get 1 − √(1 − o), so that the pair in one
  // place is as opaque as the parent was (as 3DGS-MCMC does; 3DGS keeps o and the image jumps).
  const torch::Tensor shared = torch::logit(1 - (1 - torch::sigmoid(p.logits)).sqrt(), 1e-6);
  p.logits.data().copy_(torch::where(d.clone, shared, p.logits));
  const auto [first, second] = split_centres(p.means.index({d.split}), p.log_scales.index({d.split}).exp(),
                                             p.quats.index({d.split}));
  const torch::Tensor smaller = split_log_scales(p.log_scales.index({d.split}));
  auto rows = [&](const torch::Tensor& t) {
    return torch::cat({t.index({d.clone}), t.index({d.split}), t.index({d.split})});
  };
  std::vector<torch::Tensor> added = {torch::cat({p.means.index({d.clone}), first, second}),
                                      torch::cat({p.log_scales.index({d.clone}), smaller, smaller}), rows(p.quats),
                                      rows(p.logits), rows(p.colours)};
  if (p.sh) added.push_back(rows(p.sh_rest));
  // Parents of splits and pruned ones go; the new rows come after the kept ones.
  adam.keep_rows(d.split.logical_or(d.prune).logical_not());
  adam.append_rows(added);
}

// Each view's learned colour map (gains and offsets; the first view's is the identity).
std::vector<std::pair<std::string, std::array<double, 6>>> exposure_record(const torch::Tensor& exposure,
                                                                           const std::vector<Target>& targets) {
  std::vector<std::pair<std::string, std::array<double, 6>>> out = {{targets[0].name, {1, 1, 1, 0, 0, 0}}};
  const torch::Tensor maps = exposure.detach().to(torch::kCPU);
  for (int64_t v = 0; v < maps.size(0); ++v) {
    std::array<double, 6> e;
    for (int c = 0; c < 3; ++c) {
      e[c] = maps[v][c][c].item<double>();
      e[3 + c] = maps[v][c][3].item<double>();
    }
    out.push_back({targets[static_cast<size_t>(v) + 1].name, e});
  }
  return out;
}

// The picture size a step renders at: coarse to fine by the run's fraction, the finest the
// view can give.
int step_level(const Target& target, double fraction, const RefineOptions& options) {
  int level = !options.coarse_to_fine                ? 0
              : fraction < options.quarter_until ? 2
              : fraction < options.half_until    ? 1
                                                 : 0;
  while (level > 0 && !target.levels[level].usable()) --level;
  return level;
}

// Every n-th view after the first that may be held out leaves `targets` to score the iterates
// (RefineOptions::hold_out_every); none when fewer than 3 would be left to fit.
std::vector<Target> take_held_out(std::vector<Target>& targets, int every) {
  std::vector<Target> held, fitted;
  if (every <= 0) return held;
  int candidates = 0;
  for (size_t i = 0; i < targets.size(); ++i) {
    const bool may = i > 0 && targets[i].may_hold_out;
    (may && candidates++ % every == every / 2 ? held : fitted).push_back(targets[i]);
  }
  if (fitted.size() < 3 || held.empty()) return {};
  targets = std::move(fitted);
  return held;
}

// PSNR of `drawn` over the image's own pixels (outside its mask) of every held-out view at full
// size, pooled.
double held_out_psnr(const GaussianSet& drawn, const std::vector<Target>& held, const RenderOptions& look) {
  torch::NoGradGuard no_grad;
  double squared = 0, count = 0;
  for (const Target& t : held) {
    const Level& l = t.levels[0];
    const torch::Tensor rgb = render(drawn, l.camera, look).rgb.permute({2, 0, 1}).unsqueeze(0);
    squared += ((rgb - l.rgb) * t.scored).square().sum().item<double>();
    count += 3 * t.scored.sum().item<double>();
  }
  return -10 * std::log10(std::max(squared / std::max(count, 1.0), 1e-12));
}

// A detached copy of the Gaussians being optimised, as the result gives them.
GaussianSet snapshot(const GaussianSet& g) {
  GaussianSet s = g;
  for (torch::Tensor* t : {&s.means, &s.scales, &s.quats, &s.opacities, &s.colors}) *t = t->detach().clone();
  return s;
}

// `g` (RGB colours) in the colour form of a result of `sh_degree`: RGB for 0, else SH of that
// degree with no view dependence.
GaussianSet in_result_form(GaussianSet g, int sh_degree) {
  g.means = g.means.to(torch::kFloat32);
  g.scales = g.scales.to(torch::kFloat32);
  g.quats = g.quats.to(torch::kFloat32);
  g.opacities = g.opacities.to(torch::kFloat32).reshape({-1});
  g.colors = g.colors.to(torch::kFloat32);
  if (sh_degree > 0) {
    g.colors = as_sh(g, (sh_degree + 1) * (sh_degree + 1));
    g.sh_degree = sh_degree;
  }
  return g;
}

}  // namespace

RefineResult refine_gaussians(const GaussianSet& start_set, const std::vector<RefineView>& views,
                              const RefineOptions& options) {
  const Stopwatch clock;
  check_refine_options(start_set, views, options);
  const torch::Device device = start_set.means.device();
  std::vector<Target> targets = refinement_targets(views, device);
  const bool optimise = refine_requested(options);
  const std::vector<Target> held =
      optimise ? take_held_out(targets, options.hold_out_every) : std::vector<Target>{};
  RenderOptions look;
  look.background = options.background;
  RefineResult result;
  result.steps = options.first_step;
  for (const Target& t : targets) result.views.push_back(t.name);
  for (const Target& t : held) result.held_out.push_back(t.name);

  result.start_count = start_set.size();
  GaussianSet start = start_set.to(device);
  if (!held.empty()) {
    result.start_psnr = held_out_psnr(
        options.whole_start.size() > 0 ? options.whole_start : with_fixed(start, options.fixed), held, look);
  }
  if (optimise && options.cover) {
    const GaussianSet added = cover_uncovered(start, targets);
    result.covered = added.size();
    if (added.size() > 0) {
      for (auto [to, from] : {std::pair{&start.means, &added.means}, {&start.scales, &added.scales},
                              {&start.quats, &added.quats}, {&start.colors, &added.colors}})
        *to = torch::cat({to->to(torch::kFloat32), from->to(to->device())});
      start.opacities = torch::cat({start.opacities.to(torch::kFloat32).reshape({-1}), added.opacities});
    }
  }

  const torch::TensorOptions f32 = torch::TensorOptions(device).dtype(torch::kFloat32);
  Parameters p(start, options.sh_degree, f32);
  const double extent = options.extent > 0 ? options.extent : std::max(visible_bounds(start).radius, 1e-6);
  RowAdam adam;
  adam.add(&p.means, options.position_lr * extent);
  adam.add(&p.log_scales, options.scale_lr);
  adam.add(&p.quats, options.rotation_lr);
  constexpr size_t kOpacitySlot = 3;
  adam.add(&p.logits, options.opacity_lr);
  adam.add(&p.colours, options.colour_lr);
  if (p.sh) adam.add(&p.sh_rest, options.colour_lr / 20);

  // Per-view colour maps (3 x 4: gains and offsets) for every view but the first.
  torch::Tensor exposure;
  RowAdam exposure_adam;
  if (options.exposure && targets.size() > 1) {
    exposure = torch::cat({torch::eye(3, f32), torch::zeros({3, 1}, f32)}, 1)
                   .repeat({static_cast<int64_t>(targets.size()) - 1, 1, 1})
                   .requires_grad_(true);
    exposure_adam.add(&exposure, options.exposure_lr);
  }
  // What a step draws: the optimised Gaussians and the fixed ones.
  auto drawn = [&](int degree) {
    return with_fixed(p.gaussians(degree), options.fixed);
  };

  const int64_t max_gaussians = options.densify.max_gaussians > 0
                                    ? options.densify.max_gaussians
                                    : static_cast<int64_t>(start.size() * (1 + options.densify.max_growth));
  torch::Tensor grad_sum = torch::zeros({start.size()}, f32), seen = torch::zeros({start.size()}, f32);

  // Views in a seeded order, each once per pass.
  MaskRng rng(options.seed);
  std::vector<size_t> order;
  const double budget = options.time_budget_s;
  const double initial_position_lr = options.position_lr * extent;
  double loop_start = 0;
  double views_seen = 0;  // full-resolution views' worth of pixels visited
  size_t next_reset = 0;  // into options.opacity_resets
  // A run continued has had the resets before its start (one at exactly its start is still due).
  const double start_fraction = budget > 0          ? options.first_fraction
                                : options.steps > 0 ? double(options.first_step) / options.steps
                                                    : 0;
  while (next_reset < options.opacity_resets.size() && options.opacity_resets[next_reset] < start_fraction) ++next_reset;
  // The best scored so far on the held-out views: the start, then iterates that beat it.
  GaussianSet best;
  double best_psnr = result.start_psnr;
  auto score = [&](int step) {
    const GaussianSet now = snapshot(p.gaussians(options.sh_degree));
    const double psnr = held_out_psnr(with_fixed(now, options.fixed), held, look);
    result.iterates.push_back({step, psnr});
    if (psnr > best_psnr) {
      best_psnr = psnr;
      best = now;
      result.chosen_step = step;
    }
  };
  size_t next_score = 0;  // into options.score_at
  Stopwatch loop_clock;
  for (int step = options.first_step;; ++step) {
    const double now = elapsed_s(clock);
    const double fraction = budget > 0 ? options.first_fraction + now / budget
                            : options.steps > 0 ? double(step) / options.steps
                                                : 1;
    for (; next_score < options.score_at.size() && fraction >= options.score_at[next_score]; ++next_score)
      if (!held.empty() && step > 0 && fraction < 1) score(step);
    if (fraction >= 1) break;
    if (step == options.first_step) loop_start = now;
    if (order.empty()) {
      for (size_t i = 0; i < targets.size(); ++i) order.push_back(i);
      random_shuffle(order, rng);
    }
    const size_t view = order.back();
    order.pop_back();
    const int level = step_level(targets[view], fraction, options);
    const Level& t = targets[view].levels[level];
    const int degree = std::min(options.sh_degree, static_cast<int>(fraction * 10));
    const double decayed = options.position_decay_views > 0 ? std::max(fraction, views_seen / options.position_decay_views)
                                                             : fraction;
    adam.set_lr(0, initial_position_lr *
                       std::pow(options.position_lr_final / options.position_lr, std::min(1.0, decayed)));

    // Unsupervised pixels are zero in both images: no gradient flows from them, and the SSIM
    // windows that reach into them see the same values on both sides.
    torch::Tensor rgb = render(drawn(degree), t.camera, look).rgb.permute({2, 0, 1}).unsqueeze(0);
    if (exposure.defined() && view > 0) {
      const torch::Tensor map = exposure[static_cast<int64_t>(view) - 1];
      rgb = (map.narrow(1, 0, 3).matmul(rgb.reshape({3, -1})) + map.narrow(1, 3, 1)).reshape(rgb.sizes());
    }
    rgb = rgb * t.weight;
    const torch::Tensor supervised = t.weight.sum().clamp_min(1);
    const torch::Tensor l1 = ((rgb - t.rgb).abs() * t.weight).sum() / (3 * supervised);
    const torch::Tensor loss = (1 - options.ssim_weight) * l1 +
                               options.ssim_weight * (1 - masked_ssim(rgb, t.rgb, t.weight).mean());
    loss.backward();

    const bool densifying =
        options.densify.enabled && fraction >= options.densify_from && fraction < options.densify_until;
    if (densifying) {
      torch::NoGradGuard no_grad;
      const torch::Tensor g = view_space_gradient(p.means.detach(), p.means.grad(), t.camera.camera);
      grad_sum += g;
      seen += (p.means.grad().abs().sum(1) > 0).to(torch::kFloat32);
    }
    adam.step();
    if (exposure.defined()) exposure_adam.step();
    if (densifying && (step + 1) % options.densify_every == 0) {
      DensifyDecision d;
      {
        torch::NoGradGuard no_grad;
        d = decide_densification(grad_sum / seen.clamp_min(1), p.log_scales.exp().amax(1), torch::sigmoid(p.logits),
                                 extent, max_gaussians, options.densify);
      }
      densify(p, adam, d, result);
      grad_sum = torch::zeros({p.means.size(0)}, f32);
      seen = torch::zeros({p.means.size(0)}, f32);
    }
    if (options.densify.enabled && next_reset < options.opacity_resets.size() &&
        fraction >= options.opacity_resets[next_reset]) {
      torch::NoGradGuard no_grad;
      p.logits.clamp_max_(std::log(options.reset_opacity / (1 - options.reset_opacity)));
      adam.restart(kOpacitySlot);
      ++next_reset;
      ++result.opacity_resets;
    }

    views_seen += std::pow(0.25, level);
    result.losses.push_back(loss.item<double>());
    result.steps = step + 1;
    if (options.checkpoint && options.checkpoint_every > 0 && (step + 1) % options.checkpoint_every == 0) {
      torch::NoGradGuard no_grad;
      options.checkpoint(step + 1, snapshot(p.gaussians(options.sh_degree)));
    }
    if (options.progress) {
      RefineProgress progress;
      progress.step = step + 1;
      progress.elapsed_s = elapsed_s(clock);
      progress.fraction = budget > 0 ? std::min(1.0, options.first_fraction + progress.elapsed_s / budget)
                                     : double(step + 1) / options.steps;
      progress.loss = result.losses.back();
      progress.eta_s = budget > 0 ? std::max(0.0, (1 - progress.fraction) * budget)
                                  : (progress.elapsed_s - loop_start) / (step + 1 - options.first_step) *
                                        (options.steps - step - 1);
      progress.gaussians = p.means.size(0);
      options.progress(progress);
    }
  }
  const int steps_here = result.steps - options.first_step;
  result.ms_per_step = steps_here > 0 ? loop_clock.ms() / steps_here : 0;

  torch::NoGradGuard no_grad;
  GaussianSet refined = p.gaussians(options.sh_degree);
  if (!held.empty()) {
    if (result.iterates.empty() || result.iterates.back().first != result.steps) score(result.steps);
    if (best.size() == 0) {  // nothing beat the start
      result.kept_start = true;
      result.gaussians = in_result_form(start_set.to(device), options.sh_degree);
      if (exposure.defined()) result.exposure = exposure_record(exposure, targets);
      result.seconds = elapsed_s(clock);
      return result;
    }
    refined = best;
  }
  const torch::Tensor keep = refined.opacities >= 1.0 / 255;
  result.dropped = refined.size() - keep.sum().item<int64_t>();
  for (torch::Tensor* t : {&refined.means, &refined.scales, &refined.quats, &refined.opacities, &refined.colors})
    *t = t->index({keep}).detach();
  result.gaussians = refined;
  if (exposure.defined()) result.exposure = exposure_record(exposure, targets);
  result.seconds = elapsed_s(clock);
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
    v.may_hold_out = std::find(prediction.input.context.begin(), prediction.input.context.end(), indices[i]) ==
                     prediction.input.context.end();
    views.push_back(std::move(v));
  }
  return views;
}

namespace {

// Which views chose the result, what each candidate scored there and which won.
nlohmann::json held_out_record(const RefineResult& r) {
  if (r.held_out.empty()) return nullptr;
  nlohmann::json iterates = nlohmann::json::array();
  for (const auto& [step, psnr] : r.iterates) iterates.push_back({{"step", step}, {"psnr", psnr}});
  return {{"views", r.held_out},
          {"start_psnr", r.start_psnr},
          {"iterates", iterates},
          {"chosen", r.kept_start ? nlohmann::json("start") : nlohmann::json(r.chosen_step)}};
}

}  // namespace

nlohmann::json refinement_report(const RefineResult& r, const RefineOptions& options) {
  nlohmann::json exposure = nlohmann::json::object();
  for (const auto& [name, e] : r.exposure)
    exposure[name] = {{"gain", {e[0], e[1], e[2]}}, {"offset", {e[3], e[4], e[5]}}};
  return {{"length", refine_length(options)},
          {"steps", r.steps},
          {"seconds", r.seconds},
          {"ms_per_step", r.ms_per_step},
          {"views", r.views},
          {"losses", r.losses},
          {"gaussians", {{"start", r.start_count},
                         {"covered", r.covered},
                         {"cloned", r.cloned},
                         {"split", r.split},
                         {"pruned", r.pruned},
                         {"opacity_resets", r.opacity_resets},
                         {"dropped", r.dropped},
                         {"end", r.gaussians.size()}}},
          {"dropped", r.dropped},
          {"sh_degree", options.sh_degree},
          {"position_rate", options.position_lr / kGaussianSplattingPositionLr},  // × 3DGS's
          {"coarse_to_fine", options.coarse_to_fine},
          {"densify", options.densify.enabled},
          {"exposure", options.exposure ? exposure : nlohmann::json()},
          {"held_out", held_out_record(r)}};
}

namespace {

// Which of `means` (N, 3) lie in front of `camera` and inside `region` (H, W bool) of its picture.
torch::Tensor seen_in(const torch::Tensor& means, const Camera& camera, const torch::Tensor& region) {
  const PixelHit hit = project(camera, means);
  return hit.inside.logical_and(region.reshape({-1}).index_select(0, hit.index));
}

// The reference's region as an (H, W) mask of its picture: the region surface's pixels, else its
// mask; nothing with `keep_object`.
torch::Tensor reference_region(const Prediction& prediction, bool keep_object) {
  const PreparedView& reference = prediction.input.views.front();
  torch::Tensor region = torch::zeros({reference.rgb.height, reference.rgb.width}, torch::kBool);
  if (keep_object) return region;
  if (prediction.region_surface_pixels.defined() && prediction.region_surface_pixels.numel() > 0)
    region.view({-1}).index_fill_(0, prediction.region_surface_pixels.to(torch::kCPU, torch::kInt64), true);
  else if (reference.mask)
    region = image_to_tensor(*reference.mask)[0][0] > 0.5;
  return region;
}


}  // namespace

// What the reference sees in its region (the region surface's pixels, else its mask), whichever view or
// layer made it, and the region's cover are kept as they are: the other views' masks hide the region, so
// nothing but the reference would move them, and it would slide them along its own rays (scene 1 with an
// object-free reference: refined from the network's Gaussians there, the region lost 4 dB; 2026-12-02,
// 76931df; CHANGELOG.md, 2026-12-02). Prediction::gaussians()'s order: one per pixel of each context
// view, then each layer's.
RefinementStart refinement_start(const GaussianSet& gaussians, const Prediction& prediction, bool keep_object,
                                 int stride) {
  int64_t pixels = 0;
  for (const PreparedView& v : prediction.input.views) pixels += int64_t(v.rgb.width) * v.rgb.height;
  int64_t layered = 0;
  for (const GeometryLayer& l : prediction.layers) layered += l.gaussians.size();
  const bool layers = gaussians.size() == pixels + layered;
  if (gaussians.size() != pixels && !layers)
    fail("refine: {} Gaussians do not match the prediction's {} pixels", gaussians.size(), pixels);
  stride = std::max(stride, 1);

  const torch::Tensor region = reference_region(prediction, keep_object);
  const int64_t region_pixels = region.sum().item<int64_t>();
  // Every Gaussian that the reference sees in its region, whichever view or layer it came from.
  torch::Tensor kept = torch::zeros({gaussians.size()}, torch::kBool);
  if (region_pixels > 0) {
    kept.narrow(0, 0, region.numel()).copy_(region.flatten());
    if (!prediction.input.input.view_cameras.empty())
      kept.logical_or_(seen_in(gaussians.means.to(torch::kCPU, torch::kFloat32),
                               prediction.input.input.view_cameras.front(), region));
  }
  // The rest moves, thinned.
  torch::Tensor thinned = torch::zeros({gaussians.size()}, torch::kBool);
  int64_t first = 0;
  for (const PreparedView& v : prediction.input.views) {
    thinned.narrow(0, first, int64_t(v.rgb.width) * v.rgb.height)
        .view({v.rgb.height, v.rgb.width})
        .slice(0, 0, v.rgb.height, stride)
        .slice(1, 0, v.rgb.width, stride)
        .fill_(true);
    first += int64_t(v.rgb.width) * v.rgb.height;
  }
  // The layers: the region's cover kept whole; of the others' rows (past the frames, behind depth
  // edges), counted as one run, every stride²-th moves.
  if (layers) {
    const int64_t every = int64_t(stride) * stride;
    int64_t counted = 0;
    for (const GeometryLayer& l : prediction.layers) {
      const int64_t n = l.gaussians.size();
      if (l.name == "region_cover") {
        kept.narrow(0, first, n).fill_(true);
      } else {
        thinned.narrow(0, first, n).slice(0, (every - counted % every) % every, n, every).fill_(true);
        counted += n;
      }
      first += n;
    }
  }
  const torch::Tensor moving_rows = thinned.logical_and(kept.logical_not()).nonzero().squeeze(1);
  const torch::Tensor kept_rows = kept.nonzero().squeeze(1);
  RefinementStart s;
  s.moving = select_rows(gaussians, moving_rows.to(gaussians.means.device()));
  s.moving.scales = s.moving.scales * stride;
  s.kept = select_rows(gaussians, kept_rows.to(gaussians.means.device()));
  return s;
}

GaussianSet outside_the_region(const GaussianSet& moved, const Prediction& prediction, bool keep_object,
                               int64_t* dropped) {
  const torch::Tensor region = reference_region(prediction, keep_object);
  if (!region.any().item<bool>() || prediction.input.input.view_cameras.empty()) return moved;
  const torch::Tensor in =
      seen_in(moved.means.to(torch::kCPU, torch::kFloat32), prediction.input.input.view_cameras.front(), region);
  if (dropped) *dropped = in.sum().item<int64_t>();
  return select_rows(moved, in.logical_not().to(moved.means.device()));
}

namespace {

// Each masked view but the reference fits inside its mask what `start` draws there (its render
// over the mask's bounding box alone).
void fit_the_start_in_masks(std::vector<RefineView>& views, const GaussianSet& start) {
  torch::NoGradGuard no_grad;
  for (size_t i = 1; i < views.size(); ++i) {
    RefineView& v = views[i];
    if (!v.mask) continue;
    const torch::Tensor inside = (image_to_tensor(*v.mask)[0][0] > 0.5).nonzero();
    if (inside.size(0) == 0) continue;
    const int y0 = inside.select(1, 0).min().item<int>(), y1 = inside.select(1, 0).max().item<int>() + 1;
    const int x0 = inside.select(1, 1).min().item<int>(), x1 = inside.select(1, 1).max().item<int>() + 1;
    const torch::Tensor drawn =
        render(start, {v.camera.cropped(x0, y0, x1 - x0, y1 - y0)}).rgb.clamp(0, 1).to(torch::kCPU, torch::kFloat32);
    torch::Tensor picture = torch::zeros({v.rgb.height, v.rgb.width, 3});
    picture.slice(0, y0, y1).slice(1, x0, x1).copy_(drawn);
    v.in_mask = image_from_hwc(picture);
  }
}

}  // namespace

GaussianSet refine_prediction(const Scene& scene, const Prediction& prediction, const SceneInputOptions& options,
                              const GaussianSet& start, const RefineOptions& refine, nlohmann::json& report) {
  std::vector<RefineView> views = refinement_views(scene, prediction, options);
  if (refine.start_in_masks && !options.keep_object) fit_the_start_in_masks(views, start);
  const RefinementStart parts = refinement_start(start, prediction, options.keep_object, refine.start_stride);
  RefineOptions o = refine;
  o.fixed = with_fixed(parts.kept, refine.fixed);
  o.whole_start = start;
  RefineResult r = refine_gaussians(parts.moving, views, o);
  report = refinement_report(r, refine);
  if (r.kept_start) return in_result_form(start, refine.sh_degree);
  int64_t dropped = 0;
  const GaussianSet moved = outside_the_region(r.gaussians, prediction, options.keep_object, &dropped);
  report["gaussians"]["moved_into_the_region"] = dropped;
  return with_fixed(moved, o.fixed);
}

}  // namespace ii
