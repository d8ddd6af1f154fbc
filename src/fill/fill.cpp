#include "fill/fill.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>

#include "common/error.h"
#include "common/torch.h"
#include "data/image_ops.h"
#include "data/inpaint2d.h"
#include "data/masks.h"
#include "data/preprocess.h"
#include "gaussians/gaussians.h"
#include "geometry/continued_depth.h"
#include "geometry/depth_alignment.h"
#include "geometry/surface_splats.h"
#include "geometry/visibility.h"
#include "model/device.h"
#include "render/projection.h"
#include "render/rasterizer.h"
#include "tensor/image_tensor.h"

namespace ii {

namespace {

// A kept surface in the hole continues its border's when it lies at most this share farther.
constexpr double kContinuedTolerance = 0.06;
// A pixel belongs to the hole when the region made at least this share of it.
constexpr float kHoleShare = 0.1f;

std::string bounds_text(const std::pair<Eigen::Vector3d, Eigen::Vector3d>& b) {
  return fmt::format("x {:.4g} to {:.4g}, y {:.4g} to {:.4g}, z {:.4g} to {:.4g}", b.first.x(), b.second.x(),
                     b.first.y(), b.second.y(), b.first.z(), b.second.z());
}

SplatCloud rows_of(const SplatCloud& cloud, const RegionMask& take) {
  SplatCloud out;
  const int rest = cloud.sh_rest_per_channel;
  const size_t n = static_cast<size_t>(region_count(take));
  out.resize(n, rest);
  if (!cloud.normals.empty()) out.normals.resize(n * 3);
  size_t k = 0;
  for (size_t i = 0; i < cloud.size(); ++i) {
    if (!take[i]) continue;
    auto copy = [&](const std::vector<float>& from, std::vector<float>& to, size_t width) {
      std::copy_n(from.begin() + static_cast<std::ptrdiff_t>(i * width), width, to.begin() + static_cast<std::ptrdiff_t>(k * width));
    };
    copy(cloud.means, out.means, 3);
    if (!cloud.normals.empty()) copy(cloud.normals, out.normals, 3);
    copy(cloud.sh_dc, out.sh_dc, 3);
    copy(cloud.sh_rest, out.sh_rest, 3 * static_cast<size_t>(rest));
    copy(cloud.opacity_logit, out.opacity_logit, 1);
    copy(cloud.log_scales, out.log_scales, 3);
    copy(cloud.rotations, out.rotations, 4);
    ++k;
  }
  return out;
}

RegionMask kept_flags(const RegionMask& region) {
  RegionMask keep(region.size());
  for (size_t i = 0; i < region.size(); ++i) keep[i] = !region[i];
  return keep;
}

// `added` (DC colour only) after `cloud`'s rows, with zero higher SH coefficients and normals.
void append_rows(SplatCloud& cloud, const SplatCloud& added) {
  const size_t n = cloud.size(), m = added.size();
  const int rest = cloud.sh_rest_per_channel;
  auto extend = [](std::vector<float>& to, const std::vector<float>& from) { to.insert(to.end(), from.begin(), from.end()); };
  extend(cloud.means, added.means);
  extend(cloud.sh_dc, added.sh_dc);
  extend(cloud.opacity_logit, added.opacity_logit);
  extend(cloud.log_scales, added.log_scales);
  extend(cloud.rotations, added.rotations);
  cloud.sh_rest.resize((n + m) * 3 * static_cast<size_t>(rest), 0.f);
  if (!cloud.normals.empty()) cloud.normals.resize((n + m) * 3, 0.f);
}

// A camera's render of the whole scene (cameras.h): what it saw of the surfaces behind the region.
using Observer = Sight;

Observer observe(const GaussianSet& scene, const Camera& camera, torch::Tensor* rgb = nullptr) {
  const RenderOutput out = render(scene, {camera});
  if (rgb) *rgb = out.rgb.clamp(0, 1).to(torch::kCPU);
  return {camera, out.depth.squeeze(2).to(torch::kCPU).contiguous(), out.alpha.squeeze(2).to(torch::kCPU).contiguous(), {}, {}, {}, {}};
}

// What an observer saw, where it drew something.
SeenDepth seen_depth(const Observer& o) { return {o.camera, o.depth, o.alpha > 0.5}; }

struct CameraViews {
  Image before, kept, mask;
  torch::Tensor kept_depth, kept_alpha;  // (H, W) on the CPU, scene units
  torch::Tensor share;                   // (H, W): the region's share of each pixel
  Observer whole;                        // the whole scene seen from this camera
};

// One camera: the whole scene, the scene without the region (the network's input and the
// depth to align with), and the region's share of each pixel. With a `window` (the region's in
// this camera), `scene` and `weights` hold only the splats that reach it and the whole scene
// outside it is the kept one's: the region draws nothing there.
CameraViews render_camera(const GaussianSet& scene, const GaussianSet& kept, const GaussianSet& weights,
                          const Camera& camera, const std::optional<PixelWindow>& window = std::nullopt) {
  CameraViews v;
  const RenderOutput k = render(kept, {camera});
  v.kept = image_from_hwc(k.rgb.clamp(0, 1).to(torch::kCPU));
  v.kept_depth = k.depth.squeeze(2).to(torch::kCPU).contiguous();
  v.kept_alpha = k.alpha.squeeze(2).to(torch::kCPU).contiguous();
  RenderOutput w = render(scene, {camera});
  if (window) {
    w.rgb = pasted(k.rgb, w.rgb, *window);
    w.depth = pasted(k.depth, w.depth, *window);
    w.alpha = pasted(k.alpha, w.alpha, *window);
  }
  v.before = image_from_hwc(w.rgb.clamp(0, 1).to(torch::kCPU));
  v.whole = {camera, w.depth.squeeze(2).to(torch::kCPU).contiguous(), w.alpha.squeeze(2).to(torch::kCPU).contiguous(), {}, {}, {}, {}};
  RenderOptions black;
  black.background = {0.f, 0.f, 0.f};
  v.share = render(weights, {camera}, black).rgb.select(2, 0).to(torch::kCPU);
  return v;
}

// The hole in view `self`: where the region was seen and what is behind it now was never seen
// by any other camera (it lay under or inside the object: a table top under a vase, the inside
// of what remains), or where nothing is behind it. What other cameras saw behind the region (the
// floor behind a chair) is right already and stays as the network's input. Grown 2 px.
Image hole_mask(const CameraViews& self, const std::vector<const Observer*>& others) {
  const Camera& c = self.whole.camera;
  const torch::Tensor region = self.share > kHoleShare;
  torch::Tensor hole = region.logical_and(self.kept_alpha < 0.5);
  const torch::Tensor pixels = region.logical_and(self.kept_alpha >= 0.5).nonzero();
  if (pixels.size(0) > 0) {
    const torch::Tensor d = self.kept_depth.index({pixels.select(1, 0), pixels.select(1, 1)});
    const torch::Tensor world = unproject(c, pixels.select(1, 0), pixels.select(1, 1), d);
    torch::Tensor seen = torch::zeros({pixels.size(0)}, torch::kBool);
    for (const Observer* o : others) seen.logical_or_(on_seen_surface(world, seen_depth(*o), kSeenTolerance));
    hole.index_put_({pixels.select(1, 0), pixels.select(1, 1)}, seen.logical_not());
  }
  return dilate_mask(image_from_hwc(hole.to(torch::kFloat32).unsqueeze(2)), 1, 5);
}

// Which new splats (world positions, N x 3 float64) of view `self` hide nothing another view saw:
// a splat that lands outside that view's hole in front of the surface it shows there would cover
// what was seen (a floater of a depth the network got wrong), and is left out. With the
// capture's own cameras, so is one in front of what any of them saw, the region included: space
// a photo saw through is empty (on a capture all round its object, the surface continued
// inward from one side stood as a sheet in the air from the others).
torch::Tensor in_no_ones_way(const torch::Tensor& points, const std::vector<CameraViews>& views, size_t self,
                             const ChosenCameras& cameras) {
  std::vector<SeenDepth> seen;
  for (const CameraViews& v : views)
    seen.push_back({v.whole.camera, v.kept_depth,
                    (image_to_tensor(v.mask)[0][0] <= 0.5).logical_and(v.kept_alpha > 0.5)});
  torch::Tensor through = seen_through(points, seen, kSeenTolerance, static_cast<int64_t>(self));
  if (cameras.captured) {
    std::vector<SeenDepth> empty_space;
    for (const Sight& s : cameras.sights) {
      const torch::Tensor usable = drawn_whole(s);
      empty_space.push_back({s.camera, s.depth, usable});
      // ... and in front of a surface seen behind the region (the floor behind an object is
      // seen from its other sides: nothing new stands in the object's place)
      if (s.kept_depth.defined()) empty_space.push_back({s.camera, s.kept_depth, s.kept_seen.logical_and(usable)});
    }
    through = through.logical_or(seen_through(points, empty_space, kSeenTolerance));
  }
  return through.logical_not();
}

// The factor that brings the network's depth (normalised units) to the scene's around the hole:
// the median ratio of the rendered depth to the predicted one over a ring of seen pixels
// around the mask (the whole seen view when the ring is empty; 1 when nothing is seen).
double depth_scale(const CameraViews& v, const torch::Tensor& predicted_depth, double normalization_scale) {
  const torch::Tensor mask = image_to_tensor(v.mask)[0][0] > 0.5;
  const torch::Tensor ring = image_to_tensor(dilate_mask(v.mask, 4, 5))[0][0] > 0.5;
  const torch::Tensor seen = v.kept_alpha > 0.5;
  return median_depth_ratio(v.kept_depth, predicted_depth.to(torch::kCPU) * normalization_scale,
                            {ring.logical_and(mask.logical_not()).logical_and(seen), seen});
}

// A reference painted on a given camera's full-size view comes to the working size as a photo
// would; one at the working size is taken as it is, and so is one at the official evaluation's
// working size of that view (904x512 for a 1008x567 capture).
Image reference_at_working_size(const Image& reference, const FillOptions& options, const ChosenCameras& chosen) {
  const NamedCamera& working = chosen.cameras.at(0);
  if (reference.width == working.camera.K.width && reference.height == working.camera.K.height) return reference;
  const Intrinsics* full = nullptr;
  for (const NamedCamera& c : options.cameras)
    if (c.name == working.name) full = &c.camera.K;
  if (full) {
    PreprocessOptions p;
    p.height = options.camera_options.height;
    if (auto at = view_picture_at_working_size(reference, full->width, full->height,
                                               working_size(full->width, full->height, p), p.patch))
      return *at;
  }
  fail("--reference: {}x{} pixels, but the reference view {} is {}x{}{}", reference.width, reference.height,
       working.name, working.camera.K.width, working.camera.K.height,
       full ? fmt::format(" at the working size and {}x{} as given (or that photo's working size at another height, "
                          "as eval's)",
                          full->width, full->height)
            : "");
}

}  // namespace

const char* fill_placement_name(FillPlacement placement) {
  return placement == FillPlacement::surface ? "surface" : "network";
}

FillPlacement parse_fill_placement(const std::string& name) {
  if (name == "surface") return FillPlacement::surface;
  if (name == "network") return FillPlacement::network;
  fail("fill placement '{}': surface or network", name);
}

RegionMask choose_region(const SplatCloud& cloud, const FillOptions& options, nlohmann::json& segmenter_record) {
  const bool prompted = !options.clicks.empty() || options.view_box;  // clicks, a box on the view, or both
  const int ways = (options.box ? 1 : 0) + (options.selection ? 1 : 0) + (options.stroke ? 1 : 0) + (prompted ? 1 : 0);
  if (ways != 1)
    fail("fill: name the region one way: a box, a selection file, or a view and its mask, clicks or box ({} given)",
         ways);
  RegionMask region;
  std::string what;
  if (options.box) {
    region = region_in_box(cloud, *options.box);
    what = "the box (" + options.box->describe() + ")";
  } else if (options.selection) {
    region = region_missing_from(cloud, *options.selection, options.selection_name);
    what = "--selection " + options.selection_name;
  } else {
    const auto named = std::find_if(options.cameras.begin(), options.cameras.end(),
                                    [&](const NamedCamera& c) { return c.name == options.stroke_view; });
    if (named == options.cameras.end())
      fail("--view {}: no camera of that name (the cameras come from --scene or --cameras)", options.stroke_view);
    if (options.stroke) {
      region = region_under_stroke(cloud, named->camera, *options.stroke);
      what = "the mask on view " + options.stroke_view;
    } else if (options.view_box) {
      ClickedMask clicked;
      region = region_from_view_box(cloud, named->camera, options.stroke_view, *options.view_box, options.clicks,
                                    options.not_clicks, options.segmenter.get(), &clicked);
      if (options.segmenter) segmenter_record = clicked.describe(*options.segmenter);
      what = "the box on view " + options.stroke_view;
    } else if (options.segmenter) {
      ClickedMask clicked;
      region = region_from_segmented_clicks(cloud, named->camera, options.stroke_view, options.clicks,
                                            options.not_clicks, *options.segmenter, &clicked);
      segmenter_record = clicked.describe(*options.segmenter);
      what = "the segmenter's outline on view " + options.stroke_view;
    } else {
      if (!options.not_clicks.empty())
        fail("fill: points that are not the object (--not-click) need a segmenter (--segmenter)");
      region = region_from_clicks(cloud, named->camera, options.stroke_view, options.clicks);
      what = "the click on view " + options.stroke_view;
    }
  }
  const int64_t n = region_count(region);
  if (n == 0)
    fail("{} holds no splat of {}: its splats lie within {}", what, options.scene_name, bounds_text(splat_bounds(cloud)));
  if (n == static_cast<int64_t>(cloud.size()))
    fail("{} holds all {} splats of {}: nothing would be left to fill the hole from", what, n, options.scene_name);
  return region;
}

nlohmann::json FillResult::report() const {
  nlohmann::json cams = nlohmann::json::array();
  for (size_t i = 0; i < cameras.cameras.size(); ++i) {
    nlohmann::json camera = camera_list_entry(cameras.cameras[i]);  // c2w in OpenGL axes
    camera["region_share"] = cameras.visible[i];
    camera["depth_scale"] = i < depth_scales.size() ? depth_scales[i] : 1.0;
    cams.push_back(camera);
  }
  nlohmann::json j = {{"splats",
                       {{"input", total},
                        {"removed", removed},
                        {"kept", total - removed},
                        {"added", added},
                        {"left_out", dropped},
                        {"output", total - removed + added}}},
                      {"region", region_how},
                      {"placement", fill_placement_name(placement)},
                      {"inpainter", inpainter},
                      {"cameras", {{"how", cameras.how}, {"reference", cameras.cameras.at(0).name}, {"views", cams}}},
                      {"stages", stages.to_json()},
                      {"total_ms", stages.waited_ms()}};
  if (!segmenter.is_null()) j["segmenter"] = segmenter;
  if (!inpainter_file.is_null()) j["inpainter_file"] = inpainter_file;
  if (placement == FillPlacement::surface) {
    j["surface"] = {{"reference_size", {surface_width, surface_height}}};
    for (size_t i = 0; i < uncovered.size() && i < cams.size(); ++i)
      j["cameras"]["views"][i]["uncovered_after_reference"] = uncovered[i];
  }
  if (!refine_report.is_null()) j["refine"] = refine_report;
  if (!model.is_null()) j["model"] = model;
  return j;
}

namespace {

// The scene as the renderer draws it: all of it, without the region, and the region's weight
// (white on black: a render's red channel is the region's share of each pixel).
struct SceneSets {
  GaussianSet scene, kept, weights, region;
  torch::Tensor in_region;  // a flag per row of scene (of the whole sets; near() leaves it empty)
  bool cull = true;
  std::optional<PixelWindow> window;  // near(): the region's window (none: every splat kept)

  // The sets less the splats that cannot draw near the region in `camera` (near_region), for
  // renders that are read there alone.
  SceneSets near(const Camera& camera) const {
    if (!cull) return *this;
    SceneSets s;
    s.window = region_window(region, camera);
    if (!s.window) {
      s = *this;
      s.cull = false;
      return s;
    }
    const torch::Tensor reach = reaching_window(scene, camera, *s.window);
    s.scene = select_rows(scene, reach);
    s.kept = select_rows(scene, reach.logical_and(in_region.logical_not()));
    s.weights = select_rows(weights, reach);
    s.region = region;
    s.cull = false;
    return s;
  }
};

SceneSets scene_sets(const SplatCloud& cloud, const RegionMask& region, const torch::Device& device, bool cull) {
  SceneSets s;
  s.scene = gaussians_from_splats(cloud, 3).to(device);
  s.in_region = region_flags(region, device);
  s.kept = select_rows(s.scene, s.in_region.logical_not());
  s.weights = region_weight_set(s.scene, s.in_region);
  s.region = select_rows(s.scene, s.in_region);
  s.cull = cull;
  return s;
}

constexpr size_t kNone = static_cast<size_t>(-1);

// What the cameras other than one saw: the chosen views' whole renders, the observers' (`extra`)
// and the small sights, less the view `skip_view` or the observer `skip_extra` (kNone: none).
std::vector<const Observer*> other_observers(const std::vector<CameraViews>& views, const std::vector<Observer>& extra,
                                             const std::vector<Observer>& sights, size_t skip_view, size_t skip_extra) {
  std::vector<const Observer*> others;
  for (size_t o = 0; o < views.size(); ++o)
    if (o != skip_view) others.push_back(&views[o].whole);
  for (size_t o = 0; o < extra.size(); ++o)
    if (o != skip_extra) others.push_back(&extra[o]);
  for (const Observer& o : sights) others.push_back(&o);
  return others;
}

// Every chosen camera's renders and its hole; `extra` gets the observers' whole renders at the
// working size when a refinement will look through them (else their small renders among the
// sights tell what they saw: 8 renders fewer, a second of a 0.7 M-splat fill).
std::vector<CameraViews> render_views(const SceneSets& sets, const ChosenCameras& cameras, bool refining,
                                      std::vector<Observer>& extra) {
  std::vector<CameraViews> views;
  // The scene without the region drawn whole (the network's input and the pictures); the whole
  // scene and the region's share near the region alone.
  for (const NamedCamera& c : cameras.cameras) {
    const SceneSets near = sets.near(c.camera);
    views.push_back(render_camera(near.scene, sets.kept, near.weights, c.camera, near.window));
  }
  if (refining)
    for (const NamedCamera& c : cameras.observers) extra.push_back(observe(sets.scene, c.camera));
  for (size_t v = 0; v < views.size(); ++v)
    views[v].mask = hole_mask(views[v], other_observers(views, extra, cameras.sights, v, kNone));
  return views;
}

// The network on the renders, read from memory as a scene whose views are prepared already.
Prediction predict_holes(const std::vector<CameraViews>& views, const ChosenCameras& cameras,
                         const FillOptions& options, const Predictor& predictor) {
  Scene rendered;
  rendered.root = options.scene_name;
  rendered.format = "renders";
  PreparedViewCache cache;
  SceneInputOptions input;
  input.preprocess.height = options.camera_options.height;
  input.num_views = static_cast<int>(views.size());
  input.inpainter = options.inpainter;
  input.view_cache = &cache;
  // Renders in memory: no depth maps, no photos to triangulate; the region's Gaussians are taken
  // from the maps alone, so the steps after the network would not reach it.
  input.geometry = GeometryOptions::papers();
  for (size_t i = 0; i < views.size(); ++i) {
    const NamedCamera& c = cameras.cameras[i];
    View view;
    view.name = c.name;
    view.image_path = c.name + " (render)";
    view.camera = c.camera;
    rendered.views.push_back(view);
    cache.put(view, input.preprocess, PreparedView{c.name, views[i].kept, std::nullopt, c.camera});
    input.context.push_back(c.name);
    input.masks[c.name] = views[i].mask;
  }
  if (options.reference_image) input.reference_image = reference_at_working_size(*options.reference_image, options, cameras);
  return predictor.predict(rendered, input);
}

// The hole pixels' Gaussians in the scene's frame: normalised -> scene, each view's depth scaled
// about its camera to meet the scene's around its hole, less those in another view's way.
GaussianSet hole_gaussians(const Prediction& p, const std::vector<CameraViews>& views, const FillOptions& options,
                           FillResult& result) {
  const PoseNormalization& norm = p.input.normalization;
  const GaussianMaps& maps = p.maps();
  const torch::Tensor mean = torch::tensor({norm.mean.x(), norm.mean.y(), norm.mean.z()}, torch::kFloat64);
  std::vector<torch::Tensor> means, scales, quats, opacities, colours;
  for (size_t v = 0; v < views.size(); ++v) {
    if (options.reference_only && v > 0) break;
    const int64_t vi = static_cast<int64_t>(v);
    const double s = depth_scale(views[v], maps.depth[0][vi][0], norm.scale);
    result.depth_scales.push_back(s);
    const torch::Tensor take = (image_to_tensor(views[v].mask)[0][0] > 0.5).reshape({-1}).to(maps.xyz.device());
    auto pixels = [&](const torch::Tensor& map) {  // (C, H, W) -> (hole pixels, C)
      return map[0][vi].flatten(1).t().index({take}).to(torch::kCPU, torch::kFloat64);
    };
    const Eigen::Vector3d c = result.cameras.cameras[v].camera.center();
    const torch::Tensor centre = torch::tensor({c.x(), c.y(), c.z()}, torch::kFloat64);
    const torch::Tensor world = centre + s * (pixels(maps.xyz) * norm.scale + mean - centre);
    const torch::Tensor keep = in_no_ones_way(world, views, v, result.cameras);
    result.dropped += keep.numel() - keep.sum().item<int64_t>();
    means.push_back(world.index({keep}));
    scales.push_back((pixels(maps.scale) * norm.scale * s).index({keep}));
    quats.push_back(pixels(maps.rotation).index({keep}));
    opacities.push_back(pixels(maps.opacity).squeeze(1).index({keep}));
    colours.push_back(pixels(maps.rgb).clamp(0, 1).index({keep}));
  }
  GaussianSet added;
  added.means = torch::cat(means).to(torch::kFloat32);
  added.scales = torch::cat(scales).to(torch::kFloat32);
  added.quats = torch::cat(quats).to(torch::kFloat32);
  added.opacities = torch::cat(opacities).to(torch::kFloat32);
  added.colors = torch::cat(colours).to(torch::kFloat32);
  return added;
}

// The new Gaussians optimised alone, drawn with the rest, against the chosen cameras and the
// observers outside their holes.
GaussianSet refine_new(const GaussianSet& added, const SceneSets& sets, const std::vector<CameraViews>& views,
                       const std::vector<Observer>& extra, const FillOptions& options, FillResult& result) {
  const torch::Device device = sets.scene.means.device();
  const GaussianSet filled_now = joined(sets.kept, added.to(device));
  std::vector<RefineView> targets;
  for (size_t v = 0; v < views.size(); ++v) {
    RefineView t;
    t.name = result.cameras.cameras[v].name;
    t.camera = result.cameras.cameras[v].camera;
    // The reference view's hole is held to a 2D inpainter's picture of it (--reference), else
    // to the fill as the network made it: the built-in stand-in (Telea's blur) is a worse
    // guess than the network's splats (synthetic rooms, 1 minute: left free, the new splats
    // drifted: 2 holes of 3 lost 5 and 11 dB). The views keep them in line outside their holes.
    if (v == 0 && options.reference_image) {
      t.rgb = result.reference;
    } else if (v == 0) {
      t.rgb = image_from_hwc(render(filled_now, {views[v].whole.camera}).rgb.clamp(0, 1).to(torch::kCPU));
    } else {
      t.rgb = views[v].kept;
      t.mask = views[v].mask;
    }
    targets.push_back(std::move(t));
  }
  // The other cameras that see the region supervise too, outside their holes: the new splats
  // may not cover what they saw there (a few views alone let floaters through).
  for (size_t k = 0; k < extra.size(); ++k) {
    const CameraViews v = render_camera(sets.scene, sets.kept, sets.weights, extra[k].camera);
    const Image mask = hole_mask(v, other_observers(views, extra, result.cameras.sights, kNone, k));
    RefineView t;
    t.name = result.cameras.observers[k].name;
    t.rgb = v.kept;
    t.mask = mask;
    t.camera = extra[k].camera;
    targets.push_back(std::move(t));
  }
  torch::AutoGradMode gradients(true);  // the rest of the fill runs without
  RefineOptions refine = *options.refine;
  refine.fixed = sets.kept;
  refine.cover = false;           // the rest of the scene covers what the views see
  refine.opacity_resets.clear();  // they would fade the new splats to let the views' holes decide
  // Held-out views would score outside their holes, where the new splats hardly draw: every view
  // fits the hole instead.
  refine.hold_out_every = 0;
  const RefineResult refined = refine_gaussians(added.to(device), targets, refine);
  result.refine_report = refinement_report(refined, refine);
  GaussianSet out = refined.gaussians.to(torch::kCPU);
  if (out.colors.dim() == 3) {  // SH: the DC term alone (the new splats carry one colour)
    out.colors = rgb_from_sh_dc(out.colors.select(1, 0));
    out.sh_degree = -1;
  }
  return out;
}

// The reference camera at the size it was given (at most 1080 rows), or the working one for
// automatic cameras, and that given camera's own size (a picture of it may come at that size).
struct SurfaceCamera {
  Camera camera;
  int given_width = 0, given_height = 0;
};

SurfaceCamera surface_camera(const FillOptions& options, const NamedCamera& working) {
  constexpr int kMaxRows = 1080;
  for (const NamedCamera& c : options.cameras)
    if (c.name == working.name) {
      const int h = std::min(c.camera.K.height, kMaxRows);
      const int w = static_cast<int>(std::lround(static_cast<double>(c.camera.K.width) * h / c.camera.K.height));
      return {h == c.camera.K.height ? c.camera : c.camera.resized(w, h), c.camera.K.width, c.camera.K.height};
    }
  return {working.camera, working.camera.K.width, working.camera.K.height};
}

// The reference's colours at the surface camera's size: the caller's picture (at the given
// camera's size, the working size or eval's crop), else the built-in inpainter's of the render.
// Diffusion reads the hole's border alone (`view` is drawn near the region); patches are copied
// from around the hole, so they get the kept scene drawn whole.
Image surface_colours(const FillOptions& options, const SceneSets& sets, const SurfaceCamera& at,
                      const CameraViews& view, const ChosenCameras& chosen) {
  const int w = at.camera.K.width, h = at.camera.K.height;
  if (!options.reference_image && options.inpainter == ClassicalInpainter::Patches)
    return options.inpainter.paint(image_from_hwc(render(sets.kept, {at.camera}).rgb.clamp(0, 1).to(torch::kCPU)),
                                   view.mask);
  if (!options.reference_image) return options.inpainter.paint(view.kept, view.mask);
  reference_at_working_size(*options.reference_image, options, chosen);  // one that fits nowhere fails here
  WorkingSize full;
  full.resized_width = full.width = w;
  full.resized_height = full.height = h;
  if (auto picture = view_picture_at_working_size(*options.reference_image, at.given_width, at.given_height, full,
                                                  PreprocessOptions().patch))
    return *picture;
  return resize_area(reference_at_working_size(*options.reference_image, options, chosen), w, h);
}

// New splats for a view's `unknown` pixels on the surface continued from its `known` ones, and
// for the known pixels within `grow` pixels of them (a seam of the view's own colours over
// the kept surface there: where that surface is thin, other views see through it), backed.
GaussianSet splats_over(const Camera& camera, const torch::Tensor& depth, const torch::Tensor& known,
                        const torch::Tensor& unknown, const Image& colour, const std::string& view_name,
                        int grow = 0) {
  const std::optional<torch::Tensor> surface = complete_depth(depth, known, unknown);
  if (!surface)
    fail("fill: view {} sees nothing of the scene around the hole to continue its surface from; try "
         "--placement network",
         view_name);
  torch::Tensor take = unknown;
  if (grow > 0) {
    const Image grown = dilate_mask(image_from_hwc(unknown.to(torch::kFloat32).unsqueeze(2)), 1, 2 * grow + 1);
    take = image_to_tensor(grown)[0][0] > 0.5;
  }
  return joined(surface_gaussians(camera, *surface, take, colour), backing_gaussians(camera, *surface, take, colour));
}

GaussianSet keep_rows(const GaussianSet& g, const torch::Tensor& keep, int64_t& dropped) {
  dropped += keep.numel() - keep.sum().item<int64_t>();
  return select_rows(g, keep);
}

// On a capture all round the region, what the region hid from every camera (a pedestal's top
// under a vase) keeps the surface the capture's training continued there where the scene without
// the region draws one no farther than the surface continued from the hole's border (not the
// inside of a pedestal seen through a hole in its top); what is left of `hole` is filled. Painted
// by the built-in inpainter on a surface continued from the hole's border, the pedestal's top
// under the vase rose to the wall behind it (ring rooms: docs/editing.md).
torch::Tensor still_open(const CameraViews& view, const torch::Tensor& kept, const torch::Tensor& hole) {
  const std::optional<torch::Tensor> continued = complete_depth(view.kept_depth, kept, hole);
  if (!continued) return hole;
  const torch::Tensor on_it = kept.logical_and(view.kept_depth <= *continued * (1 + kContinuedTolerance));
  return hole.logical_and(on_it.logical_not());
}

// The reference's hole at the size its camera was given: its depth continued inward, one splat a
// pixel in the reference picture's colours, and a seam of 4 pixels over the kept surface around
// it (without the seam SPIn-NeRF scene 1's test views showed 861 pixels of background in the
// region for one reference, with it 12; the reference's colours over the whole region rather
// than its hole changed nothing there, 16.42 dB both).
GaussianSet reference_splats(const SceneSets& sets, const std::vector<CameraViews>& views,
                             const std::vector<Observer>& extra, const FillOptions& options, FillResult& result) {
  const NamedCamera& reference = result.cameras.cameras.at(0);
  const SurfaceCamera at = surface_camera(options, reference);
  const SceneSets near = sets.near(at.camera);  // read near the hole alone
  CameraViews full = render_camera(near.scene, near.kept, near.weights, at.camera);
  full.mask = hole_mask(full, other_observers(views, extra, result.cameras.sights, 0, kNone));
  result.stages.lap("render the reference at its size");
  const Image colour = surface_colours(options, sets, at, full, result.cameras);
  // The 2D inpainter's share of the fill (LaMa's is most of it where it paints).
  const std::string painter = options.reference_image ? "the given reference" : options.inpainter.name();
  result.stages.lap(fmt::format("the hole's colours ({})", painter));
  result.surface_width = at.camera.K.width;
  result.surface_height = at.camera.K.height;
  PreprocessOptions p;
  p.height = options.camera_options.height;
  // The picture of the reference (reference.png): the caller's or the patches' (drawn whole), else
  // the built-in inpainter's of the working view drawn whole (the renders above hold the hole's
  // surroundings alone).
  result.reference = !options.reference_image && options.inpainter != ClassicalInpainter::Patches
                         ? options.inpainter.paint(views[0].kept, views[0].mask)
                     : at.camera.K.height == reference.camera.K.height
                         ? colour
                         : to_working_size(colour, working_size(colour.width, colour.height, p));
  result.stages.lap(fmt::format("reference.png ({})", painter));
  const torch::Tensor hole = image_to_tensor(full.mask)[0][0] > 0.5;
  const torch::Tensor kept = full.kept_alpha > 0.5;
  const GaussianSet added = splats_over(at.camera, full.kept_depth, kept,
                                        result.cameras.round ? still_open(full, kept, hole) : hole, colour,
                                        reference.name, 4);
  return keep_rows(added, in_no_ones_way(added.means.to(torch::kFloat64), views, 0, result.cameras), result.dropped);
}

// Chosen view `v`'s hole pixels that still render nothing with `added` drawn (what the reference
// did not see): that view's depth continued there, in the colours Telea gives its render; `uncovered`
// counts them.
GaussianSet view_hole_splats(const SceneSets& sets, const GaussianSet& added, const std::vector<CameraViews>& views,
                             size_t v, const FillOptions& options, FillResult& result, int64_t& uncovered) {
  const NamedCamera& c = result.cameras.cameras[v];
  const RenderOutput now = render(joined(sets.near(c.camera).kept, added.to(sets.scene.means.device())), {c.camera});
  const torch::Tensor alpha = now.alpha.squeeze(2).to(torch::kCPU);
  const torch::Tensor open = (image_to_tensor(views[v].mask)[0][0] > 0.5).logical_and(alpha < 0.5);
  uncovered = open.sum().item<int64_t>();
  if (uncovered == 0) return {};
  // Telea whatever the reference's inpainter: these holes are slivers, and `now` is drawn near the
  // region alone (patches would be copied from the blank rest).
  const Image rgb = image_from_hwc(now.rgb.clamp(0, 1).to(torch::kCPU));
  const Image paint = inpaint_telea(rgb, image_from_hwc(open.to(torch::kFloat32).unsqueeze(2)));
  const GaussianSet more =
      splats_over(c.camera, now.depth.squeeze(2).to(torch::kCPU), alpha >= 0.5, open, paint, c.name, 2);
  return keep_rows(more, in_no_ones_way(more.means.to(torch::kFloat64), views, v, result.cameras), result.dropped);
}

// The surface placement (FillPlacement::surface): the reference's hole, then each other chosen
// view's. (The 8 observers likewise, over the region's footprint in their views: 1.4 s of a 5.5 s
// fill of 1 M splats, and not one pixel fewer left uncovered in SPIn-NeRF scene 1's test views.)
GaussianSet surface_fill(const SceneSets& sets, const std::vector<CameraViews>& views, const std::vector<Observer>& extra,
                         const FillOptions& options, FillResult& result) {
  GaussianSet added = reference_splats(sets, views, extra, options, result);
  result.stages.lap("the reference's splats on the continued surface");
  result.uncovered.push_back(0);
  for (size_t v = 1; v < views.size(); ++v) {
    int64_t uncovered = 0;
    const GaussianSet more = view_hole_splats(sets, added, views, v, options, result, uncovered);
    result.uncovered.push_back(uncovered);
    if (more.size() > 0) added = joined(added, more);  // both RGB: the rows one after the other
  }
  result.stages.lap("cover the other chosen views' holes");
  return added;
}

// The pictures of fill.json's cameras: before, the region removed, the hole, and `after` drawn:
// near `changed` (the region and the new splats) alone, the rest is the removed picture's.
void add_pictures(FillResult& result, const std::vector<CameraViews>& views, const GaussianSet* after,
                  const GaussianSet* changed, bool cull) {
  for (size_t v = 0; v < views.size(); ++v) {
    result.before.push_back(views[v].before);
    result.deleted.push_back(views[v].kept);
    result.masks.push_back(views[v].mask);
    if (!after) {
      result.after.push_back(views[v].kept);
      continue;
    }
    const Camera& camera = result.cameras.cameras[v].camera;
    const std::optional<PixelWindow> window = cull ? region_window(*changed, camera) : std::nullopt;
    if (!window) {
      result.after.push_back(image_from_hwc(render(*after, {camera}).rgb.clamp(0, 1).to(torch::kCPU)));
      continue;
    }
    const Image& kept = views[v].kept;
    const torch::Tensor outside =
        torch::from_blob(const_cast<float*>(kept.pixels.data()), {kept.height, kept.width, kept.channels}, torch::kFloat32);
    const GaussianSet near = select_rows(*after, reaching_window(*after, camera, *window));
    const torch::Tensor inside = render(near, {camera}).rgb.clamp(0, 1).to(torch::kCPU);
    result.after.push_back(image_from_hwc(pasted(outside, inside, *window)));
  }
}

}  // namespace

FillResult fill_splats(const SplatCloud& cloud, const FillOptions& options, const Predictor& predictor) {
  FillResult result;
  StageTimes& stages = result.stages;
  check_splats_finite(cloud, options.scene_name);
  const RegionMask region = choose_region(cloud, options, result.segmenter);
  result.model = predictor.describe();
  result.total = static_cast<int64_t>(cloud.size());
  result.removed = region_count(region);
  result.region_how = options.box ? "box: " + options.box->describe()
                      : options.selection ? "selection: the splats missing from " + options.selection_name
                      : options.stroke    ? "mask on view " + options.stroke_view
                      : options.view_box  ? fmt::format("box {:g},{:g},{:g},{:g} on view {} ({})", (*options.view_box)[0],
                                                       (*options.view_box)[1], (*options.view_box)[2],
                                                       (*options.view_box)[3], options.stroke_view,
                                                       options.segmenter ? "the segmenter's outline" : "GrabCut in the render")
                                          : fmt::format("{} click{} on view {} ({})", options.clicks.size(),
                                                        options.clicks.size() == 1 ? "" : "s", options.stroke_view,
                                                        options.segmenter ? "the segmenter's outline"
                                                                          : "colour growth in the render");
  stages.lap("select region");

  torch::NoGradGuard no_grad;
  const torch::Device device = render_device(predictor.device());
  const SceneSets sets = scene_sets(cloud, region, device, options.camera_options.cull);
  stages.lap("splats to Gaussians");

  FillCameraOptions camera_options = options.camera_options;
  // The stroke's view is the reference unless another is named: the user drew on it.
  if (camera_options.reference.empty() && (options.stroke || !options.clicks.empty() || options.view_box))
    camera_options.reference = options.stroke_view;
  if (options.cameras.empty() && camera_options.up.norm() == 0) camera_options.up = guess_up(cloud, region);
  result.cameras = options.cameras.empty()
                       ? choose_automatic_cameras(sets.scene, region, camera_options, &stages)
                       : choose_given_cameras(sets.scene, region, options.cameras, camera_options, &stages);
  stages.lap("choose cameras");

  std::vector<Observer> extra;
  const std::vector<CameraViews> views = render_views(sets, result.cameras, options.refine.has_value(), extra);
  stages.lap("render views");

  result.splats = rows_of(cloud, kept_flags(region));  // bit for bit, in their order
  if (!options.fill) {
    result.reference = views.at(0).kept;
    add_pictures(result, views, nullptr, nullptr, false);
    stages.lap("assemble the splats");
    return result;
  }

  result.placement = options.placement;
  if (!options.reference_image) result.inpainter = options.inpainter.name();
  if (!options.reference_image && options.inpainter.learned) result.inpainter_file = options.inpainter.describe();
  GaussianSet added;
  if (options.placement == FillPlacement::surface) {
    added = surface_fill(sets, views, extra, options, result);
  } else {
    const Prediction p = predict_holes(views, result.cameras, options, predictor);
    stages.merge(p.stages);
    stages.restart_lap();
    result.reference = p.input.views.at(0).rgb;
    added = hole_gaussians(p, views, options, result);
    stages.lap("new Gaussians to the scene's frame");
  }
  if (options.refine) {
    added = refine_new(added, sets, views, extra, options, result);
    stages.lap("refine the new Gaussians");
  }

  append_rows(result.splats, splats_from_gaussians(added.to(torch::kCPU)));
  result.added = added.size();
  stages.lap("assemble the splats");
  const GaussianSet filled = gaussians_from_splats(result.splats, 3).to(device);
  GaussianSet changed;  // where the pictures change: the region and the new splats
  changed.means = torch::cat({sets.region.means, added.means.to(device, sets.region.means.scalar_type())});
  changed.scales = torch::cat({sets.region.scales, added.scales.to(device, sets.region.scales.scalar_type())});
  add_pictures(result, views, &filled, &changed, sets.cull);
  stages.lap("render after");
  return result;
}

}  // namespace ii
