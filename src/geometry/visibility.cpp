#include "geometry/visibility.h"

#include "common/error.h"
#include "tensor/camera_projection.h"

namespace ii {

std::vector<SeenDepth> seen_depths(const GaussianMaps& maps, const std::vector<PreparedView>& views,
                                   const std::vector<Camera>& cameras) {
  const int64_t count = maps.depth.size(1), h = maps.depth.size(3), w = maps.depth.size(4);
  if (static_cast<int64_t>(views.size()) != count || cameras.size() != views.size())
    fail("visibility: {} views and {} cameras for {} views of maps", views.size(), cameras.size(), count);
  const torch::Device device = maps.depth.device();
  std::vector<SeenDepth> seen;
  for (int64_t v = 0; v < count; ++v) {
    const PreparedView& view = views[static_cast<size_t>(v)];
    if (view.mask && (view.mask->width != w || view.mask->height != h))
      fail("visibility: view {}'s mask is {}x{}, its depth {}x{}", view.name, view.mask->width, view.mask->height, w,
           h);
    torch::Tensor usable =
        view.mask ? torch::from_blob(const_cast<float*>(view.mask->pixels.data()), {h, w}, torch::kFloat32)
                        .le(0.5f)
                        .to(device)
                  : torch::ones({h, w}, torch::TensorOptions(torch::kBool).device(device));
    seen.push_back({cameras[static_cast<size_t>(v)], maps.depth[0][v][0].to(torch::kFloat32), std::move(usable)});
  }
  return seen;
}

namespace {

// Where `points` land in `seen`'s picture and what it saw there.
struct Landing {
  torch::Tensor inside;  // inside the picture and where its depth is usable
  torch::Tensor z;       // the points' depth from its camera
  torch::Tensor depth;   // its depth at their pixels
};

Landing land(const torch::Tensor& points, const SeenDepth& seen) {
  const PixelHit hit = project(seen.camera, points);
  const torch::Tensor index = hit.index.to(seen.depth.device());
  Landing l;
  l.inside = hit.inside.logical_and(seen.usable.reshape({-1}).index_select(0, index).to(hit.inside.device()));
  l.z = hit.z;
  l.depth = seen.depth.reshape({-1}).index_select(0, index).to(hit.z.device(), hit.z.scalar_type());
  return l;
}

}  // namespace

torch::Tensor seen_through(const torch::Tensor& points, const std::vector<SeenDepth>& seen, double tolerance,
                           int64_t skip) {
  torch::Tensor through = torch::zeros({points.size(0)}, torch::TensorOptions(torch::kBool).device(points.device()));
  for (size_t u = 0; u < seen.size(); ++u) {
    if (static_cast<int64_t>(u) == skip) continue;
    const Landing l = land(points, seen[u]);
    through.logical_or_(l.inside.logical_and(l.z < l.depth * (1 - tolerance)));
  }
  return through;
}

torch::Tensor on_seen_surface(const torch::Tensor& points, const SeenDepth& seen, double tolerance) {
  const Landing l = land(points, seen);
  return l.inside.logical_and((l.depth - l.z).abs() <= tolerance * l.z);
}

}  // namespace ii
