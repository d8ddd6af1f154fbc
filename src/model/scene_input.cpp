#include "model/scene_input.h"

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "data/image_ops.h"
#include "data/inpaint2d.h"
#include "data/view_selection.h"

namespace ii {

PoseNormalization scene_normalization(const Scene& scene) {
  std::vector<Camera> cameras;
  for (const auto* list : {&scene.views, &scene.test_views})
    for (const View& v : *list) cameras.push_back(v.camera);
  return fit_pose_normalization(cameras);
}

namespace {

// The reference image may come at the source image's size (preprocessed like the view) or
// already at the working size.
Image reference_at_working_size(const std::filesystem::path& file, const View& view,
                                const PreparedView& prepared, const PreprocessOptions& options) {
  const Image image = read_image_rgb(file);
  const int sw = view.camera.K.width, sh = view.camera.K.height;
  if (image.width == sw && image.height == sh)
    return to_working_size(image, working_size(sw, sh, options));
  if (image.width == prepared.rgb.width && image.height == prepared.rgb.height) return image;
  fail_file(file,
            "reference image is {}x{}, but view {} is {}x{} (working size {}x{}): give the "
            "inpainted image at either size",
            image.width, image.height, view.name, sw, sh, prepared.rgb.width, prepared.rgb.height);
}

}  // namespace

SceneInput prepare_scene_input(const Scene& scene, const SceneInputOptions& options) {
  SceneInput out;
  out.context = options.context.empty() ? select_context_views(scene, options.num_views)
                                        : context_views_by_name(scene, options.context);
  for (int index : out.context) {
    const View& view = scene.views[index];
    if (!options.keep_object && &view != &scene.views[out.context[0]] && !view.mask_path && !view.mask_from_alpha)
      fail("view {} has no object mask: give masks for every context view (--masks DIR or "
           "--alpha-masks)", view.name);
    out.views.push_back(prepare_view(view, options.preprocess));
  }

  PreparedView& ref = out.views[0];
  const View& ref_view = scene.views[out.context[0]];
  if (options.keep_object) {
    // Plain reconstruction: photos as they are, empty masks (the stage-1 input).
    for (PreparedView& v : out.views) v.mask = Image(v.rgb.width, v.rgb.height, 1);
    out.reference_source = "photo (object kept)";
  } else if (options.reference) {
    ref.rgb = reference_at_working_size(*options.reference, ref_view, ref, options.preprocess);
    out.reference_source = options.reference->string();
  } else {
    if (!ref.mask)
      fail("no --reference image given and reference view {} has no mask to inpaint", ref.name);
    spdlog::warn("no --reference given: inpainting view {} with OpenCV's Telea method; a learned "
                 "2D inpainter gives much better results",
                 ref.name);
    ref.rgb = inpaint_telea(ref.rgb, *ref.mask);
    out.reference_source = "telea";
  }
  out.normalization = scene_normalization(scene);
  out.input = build_model_input(out.views, out.normalization);
  return out;
}

}  // namespace ii
