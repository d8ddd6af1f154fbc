#include "edit/scene_masks.h"

#include <algorithm>
#include <cmath>

#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include "common/error.h"
#include "common/stopwatch.h"
#include "data/masks.h"
#include "data/view_selection.h"
#include "edit/box_select.h"

namespace ii {

namespace {

const View& marked_view(const Scene& scene, const std::string& name) {
  return scene.views[static_cast<size_t>(input_view_index(scene, name))];
}

// Which pixels of depth maps (1, V, 1, H, W) lie at an edge: a neighbour (of 8) this far off in
// log depth. Their Gaussians float between the two sides and would join an object to what lies
// behind it; flattened as gaussians_from_maps flattens. Leaving them out: scene 1 from the true
// mask, carved 0.984 / 0.909 -> 0.985 / 0.929 (with near_object 0.02).
constexpr double kEdgeJump = 0.05;
torch::Tensor at_depth_edges(const torch::Tensor& depth) {
  const torch::Tensor d = depth[0].select(1, 0).to(torch::kFloat).clamp_min(1e-6).log();  // (V, H, W), on its device
  const torch::Tensor padded = torch::constant_pad_nd(d.unsqueeze(1), {1, 1, 1, 1}, 0).squeeze(1);
  const int64_t H = d.size(1), W = d.size(2);
  torch::Tensor jump = torch::zeros_like(d);
  for (int dy = 0; dy <= 2; ++dy)
    for (int dx = 0; dx <= 2; ++dx) {
      const torch::Tensor n = padded.slice(1, dy, dy + H).slice(2, dx, dx + W);
      jump = torch::maximum(jump, (n - d).abs());
    }
  // The frame's border compares with the padding: not an edge.
  torch::Tensor edge = jump.gt(kEdgeJump);
  edge.select(1, 0).zero_(), edge.select(1, H - 1).zero_(), edge.select(2, 0).zero_(), edge.select(2, W - 1).zero_();
  return edge.reshape({-1});
}

// Enough depth samples for every region: a sparse source that misses a region is passed over.
constexpr int kMinDepthSamples = 5;

}  // namespace

Image read_region_mask(const std::filesystem::path& file, const View& view) {
  const ImageInfo info = probe_image(file);
  if (info.width != view.camera.K.width || info.height != view.camera.K.height)
    fail_file(file, "the mask is {}x{} but view {} is {}x{}", info.width, info.height, view.name,
              view.camera.K.width, view.camera.K.height);
  Image mask = read_mask(file);
  if (std::none_of(mask.pixels.begin(), mask.pixels.end(), [](float v) { return v > 0.5f; }))
    fail_file(file, "the mask is empty: mark the region in white");
  return mask;
}

std::optional<Image> colmap_points_depth(const Scene& scene, const View& view) {
  const std::vector<Eigen::Vector3d> points = load_scene_points(scene);
  if (points.empty()) return std::nullopt;
  return points_depth(points, view.camera);
}

Image depth_at_image_size(const torch::Tensor& working_depth, double normalization_scale, const View& view,
                          const PreprocessOptions& preprocess) {
  // z-depth scales with the pose normalisation; the working image is the view resized, then cropped.
  const torch::Tensor working = (working_depth.to(torch::kCPU, torch::kFloat) * normalization_scale).contiguous();
  const int W = view.camera.K.width, H = view.camera.K.height;
  const WorkingSize ws = working_size(W, H, preprocess);
  if (working.dim() != 2 || working.size(0) != ws.height || working.size(1) != ws.width)
    fail("depth of view {}: {} at the working size {}x{} expected", view.name,
         working.dim() == 2 ? fmt::format("{}x{}", working.size(1), working.size(0))
                            : fmt::format("a {}-dimensional map", working.dim()),
         ws.width, ws.height);
  const auto d = working.accessor<float, 2>();
  Image depth(W, H, 1);
  for (int y = 0; y < H; ++y) {
    const long wy = std::lround((y + 0.5) * ws.resized_height / H - 0.5) - ws.crop_y;
    if (wy < 0 || wy >= ws.height) continue;
    for (int x = 0; x < W; ++x) {
      const long wx = std::lround((x + 0.5) * ws.resized_width / W - 0.5) - ws.crop_x;
      if (wx >= 0 && wx < ws.width) depth.at(y, x) = d[wy][wx];
    }
  }
  return depth;
}

ViewReconstruction predicted_view_reconstruction(const Predictor& predictor, const Scene& scene,
                                                 const std::string& view, const SceneInputOptions& options,
                                                 StageTimes* stages, int64_t max_points) {
  const View& marked = marked_view(scene, view);
  SceneInputOptions o;
  o.num_views = options.num_views;
  o.preprocess = options.preprocess;
  o.reference_view = view;
  o.keep_object = true;
  o.view_cache = options.view_cache;
  // The photos' points scale the depth where a capture has nothing better, but not for lifting
  // the mark: on the statue its masks lost precision (mean 0.562 -> 0.536, recall 1.0 both).
  o.geometry.align_depth =
      options.geometry.align_depth == DepthPoints::photos ? DepthPoints::depth_maps : options.geometry.align_depth;
  o.geometry.depth_detail = options.geometry.depth_detail;
  o.geometry.frame_margin.fraction = 0;  // only the context views' own pixels are read
  o.geometry.behind_edges.fraction = 0;
  o.geometry.floaters.fade = 1;          // (nor its opacities)
  o.geometry.region_cover.opacity = 0;
  o.geometry.region_surface.opacity = 0;  // the region's depth is the object's here
  const Prediction p = predictor.predict(scene, o);
  Stopwatch watch;
  ViewReconstruction out;
  out.depth = depth_at_image_size(p.maps().depth[0][0][0], p.input.normalization.scale, marked, o.preprocess);
  if (stages) {
    stages->merge(p.stages, "masks: ");
    stages->add("masks: depth map", watch.ms());
  }
  if (max_points > 0) {
    watch = Stopwatch();
    const GaussianSet g = in_scene_frame(gaussians_from_maps(p.maps()), p.input.normalization);
    const torch::Tensor opaque =
        g.opacities.reshape({-1}).gt(0.5).logical_and(at_depth_edges(p.maps().depth).logical_not()).nonzero().squeeze(1);
    const int64_t step = std::max<int64_t>(1, (opaque.numel() + max_points - 1) / max_points);
    static_cast<ColouredPoints&>(out) = coloured_points(g, opaque.slice(0, 0, opaque.numel(), step));
    if (stages) stages->add("masks: the reconstruction's points", watch.ms());
  }
  return out;
}

ColouredPoints coloured_points(const GaussianSet& g, const torch::Tensor& rows) {
  const torch::Tensor means = g.means.index_select(0, rows).to(torch::kCPU, torch::kDouble).contiguous();
  const torch::Tensor rgb = (g.sh_degree < 0 ? g.colors.index_select(0, rows)
                                             : rgb_from_sh_dc(g.colors.index_select(0, rows).select(1, 0)))
                                .to(torch::kCPU, torch::kFloat)
                                .contiguous();
  const auto m = means.accessor<double, 2>();
  const auto c = rgb.accessor<float, 2>();
  ColouredPoints out;
  out.points.reserve(static_cast<size_t>(means.size(0)));
  out.colours.reserve(static_cast<size_t>(means.size(0)));
  for (int64_t i = 0; i < means.size(0); ++i) {
    out.points.emplace_back(m[i][0], m[i][1], m[i][2]);
    out.colours.emplace_back(c[i][0], c[i][1], c[i][2]);
  }
  return out;
}

ColouredPoints opaque_points(const GaussianSet& g) {
  // In float32 whatever the network's type (bf16 on a GPU): the colours compared are the same.
  const torch::Tensor opacities = g.opacities.to(torch::kCPU, torch::kFloat32).reshape({-1});
  GaussianSet f = g;
  f.means = g.means.to(torch::kCPU, torch::kFloat32);
  f.colors = g.colors.to(torch::kCPU, torch::kFloat32);
  return coloured_points(f, opacities.gt(0.5).nonzero().squeeze(1));
}

SceneInputOptions scene_reconstruction_options(const SceneInputOptions& options) {
  SceneInputOptions o;
  o.preprocess = options.preprocess;
  o.num_views = options.num_views;
  o.keep_object = true;
  o.view_cache = options.view_cache;
  o.geometry = options.geometry;
  return o;
}

ClickedOutline outline_of_clicks(const View& view, const Camera& camera, const ColouredPoints& points,
                                 const std::vector<Click>& clicks, std::optional<double> scene_far,
                                 const SelectOptions& selecting, const CarveOptions& carving) {
  SelectOptions o = selecting;
  if (!o.scene_far) o.scene_far = scene_far;
  ClickedOutline out;
  out.selected = select_objects(camera, view.name, points.points, points.colours, clicks, o);
  out.mask = selection_masks({camera}, [&](size_t) { return load_view_image(view); }, points.points, out.selected, o,
                             carving)[0]
                 .mask;
  return out;
}

Image predicted_view_depth(const Predictor& predictor, const Scene& scene, const std::string& view,
                           const SceneInputOptions& options, StageTimes* stages) {
  return predicted_view_reconstruction(predictor, scene, view, options, stages, 0).depth;
}

nlohmann::json SceneMasks::describe(const OneMask& request) const {
  nlohmann::json regions_json = nlohmann::json::array();
  for (const LiftedRegion& r : regions)
    regions_json.push_back({{"pixels", r.pixels},
                            {"depth_inside", r.depth_inside},
                            {"depth_ring", r.depth_ring},
                            {"near", r.near},
                            {"far", r.far}});
  nlohmann::json out = {{"view", request.view},
          {"mode", edit_mode_name(request.propagation.mode)},
          {"depth_source", depth_source},
          {"notes", notes},
          {"regions", regions_json},
          {"carved", carved}};
  if (request.box) out["box"] = *request.box;
  if (!request.clicks.empty() || request.box) {
    nlohmann::json clicks = nlohmann::json::array(), not_clicks = nlohmann::json::array();
    for (const Click& c : request.clicks) clicks.push_back({c.x, c.y});
    for (const Click& c : request.not_clicks) not_clicks.push_back({c.x, c.y});
    if (!clicks.empty()) out["clicks"] = clicks;
    if (!not_clicks.empty()) out["not_clicks"] = not_clicks;
    out["clicked_mask"] = clicked_mask;
    if (!segmenter.is_null()) out["segmenter"] = segmenter;
    if (!request.segmenter && !request.box) {
      out["selected_points"] = selected;
      out["points"] = points;
    }
  }
  return out;
}

void SceneMasks::apply_to(SceneInputOptions& options, const OneMask& request) const {
  options.masks = masks;
  if (!options.inpaint_grow && (!request.clicks.empty() || request.box)) options.inpaint_grow = kSelectionInpaintGrow;
  if (options.reference_view.empty() && options.context.empty()) options.reference_view = request.view;
}

namespace {

// Each view's propagated mask (not the marked one's) carved to the object inside it: the
// reconstruction's points on the marked view's surface inside the lifted volume are the object's.
void carve_to_the_object(const Scene& scene, const OneMask& request, const PropagatedMasks& lifted,
                         const ViewReconstruction& reconstruction, StageTimes& times, SceneMasks& out) {
  const View& marked = marked_view(scene, request.view);
  const std::vector<PointRole> roles =
      point_roles(lifted, reconstruction.depth, marked.camera, reconstruction.points, request.carving);
  std::vector<const View*> views;
  std::vector<Image> masks;
  std::vector<Camera> cameras;
  for (const View& v : scene.views) {
    if (v.name == marked.name) continue;
    views.push_back(&v);
    masks.push_back(out.masks.at(v.name));
    cameras.push_back(v.camera);
  }
  const std::vector<CarvedMask> carved = times.time("masks: carve (with the photos)", [&] {
    return carve_masks(masks, [&](size_t i) { return load_view_image(*views[i]); }, cameras, reconstruction.points,
                       roles, request.carving);
  });
  for (size_t i = 0; i < carved.size(); ++i) {
    out.masks[views[i]->name] = carved[i].mask;
    out.carved += carved[i].carved;
  }
}

// The view's photo, at its camera's size.
Image view_photo(const View& view) {
  Image photo = load_view_image(view);
  if (photo.width != view.camera.K.width || photo.height != view.camera.K.height)
    fail("view {}: its photo is {}x{}, its camera {}x{}", view.name, photo.width, photo.height, view.camera.K.width,
         view.camera.K.height);
  return photo;
}

}  // namespace

ClickedMask segmented_view_mask(const Segmenter& segmenter, const View& view, const std::vector<Click>& clicks,
                                const std::vector<Click>& not_clicks, StageTimes* stages,
                                const std::optional<ViewBox>& box) {
  check_clicks_inside(view.camera, view.name, clicks, not_clicks);
  if (box) check_box(view.name, view.camera.K.width, view.camera.K.height, *box, clicks, true);
  const Image photo = view_photo(view);
  try {
    return box ? mask_from_prompt(segmenter, photo, clicks, not_clicks, box, stages)
               : mask_from_clicks(segmenter, photo, clicks, not_clicks, stages);
  } catch (const Error& e) {
    fail("view {}: {}", view.name, e.what());
  }
}

namespace {

// The marked view's region that a prompt makes, and how: the segmenter's mask for the clicks and
// the box; GrabCut's in the box; or the clicked objects' outline in the scene's reconstruction, as
// the page draws it.
struct PromptedRegion {
  Image region;
  std::string how;  // SceneMasks::clicked_mask
  nlohmann::json segmenter;
  int64_t selected = 0, points = 0;  // the clicks' selection in the reconstruction
};

PromptedRegion prompted_region(const Scene& scene, const View& marked, const OneMask& request,
                               const PredictorSource& predictor, const SceneInputOptions& options, StageTimes* stages) {
  StageTimes unrecorded;
  StageTimes& times = stages ? *stages : unrecorded;
  PromptedRegion out;
  if (request.segmenter) {
    const ClickedMask clicked =
        segmented_view_mask(*request.segmenter, marked, request.clicks, request.not_clicks, stages, request.box);
    out.region = clicked.mask;
    out.how = "segmenter";
    out.segmenter = clicked.describe(*request.segmenter);
    return out;
  }
  check_clicks_inside(marked.camera, marked.name, request.clicks, request.not_clicks);
  if (request.box) {
    check_box(marked.name, marked.camera.K.width, marked.camera.K.height, *request.box, request.clicks, false);
    out.region = times.time("masks: GrabCut in the box", [&] {
      return object_in_box(view_photo(marked), marked.name, *request.box, request.clicks, request.not_clicks);
    });
    out.how = "GrabCut in the box";
    return out;
  }
  if (!predictor) fail("a click on view {} needs the network's reconstruction, and no model was given", marked.name);
  const Prediction p = predictor().predict(scene, scene_reconstruction_options(options));
  times.merge(p.stages, "masks: the scene's reconstruction: ");
  const PoseNormalization& n = p.input.normalization;
  const ClickedOutline outline = times.time("masks: select and outline", [&] {
    const ColouredPoints points = opaque_points(p.gaussians());
    const std::optional<double> far = scene.far ? std::optional<double>(*scene.far / n.scale) : std::nullopt;
    return outline_of_clicks(marked, n.apply(marked.camera), points, request.clicks, far, request.selecting,
                             request.carving);
  });
  out.region = outline.mask;
  out.how = "colour growth over the reconstruction";
  out.selected = std::count(outline.selected.begin(), outline.selected.end(), uint8_t{1});
  out.points = static_cast<int64_t>(outline.selected.size());
  return out;
}

}  // namespace

SceneMasks masks_from_one(const Scene& scene, const OneMask& request, const PredictorSource& predictor,
                          const SceneInputOptions& options, StageTimes* stages) {
  StageTimes unrecorded;
  StageTimes& times = stages ? *stages : unrecorded;
  const View& marked = marked_view(scene, request.view);
  std::vector<Camera> cameras;
  for (const View& v : scene.views) cameras.push_back(v.camera);

  if (!request.clicks.empty() || request.box) {
    // The region the prompt makes on the marked view, lifted (and carved, as the request says: on
    // by default) as a drawn one.
    const PromptedRegion prompted = prompted_region(scene, marked, request, predictor, options, stages);
    OneMask drawn = request;
    drawn.clicks.clear();
    drawn.not_clicks.clear();
    drawn.box.reset();
    drawn.segmenter = nullptr;
    drawn.region = prompted.region;
    SceneMasks out = masks_from_one(scene, drawn, predictor, options, stages);
    out.clicked_mask = prompted.how;
    out.segmenter = prompted.segmenter;
    out.selected = prompted.selected;
    out.points = prompted.points;
    return out;
  }
  SceneMasks out;
  auto lift = [&](const Image& depth, double margin, bool pixel_depth) {
    PropagationOptions o = request.propagation;
    o.depth_margin = request.depth_margin.value_or(margin);
    o.pixel_depth = pixel_depth;
    return times.time("masks: propagate", [&] { return propagate_mask(request.region, depth, marked.camera, cameras, o); });
  };
  auto finish = [&](const PropagatedMasks& p, std::string source) {
    for (size_t i = 0; i < scene.views.size(); ++i) out.masks[scene.views[i].name] = p.masks[i];
    Image exact = request.region;
    for (float& v : exact.pixels) v = v > 0.5f ? 1.f : 0.f;
    out.masks[marked.name] = exact;
    out.regions = p.regions;
    out.depth_source = std::move(source);
    return out;
  };

  if (request.depth_file) {
    const Image depth = read_depth_map(*request.depth_file, marked.camera.K.width, marked.camera.K.height,
                                       request.depth_png_scale);
    return finish(lift(depth, kFileDepthMargin, true), "file " + request.depth_file->string());
  }
  if (const auto sparse = times.time("masks: colmap points", [&] { return colmap_points_depth(scene, marked); })) {
    try {
      const PropagatedMasks p = lift(*sparse, kColmapDepthMargin, true);
      const bool enough = std::all_of(p.regions.begin(), p.regions.end(), [](const LiftedRegion& r) {
        return r.depth_inside + r.depth_ring >= kMinDepthSamples;
      });
      if (enough) return finish(p, "colmap points");
      out.notes.push_back(fmt::format("fewer than {} COLMAP points fall in a region or on its ring", kMinDepthSamples));
    } catch (const Error& e) {
      out.notes.push_back(fmt::format("COLMAP points: {}", e.what()));
    }
  }
  if (request.working_depth) {
    const Image depth = times.time("masks: depth map", [&] {
      return depth_at_image_size(*request.working_depth, scene_normalization(scene).scale, marked, options.preprocess);
    });
    return finish(lift(depth, kNetworkDepthMargin, false), request.working_depth_source);
  }
  if (!predictor)
    fail("no depth for view {}: give a depth map (--depth), a scene with COLMAP points, or let the network "
         "reconstruct it{}",
         marked.name, out.notes.empty() ? "" : fmt::format(" ({})", fmt::join(out.notes, "; ")));
  for (const std::string& note : out.notes) spdlog::info("{}: using the network's depth", note);
  // Carving cuts to an object that is there: not for an insertion.
  const bool carve = request.carve && request.propagation.mode == EditMode::Remove;
  const ViewReconstruction reconstruction = predicted_view_reconstruction(
      predictor(), scene, marked.name, options, stages, carve ? kReconstructionPoints : 0);
  const PropagatedMasks lifted = lift(reconstruction.depth, kNetworkDepthMargin, false);
  finish(lifted, "network");
  if (carve && !reconstruction.points.empty())
    carve_to_the_object(scene, request, lifted, reconstruction, times, out);
  return out;
}

}  // namespace ii
