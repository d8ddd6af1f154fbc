#pragma once
// Between world points and a camera's pixels, as render() draws them (pinhole, OpenCV axes,
// pixel centres at +0.5). project and unproject work on float64 CPU tensors.
#include <optional>
#include <utility>

#include "common/torch.h"

#include "camera/camera.h"
#include "gaussians/gaussians.h"
#include "tensor/camera_projection.h"

namespace ii {

// A window of a camera's pixels: columns [x0, x1), rows [y0, y1).
struct PixelWindow {
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

// Which Gaussians may draw on `window`'s pixels in `camera`, a flag per row on g's device: those
// whose centre is in front of the near plane and whose bounding sphere (three times the largest
// scale, and the rasterizer's 2D blur) projects onto the window, or that are too near to bound.
// The rest draw nothing there: a render of the flagged rows equals the whole set's inside the
// window (culling: every render projects every Gaussian it is given).
torch::Tensor reaching_window(const GaussianSet& g, const Camera& camera, const PixelWindow& window);

// The pixels `g`'s bounding spheres cover in `camera`, grown by `margin` pixels and clamped to the
// image; nullopt when none of them is in front of the camera or the window is empty.
std::optional<PixelWindow> covered_window(const GaussianSet& g, const Camera& camera, double margin);

// `outside` (H, W, ...) with the window's pixels taken from `inside` (the same shape): a render
// of the splats reaching the window pasted over one of the rest.
torch::Tensor pasted(const torch::Tensor& outside, const torch::Tensor& inside, const PixelWindow& window);

// The world points (N, 3) of pixels (rows `v`, columns `u`, N each) at camera z-depths `z`.
torch::Tensor unproject(const Camera& camera, const torch::Tensor& v, const torch::Tensor& u, const torch::Tensor& z);

// Each pixel's world point (H, W, 3; float64) at a depth map (H, W) of `camera`.
torch::Tensor depth_points(const Camera& camera, const torch::Tensor& depth);
// Each pixel's surface normal in the world frame (H, W, 3; float64) from its world points (H, W, 3;
// float64, depth_points), by its neighbours' points, turned towards the camera (zero on the
// picture's edge).
torch::Tensor point_normals(const Camera& camera, const torch::Tensor& points);
// point_normals of depth_points.
torch::Tensor depth_normals(const Camera& camera, const torch::Tensor& depth);

}  // namespace ii
