#pragma once
// Scenes and cameras shared by the renderer tests.
#include "common/torch.h"

#include <cmath>
#include <filesystem>

#include "camera/camera.h"
#include "io/safetensors.h"
#include "render/rasterizer.h"

namespace ii::test {

// A camera at `position` (world) looking along world +z with OpenCV axes (y down), as
// brush's golden cases use: pinhole, square pixels, centred principal point.
inline RenderCamera opencv_camera(int width, int height, double focal, const Eigen::Vector3d& position) {
  RenderCamera rc;
  rc.camera.K.width = width;
  rc.camera.K.height = height;
  rc.camera.K.fx = rc.camera.K.fy = focal;
  rc.camera.K.cx = width / 2.0;
  rc.camera.K.cy = height / 2.0;
  Eigen::Matrix4d c2w_cv = Eigen::Matrix4d::Identity();
  c2w_cv.block<3, 1>(0, 3) = position;
  rc.camera.c2w = opencv_to_opengl(c2w_cv);
  return rc;
}

// Random Gaussians in front of opencv_camera(w, h, ., (0,0,-dist)): means in a box around
// the origin, moderate scales, opacities in (0.3, 0.95), unnormalised quaternions.
inline GaussianSet random_scene(int64_t n, int sh_degree, torch::ScalarType dtype, uint64_t seed,
                                double spread = 1.0, double scale = 0.15) {
  torch::manual_seed(seed);
  const auto o = torch::TensorOptions().dtype(torch::kFloat64);
  GaussianSet g;
  g.means = (torch::rand({n, 3}, o) * 2 - 1) * spread;
  g.quats = torch::randn({n, 4}, o);
  g.scales = scale * (0.3 + torch::rand({n, 3}, o));
  g.opacities = 0.3 + 0.65 * torch::rand({n}, o);
  g.sh_degree = sh_degree;
  if (sh_degree < 0)
    g.colors = torch::rand({n, 3}, o);
  else
    g.colors = torch::randn({n, (sh_degree + 1) * (sh_degree + 1), 3}, o) * 0.4;
  for (torch::Tensor* t : {&g.means, &g.quats, &g.scales, &g.opacities, &g.colors}) *t = t->to(dtype);
  return g;
}

inline torch::Tensor tensor_of(const SafetensorsFile& f, const std::string& name, const std::filesystem::path& path) {
  const TensorData& t = f.at(name, path);
  const std::vector<float> v = t.to_float();
  return torch::tensor(v, torch::kFloat32).reshape(t.shape);
}

// brush's golden case (see shared/data/render-golden/PROVENANCE.md): log scales, logit
// opacities, SH degree 3, quaternions not normalised; out_img is H x W x RGBA.
struct GoldenCase {
  GaussianSet gaussians;
  RenderCamera camera;
  RenderOptions options;
  torch::Tensor image;  // (H, W, 4)
};

inline GoldenCase load_golden(const std::filesystem::path& path) {
  const SafetensorsFile f = read_safetensors(path);
  GoldenCase c;
  c.gaussians.means = tensor_of(f, "means", path);
  c.gaussians.quats = tensor_of(f, "quats", path);
  c.gaussians.scales = tensor_of(f, "scales", path).exp();
  c.gaussians.opacities = torch::sigmoid(tensor_of(f, "opacities", path));
  c.gaussians.colors = tensor_of(f, "coeffs", path);
  c.gaussians.sh_degree = 3;
  c.image = tensor_of(f, "out_img", path);
  const int h = static_cast<int>(c.image.size(0)), w = static_cast<int>(c.image.size(1));
  // 90° horizontal FOV: focal = W/2 for both axes; camera at (0.123, 0.456, -8).
  c.camera = opencv_camera(w, h, w / 2.0, Eigen::Vector3d(0.123, 0.456, -8.0));
  c.camera.far_plane = 1e10f;
  c.options.background = {0.f, 0.f, 0.f};
  return c;
}

inline double psnr(const torch::Tensor& a, const torch::Tensor& b) {
  const double mse = (a.to(torch::kFloat64) - b.to(torch::kFloat64)).pow(2).mean().item<double>();
  return mse <= 0 ? 1000.0 : 10.0 * std::log10(1.0 / mse);
}

// The largest absolute value; 0 for an empty tensor (LibTorch 2.x refuses max() of nothing,
// which a scene without Gaussians gives).
inline double max_abs(const torch::Tensor& a) { return a.numel() == 0 ? 0.0 : a.abs().max().item<double>(); }

inline double max_abs_diff(const torch::Tensor& a, const torch::Tensor& b) {
  return max_abs(a.to(torch::kFloat64) - b.to(torch::kFloat64));
}

}  // namespace ii::test
