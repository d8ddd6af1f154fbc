#include "geometry/measured_surface.h"

#include <optional>
#include <vector>

#include "data/masks.h"
#include "data/preprocess.h"
#include "model/scene_input.h"
#include "geometry/surface_splats.h"
#include "tensor/camera_projection.h"
#include "tensor/image_tensor.h"

namespace ii {

using torch::indexing::Slice;

namespace {

// `scene`'s depth map of the context view `v` at the working size (nearest: no depth between the
// two sides of an edge), in the pose-normalised frame's units; undefined without one.
torch::Tensor working_depth_map(const Scene& scene, const SceneInput& input, const PreprocessOptions& preprocess,
                                size_t v) {
  const View& view = scene.views[static_cast<size_t>(input.context[v])];
  const std::optional<Image> depth = load_view_depth(scene, view);  // at the photo's size
  if (!depth) return {};
  const Image at_working =
      to_working_size(*depth, working_size(depth->width, depth->height, preprocess), /*is_mask=*/true);
  return torch::from_blob(const_cast<float*>(at_working.pixels.data()), {at_working.height, at_working.width},
                          torch::kFloat32)
             .clone() /
         input.normalization.scale;
}

// Where the object can be: the cone of the reference's mask, grown, from its camera. Its measured
// points that another view sees outside that cone, or outside the reference's picture, are not
// the object (an object the reference's frame cuts goes on there too: the reference cannot
// remove what it does not see). Counting as the object also what lies in the cone farther
// behind the reference's measured object than the object is wide lost the rooms' region 0.1-0.2
// dB (its back, its shadow); keeping what lies outside the picture as the object lost make
// demo's room 2.7 dB (the white patches stayed).
struct ObjectCone {
  Camera camera;
  torch::Tensor inside;  // (H, W) bool: the reference's mask, grown
};

std::optional<ObjectCone> object_cone(const SceneInput& input, int grow) {
  const PreparedView& reference = input.views.front();
  if (!reference.mask) return std::nullopt;
  return ObjectCone{input.input.view_cameras.front(), grown_mask(reference, grow)};
}

// Which points (N, 3) cannot be the object.
torch::Tensor not_the_object(const ObjectCone& cone, const torch::Tensor& points) {
  const PixelHit hit = project(cone.camera, points.to(torch::kFloat32));
  return hit.inside.logical_and(cone.inside.flatten().index({hit.index})).logical_not();
}

// The measured points of `masked` pixels (a view's mask and its margin) that cannot be the
// object, written over view `vi`'s maps; the network saw them masked, so the photo's colours.
// (The margin too: between these splats and those outside, its soft Gaussians drew white outlines
// in make demo's novel views.) Returns how many.
int64_t put_beside_object(GaussianMaps& maps, int64_t vi, const Camera& camera, const torch::Tensor& depth,
                          const torch::Tensor& masked, const Image& photo, const ObjectCone& object,
                          const MeasuredSurfaceOptions& options) {
  const GaussianSet hidden =
      surface_gaussians(camera, depth, masked, photo, static_cast<float>(options.opacity), options.width);
  if (hidden.size() == 0) return 0;
  const torch::Tensor rows = not_the_object(object, hidden.means).nonzero().squeeze(1);
  if (rows.numel() == 0) return 0;
  const GaussianSet beside = select_rows(hidden, rows);
  write_splats(maps, vi, masked.flatten().nonzero().squeeze(1).index({rows}), beside,
               depth.index({masked}).index({rows}), true);
  return beside.size();
}

// Each context view's depth measured by a plane sweep between the context photos, about the
// network's aligned depth.
MeasuredDepth stereo_of_photos(const SceneInput& input, const GaussianMaps& maps, const StereoOptions& options) {
  MeasuredDepth out;
  if (input.views.size() < 2) return out;
  std::vector<Image> photos;
  std::vector<torch::Tensor> guides;
  for (size_t v = 0; v < input.views.size(); ++v) {
    photos.push_back(input.views[v].rgb);
    guides.push_back(maps.depth[0][static_cast<int64_t>(v)][0]);
  }
  out.source = "the photos (stereo)";
  out.from = MeasuredFrom::photos;
  out.depth = stereo_depth(photos, input.input.view_cameras, guides, options);
  return out;
}

}  // namespace

torch::Tensor grown_mask(const PreparedView& view, int grow) {
  if (!view.mask) return torch::zeros({view.rgb.height, view.rgb.width}, torch::kBool);
  return image_to_tensor(dilate_mask(*view.mask, grow > 0 ? 1 : 0, 2 * grow + 1))[0][0].gt(0.5);
}

void write_colours(GaussianMaps& maps, int64_t vi, const torch::Tensor& pixels, const torch::Tensor& colours) {
  const torch::Tensor map = maps.rgb[0][vi];
  map.view({map.size(0), -1})
      .index_put_({Slice(), pixels.to(map.device())}, colours.t().to(map.device(), map.scalar_type()));
}

void write_splats(GaussianMaps& maps, int64_t vi, const torch::Tensor& pixels, const GaussianSet& splats,
                  const torch::Tensor& depth, bool colours) {
  const torch::Tensor at = pixels.to(maps.xyz.device());
  auto put = [&](const torch::Tensor& map, const torch::Tensor& rows) {  // map (C, H, W), rows (N, C)
    map.view({map.size(0), -1}).index_put_({Slice(), at}, rows.t().to(map.device(), map.scalar_type()));
  };
  put(maps.xyz[0][vi], splats.means);
  put(maps.depth[0][vi], depth.view({-1, 1}));
  put(maps.scale[0][vi], splats.scales);
  put(maps.rotation[0][vi], splats.quats);
  const torch::Tensor network_opacity =
      maps.opacity[0][vi].view({1, -1}).index({Slice(), at}).t().to(torch::kCPU, torch::kFloat32);
  put(maps.opacity[0][vi], torch::maximum(network_opacity, splats.opacities.view({-1, 1})));
  if (colours) write_colours(maps, vi, pixels, splats.colors);
}

MeasuredDepth measured_depth(const Scene& scene, const SceneInput& input, const PreprocessOptions& preprocess,
                             const GaussianMaps& maps, const MeasuredSurfaceOptions& options) {
  MeasuredDepth out;
  if (options.opacity <= 0) return out;
  bool any = false;
  for (size_t v = 0; v < input.views.size(); ++v) {
    out.depth.push_back(working_depth_map(scene, input, preprocess, v));
    out.far_side.emplace_back();
    if (out.depth.back().defined() && options.far_side) {
      out.far_side.back() = flying_pixels_to_far_side(out.depth.back(), options.flying);
      out.depth.back() = out.far_side.back().depth;
    }
    any = any || out.depth.back().defined();
  }
  if (any) {
    out.source = "depth maps";
    out.from = MeasuredFrom::depth_maps;
    return out;
  }
  if (options.from_photos) return stereo_of_photos(input, maps, options.stereo);
  return {};
}

MeasuredSurface put_on_measured_surface(GaussianMaps& maps, const SceneInput& input, const MeasuredDepth& measured,
                                        const MeasuredSurfaceOptions& options) {
  MeasuredSurface done;
  if (options.opacity <= 0 || measured.depth.empty()) return done;
  done.source = measured.source;
  done.from = measured.from;
  torch::InferenceMode inference;  // the maps are the network's inference tensors
  const auto opacity = static_cast<float>(options.opacity);
  const std::optional<ObjectCone> object =
      options.beside_object ? object_cone(input, options.cone_margin) : std::nullopt;
  for (size_t v = 0; v < input.views.size() && v < measured.depth.size(); ++v) {
    const torch::Tensor& depth = measured.depth[v];
    if (!depth.defined() || depth.size(0) != maps.depth.size(3) || depth.size(1) != maps.depth.size(4)) continue;
    const PreparedView& view = input.views[v];
    const Camera& camera = input.input.view_cameras[v];
    const int64_t vi = static_cast<int64_t>(v);
    const torch::Tensor valid = depth.gt(0).logical_and(depth.isfinite());
    done.views.push_back(view.name);
    done.known.push_back(valid.to(torch::kFloat32).mean().item<double>());
    // The photo with the moved pixels in their far side's colours.
    const bool moved_any = v < measured.far_side.size() && measured.far_side[v].moved.defined() &&
                           measured.far_side[v].moved.any().item<bool>();
    const FarSide* far = moved_any ? &measured.far_side[v] : nullptr;
    const Image photo = far ? tensor_to_image(far_side_colours(image_to_tensor(view.rgb)[0], *far)) : view.rgb;
    // Outside the mask (grown): the surface in place of the network's Gaussians, its colours kept
    // but for the moved pixels'.
    const torch::Tensor take = valid.logical_and(grown_mask(view, options.mask_margin).logical_not());
    const GaussianSet surface = surface_gaussians(camera, depth, take, photo, opacity, options.width);
    // surface_gaussians keeps the `take` pixels in row-major order: their indices in the maps' rows.
    const torch::Tensor pixels = take.flatten().nonzero().squeeze(1);
    if (surface.size() > 0) write_splats(maps, vi, pixels, surface, depth.index({take}), false);
    if (far && surface.size() > 0) {
      const torch::Tensor moved = far->moved.index({take}).nonzero().squeeze(1);
      if (moved.numel() > 0)
        write_colours(maps, vi, pixels.index_select(0, moved), surface.colors.index_select(0, moved));
    }
    done.gaussians += surface.size();
    if (far) done.far_side += far->moved.sum().item<int64_t>();
    // Inside another view's mask (and its margin): the scene beside the object.
    if (v > 0 && object && view.mask)
      done.beside_object += put_beside_object(maps, vi, camera, depth, valid.logical_and(take.logical_not()), photo,
                                              *object, options);
  }
  return done;
}

nlohmann::json describe_measured_surface(const MeasuredSurfaceOptions& options, const MeasuredSurface& done) {
  return {{"opacity", options.opacity},
          {"source", done.source},
          {"known", done.known},
          {"width", options.width},
          {"mask_margin", options.mask_margin},
          {"views", done.views},
          {"gaussians", done.gaussians},
          {"cone_margin", options.cone_margin},
          {"beside_object", done.beside_object},
          {"far_side", done.far_side}};
}

}  // namespace ii
