#include "model/floaters.h"

#include "common/error.h"
#include "tensor/camera_projection.h"

namespace ii {

namespace {

// (H, W) bool: where the log depths of a pixel's 3 x 3 neighbourhood span more than `edge`.
torch::Tensor depth_edges(const torch::Tensor& depth, double edge) {
  const torch::Tensor log_depth = depth.clamp_min(1e-12).log().unsqueeze(0).unsqueeze(0);
  const torch::Tensor span = torch::max_pool2d(log_depth, {3, 3}, {1, 1}, {1, 1}) +
                             torch::max_pool2d(-log_depth, {3, 3}, {1, 1}, {1, 1});
  return span[0][0] > edge;
}

// (N) bool: which of `points` (N, 3) land inside `camera`'s picture, outside `usable`'s false
// pixels, more than `tolerance` in front of `depth` (H, W) there.
torch::Tensor in_front_of(const torch::Tensor& points, const Camera& camera, const torch::Tensor& depth,
                          const torch::Tensor& usable, double tolerance) {
  const PixelHit hit = project(camera, points);
  const torch::Tensor there = depth.reshape({-1}).index_select(0, hit.index);
  return hit.inside.logical_and(usable.reshape({-1}).index_select(0, hit.index))
      .logical_and(hit.z < there * (1 - tolerance));
}

}  // namespace

int64_t fade_floaters(GaussianMaps& maps, const std::vector<PreparedView>& views, const std::vector<Camera>& cameras,
                      const FloaterOptions& options) {
  if (options.fade >= 1 || views.size() < 2) return 0;
  const int64_t count = maps.depth.size(1), h = maps.depth.size(3), w = maps.depth.size(4);
  if (static_cast<int64_t>(views.size()) != count || cameras.size() != views.size())
    fail("floaters: {} views and {} cameras for {} views of maps", views.size(), cameras.size(), count);
  torch::InferenceMode inference;  // the maps are the network's inference tensors
  const torch::Device device = maps.depth.device();
  std::vector<torch::Tensor> depth, usable;
  for (int64_t v = 0; v < count; ++v) {
    depth.push_back(maps.depth[0][v][0].to(torch::kFloat32));
    const auto& mask = views[static_cast<size_t>(v)].mask;
    if (mask && (mask->width != w || mask->height != h))
      fail("floaters: view {}'s mask is {}x{}, its depth {}x{}", views[static_cast<size_t>(v)].name, mask->width,
           mask->height, w, h);
    usable.push_back(mask ? torch::from_blob(const_cast<float*>(mask->pixels.data()), {h, w}, torch::kFloat32)
                                .le(0.5f)
                                .to(device)
                          : torch::ones({h, w}, torch::TensorOptions(torch::kBool).device(device)));
  }
  int64_t faded = 0;
  for (int64_t v = 0; v < count; ++v) {
    // Only the pixels on its depth edges are candidates (a tenth to a fifth of them): the others
    // are not projected at all.
    const torch::Tensor on_edge = depth_edges(depth[static_cast<size_t>(v)], options.edge);
    const torch::Tensor edge = on_edge.reshape({-1}).nonzero().squeeze(1);
    if (edge.numel() == 0) continue;
    const torch::Tensor points = maps.xyz[0][v].to(torch::kFloat32).reshape({3, -1}).index_select(1, edge).t();
    torch::Tensor seen_through = torch::zeros({edge.numel()}, torch::TensorOptions(torch::kBool).device(device));
    for (int64_t u = 0; u < count; ++u)
      if (u != v)
        seen_through.logical_or_(in_front_of(points, cameras[static_cast<size_t>(u)], depth[static_cast<size_t>(u)],
                                             usable[static_cast<size_t>(u)], options.tolerance));
    const torch::Tensor floaters =
        torch::zeros({h * w}, on_edge.options()).index_fill_(0, edge.masked_select(seen_through), true).view({h, w});
    faded += floaters.sum().item<int64_t>();
    torch::Tensor opacity = maps.opacity[0][v][0];  // a view of the maps, whatever its strides
    opacity.copy_(torch::where(floaters, opacity * options.fade, opacity));
  }
  return faded;
}

nlohmann::json describe_floaters(const FloaterOptions& options, int64_t faded) {
  return {{"fade", options.fade}, {"tolerance", options.tolerance}, {"edge", options.edge}, {"faded", faded}};
}

}  // namespace ii
