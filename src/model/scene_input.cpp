#include "model/scene_input.h"

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "data/image_ops.h"
#include "data/inpaint2d.h"
#include "data/view_selection.h"

namespace ii {

namespace {

// The reference image may come at the source image's size (preprocessed like the view) or
// already at the working size.
Image reference_at_working_size(const Image& image, const std::string& source, const View& view,
                                const PreparedView& prepared, const PreprocessOptions& options) {
  const int sw = view.camera.K.width, sh = view.camera.K.height;
  if (image.width == sw && image.height == sh)
    return to_working_size(image, working_size(sw, sh, options));
  if (image.width == prepared.rgb.width && image.height == prepared.rgb.height) return image;
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
                                               const SceneInputOptions& options, const std::string& role) {
  std::vector<PreparedView> views;
  for (int index : indices) {
    const View& view = scene.views.at(static_cast<size_t>(index));
    const auto given_mask = options.masks.find(view.name);
    const bool has_mask = view.mask_path || view.mask_from_alpha || given_mask != options.masks.end();
    if (!options.keep_object && !views.empty() && !has_mask)
      fail("view {} has no object mask: give masks for every {} (--masks DIR or --alpha-masks)", view.name, role);
    View source = view;
    if (given_mask != options.masks.end()) {  // the caller's mask: the scene's file is not read
      source.mask_path.reset();
      source.mask_from_alpha = false;
    }
    views.push_back(prepare_view(source, options.preprocess));
    if (given_mask != options.masks.end())
      views.back().mask = mask_at_working_size(given_mask->second, view, options.preprocess);
  }
  return views;
}

SceneInput prepare_scene_input(const Scene& scene, const SceneInputOptions& options) {
  SceneInput out;
  if (!options.context.empty() && !options.reference_view.empty())
    fail("give the context views or the reference view, not both (the context's first view is the reference)");
  std::optional<int> reference;
  if (!options.reference_view.empty()) reference = input_view_index(scene, options.reference_view, "reference view");
  out.context = options.context.empty() ? select_context_views(scene, options.num_views, reference)
                                        : context_views_by_name(scene, options.context);
  out.views = prepare_masked_views(scene, out.context, options, "context view");

  PreparedView& ref = out.views[0];
  const View& ref_view = scene.views[out.context[0]];
  if (options.keep_object) {
    // Plain reconstruction: photos as they are, empty masks (the stage-1 input).
    for (PreparedView& v : out.views) v.mask = Image(v.rgb.width, v.rgb.height, 1);
    out.reference_source = "photo (object kept)";
  } else if (options.reference_image) {
    ref.rgb = reference_at_working_size(*options.reference_image, "reference image in memory", ref_view, ref,
                                        options.preprocess);
    out.reference_source = "image in memory";
  } else if (options.reference) {
    ref.rgb = reference_at_working_size(read_image_rgb(*options.reference), options.reference->string(), ref_view,
                                        ref, options.preprocess);
    out.reference_source = options.reference->string();
  } else {
    if (!ref.mask)
      fail("no --reference image given and reference view {} has no mask to inpaint", ref.name);
    spdlog::warn("no --reference given: inpainting view {} with OpenCV's {} method; a learned "
                 "2D inpainter gives much better results",
                 ref.name, options.inpainter == ClassicalInpainter::Telea ? "Telea" : "Navier-Stokes");
    ref.rgb = inpaint_classical(ref.rgb, *ref.mask, options.inpainter);
    out.reference_source = inpainter_name(options.inpainter);
  }
  out.normalization = scene_normalization(scene);
  out.input = build_model_input(out.views, out.normalization);
  return out;
}

}  // namespace ii
