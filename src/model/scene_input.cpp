#include "model/scene_input.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "common/parallel.h"
#include "data/image_ops.h"
#include "data/inpaint2d.h"
#include "data/masks.h"
#include "data/view_selection.h"

namespace ii {

namespace {

// The reference image may come at the source image's size (preprocessed like the view), at the
// working size, or at the photo's working size for another height (the official evaluation's crop).
Image reference_at_working_size(const Image& image, const std::string& source, const View& view,
                                const PreparedView& prepared, const PreprocessOptions& options) {
  const int sw = view.camera.K.width, sh = view.camera.K.height;
  if (auto at = view_picture_at_working_size(image, sw, sh, working_size(sw, sh, options), options.patch)) return *at;
  fail("{}: reference image is {}x{}, but view {} is {}x{} (working size {}x{}): give the "
       "inpainted image at either size",
       source, image.width, image.height, view.name, sw, sh, prepared.rgb.width, prepared.rgb.height);
}

// A caller's mask for a view, checked against the view's image and brought to the working size.
Image mask_at_working_size(const Image& mask, const View& view, const PreprocessOptions& options) {
  const int w = view.camera.K.width, h = view.camera.K.height;
  if (mask.width != w || mask.height != h || mask.channels != 1)
    fail("mask for view {}: {}x{} with {} channels, the view's image is {}x{} (one channel expected)", view.name,
         mask.width, mask.height, mask.channels, w, h);
  Image binary = mask;
  for (float& v : binary.pixels) v = v > 0.5f ? 1.f : 0.f;
  return to_working_size(binary, working_size(w, h, options), /*is_mask=*/true);
}

}  // namespace

std::vector<PreparedView> prepare_masked_views(const Scene& scene, const std::vector<int>& indices,
                                               const InputOptions& options, const std::string& role) {
  for (size_t i = 1; i < indices.size() && !options.keep_object; ++i) {
    const View& view = scene.views.at(static_cast<size_t>(indices[i]));
    if (!view.mask_path && !view.mask_from_alpha && !options.masks.count(view.name))
      fail("view {} has no object mask: give masks for every {} (--masks DIR or --alpha-masks)", view.name, role);
  }
  std::vector<PreparedView> views(indices.size());
  parallel_dynamic(static_cast<int64_t>(indices.size()), thread_plan().cores, [&](int64_t i) {
    const View& view = scene.views.at(static_cast<size_t>(indices[static_cast<size_t>(i)]));
    const auto given_mask = options.masks.find(view.name);
    View source = view;
    if (given_mask != options.masks.end()) {  // the caller's mask: the scene's file is not read
      source.mask_path.reset();
      source.mask_from_alpha = false;
    }
    views[static_cast<size_t>(i)] =
        options.view_cache ? options.view_cache->get(view, options.preprocess) : prepare_view(source, options.preprocess);
    if (given_mask != options.masks.end())
      views[static_cast<size_t>(i)].mask = mask_at_working_size(given_mask->second, view, options.preprocess);
  });
  return views;
}

Image region_to_paint(const Image& mask, double grow) {
  if (!(grow > 0)) return mask;
  const int pixels = std::max(1, static_cast<int>(std::lround(grow * std::max(mask.width, mask.height))));
  return dilate_mask(mask, 1, 2 * pixels + 1);
}

Image painted_reference(const Scene& scene, const std::string& view, const Image& mask, const InputOptions& options) {
  const View& v = scene.views.at(static_cast<size_t>(input_view_index(scene, view, "reference view")));
  const PreparedView prepared =
      options.view_cache ? options.view_cache->get(v, options.preprocess) : prepare_view(v, options.preprocess);
  return options.inpainter.paint(prepared.rgb,
                                 region_to_paint(mask_at_working_size(mask, v, options.preprocess), options.inpaint_grow.value_or(0)));
}

SceneInput prepare_scene_input(const Scene& scene, const InputOptions& options, StageTimes* stages) {
  StageTimes unrecorded;
  StageTimes& times = stages ? *stages : unrecorded;
  times.restart_lap();
  SceneInput out;
  if (!options.context.empty() && !options.reference_view.empty())
    fail("give the context views or the reference view, not both (the context's first view is the reference)");
  std::optional<int> reference;
  if (!options.reference_view.empty()) reference = input_view_index(scene, options.reference_view, "reference view");
  out.context = options.context.empty() ? select_context_views(scene, options.num_views, reference)
                                        : context_views_by_name(scene, options.context);
  out.views = prepare_masked_views(scene, out.context, options, "context view");
  times.lap("prepare context views");

  PreparedView& ref = out.views[0];
  const View& ref_view = scene.views[out.context[0]];
  if (options.keep_object) {
    // Plain reconstruction: photos as they are, empty masks (the stage-1 input).
    for (PreparedView& v : out.views) v.mask = Image(v.rgb.width, v.rgb.height, 1);
    out.reference_source = "photo (object kept)";
  } else if (options.reference_image) {
    ref.rgb = reference_at_working_size(*options.reference_image, "reference image in memory", ref_view, ref,
                                        options.preprocess);
    out.reference_source = options.reference_image_source;
  } else if (options.reference) {
    ref.rgb = reference_at_working_size(read_image_rgb(*options.reference), options.reference->string(), ref_view,
                                        ref, options.preprocess);
    out.reference_source = options.reference->string();
    times.lap("read reference");
  } else {
    if (!ref.mask)
      fail("no --reference image given and reference view {} has no mask to inpaint", ref.name);
    if (!options.inpainter.learned)
      spdlog::warn("no --reference given: inpainting view {} with the classical '{}' method; a learned 2D inpainter "
                   "gives much better results (instainpaint models get big-lama: then used by default)",
                   ref.name, options.inpainter.name());
    ref.rgb = options.inpainter.paint(ref.rgb, region_to_paint(*ref.mask, options.inpaint_grow.value_or(0)));
    out.reference_source = options.inpainter.name();
    out.reference_inpainter = options.inpainter.describe();
    out.reference_inpainter["grow"] = options.inpaint_grow.value_or(0);  // the mask grown by this fraction first
    times.lap(fmt::format("inpaint reference ({})", out.reference_source));
  }
  out.normalization = scene_normalization(scene);
  out.input = build_model_input(out.views, out.normalization);
  times.lap("network input");
  return out;
}

namespace {

GaussianSet moved(const GaussianSet& g, double scale, const Eigen::Vector3d& shift) {
  GaussianSet out = g;
  const torch::Tensor t = torch::tensor({shift.x(), shift.y(), shift.z()}, torch::kFloat64);
  out.means = (g.means.to(torch::kFloat64) * scale + t.to(g.means.device())).to(g.means.dtype());
  out.scales = (g.scales.to(torch::kFloat64) * scale).to(g.scales.dtype());
  return out;
}

}  // namespace

GaussianSet in_scene_frame(const GaussianSet& gaussians, const PoseNormalization& normalization) {
  return moved(gaussians, normalization.scale, normalization.mean);
}

GaussianSet in_normalized_frame(const GaussianSet& gaussians, const PoseNormalization& normalization) {
  return moved(gaussians, 1.0 / normalization.scale, -normalization.mean / normalization.scale);
}

}  // namespace ii
