#include "geometry/floaters.h"

#include "common/error.h"

namespace ii {

namespace {

// (H, W) bool: where the log depths of a pixel's 3 x 3 neighbourhood span more than `edge`.
torch::Tensor depth_edges(const torch::Tensor& depth, double edge) {
  const torch::Tensor log_depth = depth.clamp_min(1e-12).log().unsqueeze(0).unsqueeze(0);
  const torch::Tensor span = torch::max_pool2d(log_depth, {3, 3}, {1, 1}, {1, 1}) +
                             torch::max_pool2d(-log_depth, {3, 3}, {1, 1}, {1, 1});
  return span[0][0] > edge;
}

}  // namespace

int64_t fade_floaters(GaussianMaps& maps, const std::vector<PreparedView>& views, const std::vector<Camera>& cameras,
                      const FloaterOptions& options) {
  if (options.fade >= 1 || views.size() < 2) return 0;
  const int64_t count = maps.depth.size(1), h = maps.depth.size(3), w = maps.depth.size(4);
  if (static_cast<int64_t>(views.size()) != count || cameras.size() != views.size())
    fail("floaters: {} views and {} cameras for {} views of maps", views.size(), cameras.size(), count);
  torch::InferenceMode inference;  // the maps are the network's inference tensors
  const std::vector<SeenDepth> seen = seen_depths(maps, views, cameras);
  int64_t faded = 0;
  for (int64_t v = 0; v < count; ++v) {
    // Only the pixels on its depth edges are candidates (a tenth to a fifth of them): the others
    // are not projected at all.
    const torch::Tensor on_edge = depth_edges(seen[static_cast<size_t>(v)].depth, options.edge);
    const torch::Tensor edge = on_edge.reshape({-1}).nonzero().squeeze(1);
    if (edge.numel() == 0) continue;
    const torch::Tensor points = maps.xyz[0][v].to(torch::kFloat32).reshape({3, -1}).index_select(1, edge).t();
    const torch::Tensor through = seen_through(points, seen, options.tolerance, v);
    const torch::Tensor floaters =
        torch::zeros({h * w}, on_edge.options()).index_fill_(0, edge.masked_select(through), true).view({h, w});
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
