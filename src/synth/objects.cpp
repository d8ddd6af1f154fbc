// The inserted objects: procedural compositions of primitives, and real captured splats
// normalised to stand upright on the origin.
#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>

#include "common/error.h"
#include "io/ply.h"
#include "gaussians/gaussians.h"
#include "synth/scene_parts.h"

namespace ii::synth {

namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

Material object_material(SynthRng& rng, double size) {
  Material m;
  m.base = hsv(rng.uniform(), rng.uniform(0.45, 0.95), rng.uniform(0.45, 0.95));
  m.accent = rng.chance(0.5) ? hsv(rng.uniform(), rng.uniform(0.3, 0.9), rng.uniform(0.3, 1.0))
                             : Rgb(m.base * static_cast<float>(rng.uniform(0.3, 0.6)));
  m.pattern = rng.pick(std::vector<Pattern>{Pattern::solid, Pattern::solid, Pattern::stripes, Pattern::dots,
                                            Pattern::checker, Pattern::noise, Pattern::marble});
  m.scale = size * rng.uniform(0.12, 0.3);
  m.variation = 0.04;
  m.seed = static_cast<uint32_t>(rng.bits());
  return m;
}

Matrix3d random_rotation(SynthRng& rng, double max_tilt) {
  return (Eigen::AngleAxisd(rng.uniform(0, 2 * M_PI), Vector3d::UnitY()) *
          Eigen::AngleAxisd(rng.uniform(-max_tilt, max_tilt), Vector3d::UnitX()))
      .toRotationMatrix();
}

// Smooth profile through control radii at evenly spaced heights (cosine interpolation).
std::function<double(double)> profile(std::vector<double> radii) {
  return [radii](double t) {
    const double x = std::clamp(t, 0.0, 1.0) * (radii.size() - 1);
    const size_t i = std::min(static_cast<size_t>(x), radii.size() - 2);
    const double f = x - i, w = 0.5 - 0.5 * std::cos(M_PI * f);
    return radii[i] * (1 - w) + radii[i + 1] * w;
  };
}

struct Parts {
  SurfelSampler& sampler;
  const DetailMap& detail;
  SynthRng& rng;
  void ellipsoid(const Vector3d& c, const Vector3d& radii, const Matrix3d& rot, const Material& m) {
    sampler.ellipsoid(c, radii, rot, m, detail.spacing_sphere(c, radii.maxCoeff()));
  }
  void lathe(const Vector3d& base, double h, const std::function<double(double)>& r, double r_max, const Material& m,
             bool bottom, bool top) {
    sampler.lathe(base, h, r, m, detail.spacing_sphere(base + Vector3d(0, h / 2, 0), std::hypot(h / 2, r_max)), bottom,
                  top);
  }
  void box(const Vector3d& c, const Vector3d& half, double yaw, const Material& m) {
    sampler.box(c, half, yaw, m, detail.spacing_sphere(c, half.norm()), true);
  }
};

std::string stack(Parts& p, const Vector3d& base, double height, double footprint) {
  const int n = p.rng.integer(2, 4);
  std::vector<double> share(n);
  double total = 0;
  for (double& s : share) total += (s = p.rng.uniform(0.6, 1.4));
  double y = 0;
  for (int k = 0; k < n; ++k) {
    const double h = height * share[k] / total;
    const double r = footprint * p.rng.uniform(0.45, 1.0) * (k == 0 ? 1.0 : p.rng.uniform(0.7, 1.0));
    const Vector3d at = base + Vector3d(p.rng.uniform(-0.1, 0.1) * footprint, y, p.rng.uniform(-0.1, 0.1) * footprint);
    const Material m = object_material(p.rng, height);
    switch (p.rng.integer(0, 3)) {
      case 0:
        p.ellipsoid(at + Vector3d(0, h / 2, 0), {r, h / 2, r * p.rng.uniform(0.7, 1.0)}, random_rotation(p.rng, 0.0),
                    m);
        break;
      case 1: {
        const double hw = r / std::sqrt(2.0);
        p.box(at + Vector3d(0, h / 2, 0), {hw, h / 2, hw * p.rng.uniform(0.6, 1.0)}, p.rng.uniform(0, M_PI), m);
        break;
      }
      case 2: {
        const double top = r * p.rng.uniform(0.3, 1.0);
        p.lathe(
            at, h, [=](double t) { return r + (top - r) * t; }, r, m, true, true);
        break;
      }
      default:
        p.lathe(at, h, profile({r * 0.7, r, r * p.rng.uniform(0.4, 0.9), r * p.rng.uniform(0.3, 0.7)}), r, m, true,
                true);
        break;
    }
    y += h;
  }
  return "stack";
}

std::string blob(Parts& p, const Vector3d& base, double height, double footprint) {
  const int n = p.rng.integer(3, 7);
  const Material main = object_material(p.rng, height);
  for (int k = 0; k < n; ++k) {
    const Material m = p.rng.chance(0.6) ? main : object_material(p.rng, height);
    const Vector3d radii(footprint * p.rng.uniform(0.3, 0.6), height * p.rng.uniform(0.15, 0.3),
                         footprint * p.rng.uniform(0.3, 0.6));
    const double a = p.rng.uniform(0, 2 * M_PI), d = p.rng.uniform(0, footprint - radii.x());
    // The first rests on the base (slightly sunk in), the others pile up anywhere.
    const double y = k == 0 ? 0.9 * radii.y() : radii.y() + p.rng.uniform(0, std::max(0.0, height - 2 * radii.y()));
    p.ellipsoid(base + Vector3d(d * std::cos(a), y, d * std::sin(a)), radii, random_rotation(p.rng, 0.5), m);
  }
  return "blob";
}

std::string vase(Parts& p, const Vector3d& base, double height, double footprint) {
  std::vector<double> radii;
  const int controls = p.rng.integer(3, 5);
  for (int k = 0; k < controls; ++k) radii.push_back(footprint * p.rng.uniform(0.3, 1.0));
  const bool flowers = p.rng.chance(0.5);
  const double body = flowers ? height * 0.65 : height;
  p.lathe(base, body, profile(radii), footprint, object_material(p.rng, height), true, true);
  if (flowers) {
    const int n = p.rng.integer(2, 4);
    const Material stem = [&] {
      Material m;
      m.base = hsv(0.3, 0.6, 0.35);
      m.seed = static_cast<uint32_t>(p.rng.bits());
      return m;
    }();
    for (int k = 0; k < n; ++k) {
      const double a = p.rng.uniform(0, 2 * M_PI), d = radii.back() * 0.4;
      const Vector3d foot = base + Vector3d(d * std::cos(a), body, d * std::sin(a));
      const double h = height - body - 0.05 * height;
      p.lathe(
          foot, h, [&](double) { return 0.006 + 0.01 * footprint; }, 0.02, stem, false, false);
      const double r = footprint * p.rng.uniform(0.2, 0.35);
      p.ellipsoid(foot + Vector3d(0, h, 0), {r, r * 0.6, r}, Matrix3d::Identity(), object_material(p.rng, r * 4));
    }
  }
  return flowers ? "vase with flowers" : "vase";
}

std::string figure(Parts& p, const Vector3d& base, double height, double footprint) {
  const Material skin = object_material(p.rng, height);
  const Material cloth = object_material(p.rng, height);
  const double body_h = height * 0.6, head_r = std::min(height * 0.2, footprint * 0.7);
  const double body_r = footprint * p.rng.uniform(0.55, 0.85);
  p.lathe(base, body_h, profile({body_r, body_r * 0.9, body_r * p.rng.uniform(0.5, 0.8)}), body_r, cloth, true, true);
  const Vector3d head = base + Vector3d(0, body_h + head_r * 0.9, 0);
  p.ellipsoid(head, Vector3d::Constant(head_r), Matrix3d::Identity(), skin);
  const double facing = p.rng.uniform(0, 2 * M_PI);
  const Vector3d forward(std::cos(facing), 0, std::sin(facing)), side(-std::sin(facing), 0, std::cos(facing));
  Material eye;
  eye.base = Rgb(0.05f, 0.05f, 0.05f);
  eye.seed = static_cast<uint32_t>(p.rng.bits());
  for (int s : {-1, 1}) {
    p.ellipsoid(head + forward * head_r * 0.85 + side * (s * head_r * 0.35) + Vector3d(0, head_r * 0.15, 0),
                Vector3d::Constant(head_r * 0.15), Matrix3d::Identity(), eye);
    const Matrix3d arm_rot = Eigen::AngleAxisd(s * 0.45, forward).toRotationMatrix();  // arms held out
    p.ellipsoid(base + Vector3d(0, body_h * 0.65, 0) + side * (s * body_r * 1.05),
                {body_r * 0.25, body_h * 0.3, body_r * 0.25}, arm_rot, skin);
  }
  if (p.rng.chance(0.5)) {  // a hat
    const double r = head_r * 1.05;
    p.lathe(
        head + Vector3d(0, head_r * 0.6, 0), head_r * 1.1, [=](double t) { return r * (1 - t * 0.9); }, r,
        object_material(p.rng, height), true, false);
  }
  return "figure";
}

std::string mushroom(Parts& p, const Vector3d& base, double height, double footprint) {
  const double stem_r = footprint * p.rng.uniform(0.2, 0.35), stem_h = height * p.rng.uniform(0.5, 0.7);
  Material stem = object_material(p.rng, height);
  stem.pattern = Pattern::solid;
  stem.base = hsv(p.rng.uniform(0.08, 0.15), p.rng.uniform(0.05, 0.3), p.rng.uniform(0.75, 0.95));
  p.lathe(
      base, stem_h, [=](double t) { return stem_r * (1.2 - 0.3 * t); }, stem_r * 1.2, stem, true, false);
  Material cap = object_material(p.rng, height);
  if (p.rng.chance(0.6)) {
    cap.pattern = Pattern::dots;
    cap.accent = Rgb(0.95f, 0.95f, 0.9f);
  }
  const double cap_h = height - stem_h;
  p.ellipsoid(base + Vector3d(0, stem_h, 0), {footprint, cap_h, footprint}, Matrix3d::Identity(), cap);
  return "mushroom";
}

}  // namespace

void build_procedural_object(const Vector3d& base, double height, double footprint, const DetailMap& detail,
                             const Lighting& lighting, SynthRng& rng, GaussianBuilder& out,
                             nlohmann::json& description) {
  SurfelSampler sampler(out, lighting, rng);
  Parts parts{sampler, detail, rng};
  std::string kind;
  switch (rng.weighted({0.3, 0.2, 0.2, 0.15, 0.15})) {
    case 0:
      kind = stack(parts, base, height, footprint);
      break;
    case 1:
      kind = blob(parts, base, height, footprint);
      break;
    case 2:
      kind = vase(parts, base, height, footprint);
      break;
    case 3:
      kind = figure(parts, base, height, footprint);
      break;
    default:
      kind = mushroom(parts, base, height, footprint);
      break;
  }
  description = {{"kind", "procedural"}, {"shape", kind}, {"height", height}, {"footprint", footprint}};
}

std::vector<std::filesystem::path> list_splat_objects(const std::filesystem::path& dir) {
  std::vector<std::filesystem::path> files;
  if (dir.empty() || !std::filesystem::is_directory(dir)) return files;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.is_regular_file() && e.path().extension() == ".ply") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}

namespace {

// Value at fraction q of the sorted values (nearest rank).
float quantile(std::vector<float> v, double q) {
  if (v.empty()) return 0.f;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

GaussianSet normalize_splat(const std::filesystem::path& path) {
  const GaussianSet raw = gaussians_from_splats(read_splat_ply(path), 0);
  torch::Tensor rgb = rgb_from_sh_dc(raw.colors.select(1, 0)).clamp(0.0, 1.0);
  // Transparent splats add nothing but cost: drop them.
  torch::Tensor keep = raw.opacities > 0.1f;
  torch::Tensor means = raw.means.index({keep});
  if (means.size(0) < 10) fail_file(path, "fewer than 10 visible splats");
  // Robust box: floaters far from the object are cut.
  const torch::Tensor m = means.contiguous();
  std::array<float, 3> lo{}, hi{};
  for (int a = 0; a < 3; ++a) {
    const torch::Tensor col = m.select(1, a).contiguous();
    std::vector<float> v(col.data_ptr<float>(), col.data_ptr<float>() + col.numel());
    lo[a] = quantile(v, 0.005);
    hi[a] = quantile(v, 0.995);
  }
  torch::Tensor inside = torch::ones({raw.size()}, torch::kBool);
  for (int a = 0; a < 3; ++a) {
    const float margin = 0.05f * (hi[a] - lo[a]);
    const torch::Tensor c = raw.means.select(1, a);
    inside = inside & (c >= lo[a] - margin) & (c <= hi[a] + margin);
  }
  keep = keep & inside;
  GaussianSet g;
  g.means = raw.means.index({keep});
  torch::Tensor q = raw.quats.index({keep});
  g.scales = raw.scales.index({keep});
  g.opacities = raw.opacities.index({keep}).clamp_max(static_cast<float>(kMaxOpacity));
  g.colors = rgb.index({keep});
  g.sh_degree = -1;
  // Captures are y-down: turn by 180 degrees about x, (x, y, z) -> (x, -y, -z), rotations
  // pre-multiplied by the quaternion (0, 1, 0, 0).
  g.means = g.means * torch::tensor({1.f, -1.f, -1.f});
  g.quats = torch::stack({-q.select(1, 1), q.select(1, 0), -q.select(1, 3), q.select(1, 2)}, 1);
  // Stand on the origin, height 1.
  const float bottom = -hi[1], top = -lo[1];
  const float height = std::max(top - bottom, 1e-6f);
  const torch::Tensor offset = torch::tensor({0.5f * (lo[0] + hi[0]), bottom, -0.5f * (lo[2] + hi[2])});
  g.means = (g.means - offset) / height;
  g.scales = g.scales / height;
  return g;
}

}  // namespace

const GaussianSet& normalized_splat_object(const std::filesystem::path& path) {
  static std::mutex mutex;
  static std::map<std::string, GaussianSet> cache;
  std::lock_guard<std::mutex> lock(mutex);
  const std::string key = std::filesystem::absolute(path).lexically_normal().string();
  auto it = cache.find(key);
  if (it == cache.end()) it = cache.emplace(key, normalize_splat(path)).first;
  return it->second;
}

GaussianSet place_splat_object(const GaussianSet& normalized, const Vector3d& base, double height, double yaw) {
  const double c = std::cos(yaw), s = std::sin(yaw);
  // Rotation about +y: x' = c x + s z, z' = -s x + c z (Eigen::AngleAxisd(yaw, UnitY)).
  const torch::Tensor rot = torch::tensor({{c, 0.0, s}, {0.0, 1.0, 0.0}, {-s, 0.0, c}}, torch::kFloat32);
  GaussianSet g = normalized;
  g.means = torch::matmul(normalized.means * static_cast<float>(height), rot.t()) +
            torch::tensor({float(base.x()), float(base.y()), float(base.z())});
  g.scales = normalized.scales * static_cast<float>(height);
  const float hc = static_cast<float>(std::cos(yaw / 2)), hs = static_cast<float>(std::sin(yaw / 2));
  const torch::Tensor& q = normalized.quats;  // (cos, 0, sin, 0) x q
  g.quats = torch::stack({hc * q.select(1, 0) - hs * q.select(1, 2), hc * q.select(1, 1) + hs * q.select(1, 3),
                          hc * q.select(1, 2) + hs * q.select(1, 0), hc * q.select(1, 3) - hs * q.select(1, 1)},
                         1);
  return g;
}

}  // namespace ii::synth
