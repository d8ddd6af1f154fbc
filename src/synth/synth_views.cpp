#include "synth/synth_views.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "common/error.h"
#include "data/inpaint2d.h"
#include "synth/random.h"
#include "tensor/image_tensor.h"

namespace ii::synth {

namespace {

// A sub-rectangle of the image, pixel edges: columns [x0, x1), rows [y0, y1).
struct Window {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  bool empty() const { return x1 <= x0 || y1 <= y0; }
};

// Copies of the given rows of a float tensor with `width` values per row.
torch::Tensor take_rows(const torch::Tensor& t, const std::vector<int64_t>& rows, int64_t width) {
  torch::Tensor out = torch::empty({static_cast<int64_t>(rows.size()), width}, torch::kFloat32);
  const float* src = t.data_ptr<float>();
  float* dst = out.data_ptr<float>();
  for (size_t i = 0; i < rows.size(); ++i) std::memcpy(dst + i * width, src + rows[i] * width, width * sizeof(float));
  return out;
}

}  // namespace

SynthRenderer::SynthRenderer(const SynthScene& scene) : scene_(scene), background_count_(scene.background.size()) {
  const GaussianSet all = combined_gaussians(scene);
  means_ = all.means.to(torch::kFloat32).contiguous();
  quats_ = all.quats.to(torch::kFloat32).contiguous();
  scales_ = all.scales.to(torch::kFloat32).contiguous();
  opacities_ = all.opacities.to(torch::kFloat32).reshape({-1, 1}).contiguous();
  colors_ = all.colors.to(torch::kFloat32).contiguous();
  const torch::Tensor largest = std::get<0>(scales_.max(1)).contiguous();
  reach_.assign(largest.data_ptr<float>(), largest.data_ptr<float>() + largest.numel());
  for (float& r : reach_) r *= 6.0f;
}

GaussianSet SynthRenderer::rows(const std::vector<int64_t>& rows) const {
  GaussianSet g;
  g.means = take_rows(means_, rows, 3);
  g.quats = take_rows(quats_, rows, 4);
  g.scales = take_rows(scales_, rows, 3);
  g.opacities = take_rows(opacities_, rows, 1).reshape({-1});
  g.colors = take_rows(colors_, rows, 3);
  g.sh_degree = -1;
  return g;
}

// How far a Gaussian can reach on screen: 6 sigma (its largest scale) plus 4 pixels. Splats
// are cut at 3 sigma and alpha < 1/255 is skipped (beyond 3.4 sigma of the 2D covariance,
// which the perspective Jacobian stretches by at most ~1.5 and the rasterizer's 0.3 px^2 blur
// widens by < 2 px), so nothing outside this reach is ever drawn.
std::vector<int64_t> SynthRenderer::visible_rows(const Camera& camera, const std::vector<float>& points, int x0, int y0,
                                                 int x1, int y1) const {
  const Intrinsics& K = camera.K;
  const double pixel = 4.0 / std::min(K.fx, K.fy);
  // Inward unit normals of the window's four side planes: u >= x0, u <= x1, v >= y0, v <= y1.
  double sides[4][3] = {{K.fx, 0, K.cx - x0}, {-K.fx, 0, x1 - K.cx}, {0, K.fy, K.cy - y0}, {0, -K.fy, y1 - K.cy}};
  for (auto& n : sides) {
    const double norm = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (double& c : n) c /= norm;
  }
  std::vector<int64_t> rows;
  const int64_t n = static_cast<int64_t>(reach_.size());
  for (int64_t i = 0; i < n; ++i) {
    const float* p = &points[3 * i];
    if (!(p[2] > 0)) continue;  // the rasterizer culls these itself (camera z below its near plane)
    const double margin = reach_[i] + p[2] * pixel;
    bool inside = true;
    for (const auto& s : sides) inside = inside && s[0] * p[0] + s[1] * p[1] + s[2] * p[2] >= -margin;
    if (inside) rows.push_back(i);
  }
  return rows;
}

SynthViewImages SynthRenderer::render(const Camera& camera, bool with_object) const {
  torch::NoGradGuard no_grad;
  const Intrinsics& K = camera.K;
  RenderCamera rc;
  rc.camera = camera;
  RenderOptions options;
  options.background = scene_.render_background;
  RenderOptions black = options;
  black.background = {0.f, 0.f, 0.f};

  // Means in the camera's frame (OpenCV axes).
  const Eigen::Matrix4d w2c = camera.w2c_opencv();
  const int64_t n = static_cast<int64_t>(reach_.size());
  std::vector<float> points(3 * n);
  const float* m = means_.data_ptr<float>();
  for (int64_t i = 0; i < n; ++i) {
    const Eigen::Vector3d x =
        w2c.topLeftCorner<3, 3>() * Eigen::Vector3d(m[3 * i], m[3 * i + 1], m[3 * i + 2]) + w2c.topRightCorner<3, 1>();
    for (int c = 0; c < 3; ++c) points[3 * i + c] = static_cast<float>(x[c]);
  }

  // Culling keeps the rows in order, so every pixel composites the same Gaussians in the
  // same order as a render of the full set: the results are identical, only cheaper.
  SynthViewImages out;
  std::vector<int64_t> background_rows = visible_rows(camera, points, 0, 0, K.width, K.height);
  background_rows.erase(std::lower_bound(background_rows.begin(), background_rows.end(), background_count_),
                        background_rows.end());
  const RenderOutput clean = ii::render(rows(background_rows), rc, options);
  out.clean = image_from_hwc(clean.rgb);
  out.clean_depth = image_from_hwc(clean.depth);
  if (with_object) {
    out.with_object = out.clean;
    out.depth = out.clean_depth;
  }
  out.object_weight = Image(K.width, K.height, 1);
  out.mask = Image(K.width, K.height, 1);
  if (n == background_count_) return out;

  // The object touches only the window around its splats' reach; outside it, the image with
  // the object is exactly the clean one and the object's weight is 0.
  Window window{0, 0, K.width, K.height};
  bool in_front = true;
  double u0 = INFINITY, u1 = -INFINITY, v0 = INFINITY, v1 = -INFINITY;
  for (int64_t i = background_count_; i < n && in_front; ++i) {
    const float* p = &points[3 * i];
    in_front = p[2] > 0.05f;
    const double reach_px = (reach_[i] / p[2]) * std::max(K.fx, K.fy) + 4.0;
    const double u = K.fx * p[0] / p[2] + K.cx, v = K.fy * p[1] / p[2] + K.cy;
    u0 = std::min(u0, u - reach_px);
    u1 = std::max(u1, u + reach_px);
    v0 = std::min(v0, v - reach_px);
    v1 = std::max(v1, v + reach_px);
  }
  if (in_front) {  // else an object splat is at or behind the camera: the whole image
    window.x0 = static_cast<int>(std::clamp(std::floor(u0), 0.0, double(K.width)));
    window.x1 = static_cast<int>(std::clamp(std::ceil(u1) + 1, 0.0, double(K.width)));
    window.y0 = static_cast<int>(std::clamp(std::floor(v0), 0.0, double(K.height)));
    window.y1 = static_cast<int>(std::clamp(std::ceil(v1) + 1, 0.0, double(K.height)));
  }
  if (window.empty()) return out;
  const std::vector<int64_t> near_rows = visible_rows(camera, points, window.x0, window.y0, window.x1, window.y1);
  GaussianSet near_object = rows(near_rows);
  auto paste = [&](const torch::Tensor& hwc, Image& target) {
    const Image full = image_from_hwc(hwc);
    for (int y = window.y0; y < window.y1; ++y)
      for (int x = window.x0; x < window.x1; ++x)
        for (int c = 0; c < target.channels; ++c) target.at(y, x, c) = full.at(y, x, c);
  };
  if (with_object) {
    const RenderOutput captured = ii::render(near_object, rc, options);
    paste(captured.rgb, out.with_object);
    paste(captured.depth, out.depth);
  }
  torch::Tensor indicator = torch::zeros({static_cast<int64_t>(near_rows.size()), 3});
  const auto first_object = std::lower_bound(near_rows.begin(), near_rows.end(), background_count_) - near_rows.begin();
  indicator.narrow(0, first_object, indicator.size(0) - first_object).fill_(1.f);
  near_object.colors = indicator;
  paste(ii::render(near_object, rc, black).rgb.narrow(2, 0, 1), out.object_weight);
  for (size_t i = 0; i < out.mask.pixels.size(); ++i)
    out.mask.pixels[i] = out.object_weight.pixels[i] >= kMaskWeightThreshold ? 1.f : 0.f;
  return out;
}

Degradation parse_degradation(const std::string& text, const std::string& what) {
  if (text == "none") return Degradation::none;
  if (text == "blur") return Degradation::blur;
  if (text == "color") return Degradation::color;
  if (text == "noise") return Degradation::noise;
  if (text == "telea") return Degradation::telea;
  if (text == "mixed") return Degradation::mixed;
  fail("{}: unknown degradation '{}' (expected none, blur, color, noise, telea or mixed)", what, text);
}

std::string to_string(Degradation mode) {
  switch (mode) {
    case Degradation::none:
      return "none";
    case Degradation::blur:
      return "blur";
    case Degradation::color:
      return "color";
    case Degradation::noise:
      return "noise";
    case Degradation::telea:
      return "telea";
    default:
      return "mixed";
  }
}

namespace {

cv::Mat as_mat(const Image& image) {
  return cv::Mat(image.height, image.width, CV_32FC(image.channels), const_cast<float*>(image.pixels.data())).clone();
}

Image from_mat(const cv::Mat& m) {
  Image out(m.cols, m.rows, m.channels());
  cv::Mat view(m.rows, m.cols, CV_32FC(m.channels()), out.pixels.data());
  m.copyTo(view);
  return out;
}

void check_same_size(const Image& a, const Image& b, const char* what) {
  if (a.width != b.width || a.height != b.height)
    fail("degrade_reference: {} is {}x{}, the clean image {}x{}", what, b.width, b.height, a.width, a.height);
}

}  // namespace

Image degrade_reference(const Image& clean, const Image& with_object, const Image& mask, Degradation mode,
                        uint64_t seed, std::string* applied) {
  if (clean.channels != 3) fail("degrade_reference: the clean image must be RGB");
  check_same_size(clean, mask, "the mask");
  SynthRng rng(seed);
  if (mode == Degradation::mixed)
    mode = std::vector<Degradation>{Degradation::blur, Degradation::color, Degradation::noise, Degradation::telea,
                                    Degradation::mixed}[rng.integer(0, 4)];  // mixed here = blur + color
  const bool combo = mode == Degradation::mixed;
  if (applied) *applied = combo ? "blur+color" : to_string(mode);
  if (mode == Degradation::none) return clean;

  // Dilated mask and its feathered version.
  const int side = std::min(clean.width, clean.height);
  const int grow = std::max(1, static_cast<int>(std::lround(side * rng.uniform(0.01, 0.025))));
  cv::Mat hard = as_mat(mask) > 0.5f;
  cv::dilate(hard, hard, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * grow + 1, 2 * grow + 1)));
  cv::Mat hard_weight, soft;
  hard.convertTo(hard_weight, CV_32F, 1.0 / 255.0);
  cv::GaussianBlur(hard_weight, soft, cv::Size(0, 0), std::max(0.5, grow / 2.0));
  soft = cv::max(soft, hard_weight);  // 1 inside the dilated mask, fading outside

  const cv::Mat base = as_mat(clean);
  cv::Mat filled = base.clone();
  if (mode == Degradation::blur || combo) {
    const double sigma = side * rng.uniform(0.01, 0.03);
    cv::GaussianBlur(filled, filled, cv::Size(0, 0), sigma);
  }
  if (mode == Degradation::color || combo) {
    const cv::Scalar gain(rng.uniform(0.85, 1.15), rng.uniform(0.85, 1.15), rng.uniform(0.85, 1.15));
    const cv::Scalar offset(rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05));
    cv::multiply(filled, gain, filled);
    cv::add(filled, offset, filled);
    // A soft brightness ramp across the image.
    const double angle = rng.uniform(0, 2 * M_PI), amount = rng.uniform(0.0, 0.08);
    for (int y = 0; y < filled.rows; ++y)
      for (int x = 0; x < filled.cols; ++x) {
        const double t = ((x - filled.cols / 2.0) * std::cos(angle) + (y - filled.rows / 2.0) * std::sin(angle)) / side;
        filled.at<cv::Vec3f>(y, x) *= static_cast<float>(1.0 + amount * t);
      }
  }
  if (mode == Degradation::noise) {
    const int cells = 8;
    cv::Mat coarse(cells, cells, CV_32FC3);
    for (int y = 0; y < cells; ++y)
      for (int x = 0; x < cells; ++x)
        for (int c = 0; c < 3; ++c) coarse.at<cv::Vec3f>(y, x)[c] = static_cast<float>(rng.normal());
    cv::Mat field;
    cv::resize(coarse, field, filled.size(), 0, 0, cv::INTER_CUBIC);
    filled += field * rng.uniform(0.03, 0.08);
  }
  if (mode == Degradation::telea) {
    check_same_size(clean, with_object, "the with-object image");
    Image dilated(clean.width, clean.height, 1);
    for (int y = 0; y < hard.rows; ++y)
      for (int x = 0; x < hard.cols; ++x) dilated.at(y, x) = hard.at<uint8_t>(y, x) ? 1.f : 0.f;
    filled = as_mat(inpaint_telea(with_object, dilated, 5.0));
  }
  // Blend: the fill inside the (feathered) dilated mask, the clean image outside.
  cv::Mat weight3;
  cv::merge(std::vector<cv::Mat>{soft, soft, soft}, weight3);
  cv::Mat out = filled.mul(weight3) + base.mul(cv::Scalar::all(1.0) - weight3);
  cv::min(cv::max(out, 0.0), 1.0, out);
  return from_mat(out);
}

}  // namespace ii::synth
