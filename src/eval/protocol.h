#pragma once
// The SPIn-NeRF evaluation protocol: for a scene with object-free test views (LLFF/SPIn-NeRF
// layout, `images_K/test_label/`), predict the scene without the object, render every test
// view at the working size of the official evaluation (spec §5.3: 512 rows, width centre-
// cropped to a multiple of the patch; masks nearest), and compare with its ground truth.
//
// Predictions ("methods"):
//  * model      — Gaussians from the network on the context views (a checkpoint), or read
//                 from a splat PLY in the pose-normalised frame (as `infer` writes them; this
//                 also evaluates other methods' splats). Rendered with the scene's cameras
//                 normalised over all cameras (spec §5.1), white background.
//  * telea      — each test view's masked region filled by OpenCV Telea inpainting of that
//                 view's own ground truth (a 2D baseline).
//  * mean-fill  — the masked region filled with the mean ground-truth colour of a ring around
//                 the mask (the trivial baseline).
// Every prediction is quantised to 8 bits (as the official pipeline saves its renders) and
// goes through the same metrics: PSNR, SSIM, masked and bounding-box variants, LPIPS (VGG)
// and masked LPIPS, FID/KID and the crop variants C-FID/C-KID (see metrics.h, lpips.h,
// fid.h). Metrics whose weights are not supplied are reported as unavailable, with why.
//
// Writes OUT/metrics.json, OUT/report.html, OUT/renders/<view>.png and OUT/sheets/<view>.png
// (ground truth | prediction | error map | mask outline).
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "data/scene.h"
#include "edit/scene_masks.h"
#include "eval/metrics.h"
#include "model/network.h"
#include "predict/predictor.h"

namespace ii {

// floor and sticker are the insertion baselines (scenes from `synth --task insert`): the test
// view with nothing inserted (original/), and that view with the reference's edit region
// pasted flat at the background depth.
enum class EvalMethod { model, telea, mean_fill, floor, sticker };
const char* eval_method_name(EvalMethod method);  // "model", "telea", "mean-fill", "floor", "sticker"
EvalMethod parse_eval_method(const std::string& name);  // throws on anything else

struct EvalOptions {
  std::filesystem::path scene_dir;
  SceneOptions scene;
  std::filesystem::path out;
  EvalMethod method = EvalMethod::model;

  // method model: exactly one of these.
  std::optional<std::filesystem::path> checkpoint;
  std::optional<std::filesystem::path> gaussians;  // a splat file in the scene's frame (infer's, a 3DGS trainer's)
  bool gaussians_normalized = false;               // ... in the pose-normalised frame (infer --normalized)
  // Network inputs (checkpoint only).
  std::vector<std::string> context;  // reference first; empty = automatic
  int num_views = 4;
  std::optional<std::filesystem::path> reference;  // 2D-inpainted reference (default: `inpainter`)
  Inpainter inpainter;
  std::optional<double> inpaint_grow;  // see InputOptions::inpaint_grow
  std::string reference_view;   // automatic context around this reference (default: the edit's view)
  std::optional<OneMask> edit;  // one marked view instead of the scene's masks
  bool keep_object = false;     // a reconstruction: no masks, the reference's own photo
  GeometryOptions geometry;     // SceneInputOptions::geometry
  // Applied to the network's Gaussians before rendering (e.g. refinement, which lives above
  // eval): given the scene, the prediction and its input options; fills `report`.
  std::function<GaussianSet(const Scene&, const Prediction&, const SceneInputOptions&, GaussianSet, nlohmann::json& report)>
      after_prediction;
  Precision precision = Precision::Float32;
  int sh_degree = 3;  // highest SH degree used from a PLY

  int height = 512;  // working height (the official evaluation: 512)
  // How predictions become 8-bit: "round" (default; as PNG writers do), "truncate" (the
  // official metric_output images, matplotlib's float→uint8), "none" (keep floats; the ground
  // truth is then not quantised either).
  std::string quantize = "round";
  int ring_width = 8;  // mean-fill: ring width in working-size pixels

  // Metric weights (absent: $INSTAINPAINT_LPIPS_VGG, $INSTAINPAINT_LPIPS_ALEX,
  // $INSTAINPAINT_FID_INCEPTION; still absent: the metric is unavailable).
  std::optional<std::filesystem::path> lpips_vgg, lpips_alex, lpips_heads_dir, inception;

  torch::Device device = torch::kCPU;  // network, rendering, metrics
  bool write_report = true;
};

// Runs the protocol and writes OUT; returns the content of metrics.json.
nlohmann::json run_evaluation(const EvalOptions& options);

// Mean-fill baseline on one image: pixels with mask > 0.5 set to the mean colour of the ring
// of pixels within `ring_width` (Chebyshev distance) outside the mask; the rest unchanged. An
// empty ring (mask everywhere) fills grey 0.5.
Image mean_fill(const Image& rgb, const Image& mask, int ring_width);

// The "sticker" an insertion without 3D gives: every `region` pixel of the reference image,
// placed at its `depth` (z-depth of the reference view's background; 0 = unknown, skipped) and
// projected into `view` over `floor` (nearest surface wins; each pixel covers 2x2 pixels so
// that a view nearer than the reference shows no holes). All images at their camera's size.
Image sticker_view(const Image& floor, const Camera& view, const Image& reference, const Image& region,
                   const Image& depth, const Camera& reference_camera);

// Square crop around a mask for C-FID/C-KID: centred on the mask's bounding box, side 1.2 ×
// its longer side (at least 16 px), shifted to lie inside the image and at most its shorter
// side. nullopt for an empty mask.
std::optional<PixelBox> crop_around_mask(const Image& mask);

// 8-bit quantisation as EvalOptions::quantize describes ("round", "truncate", "none"), of
// images in [0,1] on any device; rounding is half away from zero like the PNG writer's.
torch::Tensor quantize_image(const torch::Tensor& images, const std::string& mode);
Image quantize_image(const Image& image, const std::string& mode);

}  // namespace ii
