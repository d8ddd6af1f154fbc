#include "synth/surfels.h"

#include <algorithm>
#include <cmath>

namespace ii::synth {

namespace {

// Fraction of the grid cell a Gaussian's standard deviation spans along the surface: with
// 0.6 neighbouring Gaussians overlap enough for an opaque, seamless surface.
constexpr double kSigmaPerCell = 0.6;
// Thickness of a surfel relative to its cell.
constexpr double kThickness = 0.08;
// Positional jitter, fraction of a cell: breaks the grid's regularity (no moiré).
constexpr double kJitter = 0.3;

torch::Tensor tensor_from(const std::vector<float>& v, std::vector<int64_t> shape) {
  return torch::from_blob(const_cast<float*>(v.data()), shape, torch::kFloat32).clone();
}

}  // namespace

void GaussianBuilder::add(const Eigen::Vector3d& mean, const Eigen::Matrix3d& rotation, const Eigen::Vector3d& scales,
                          double opacity, const Rgb& rgb) {
  const Eigen::Quaterniond q(rotation);
  means_.insert(means_.end(), {float(mean.x()), float(mean.y()), float(mean.z())});
  quats_.insert(quats_.end(), {float(q.w()), float(q.x()), float(q.y()), float(q.z())});
  scales_.insert(scales_.end(), {float(scales.x()), float(scales.y()), float(scales.z())});
  opacities_.push_back(static_cast<float>(std::clamp(opacity, 0.0, kMaxOpacity)));
  colors_.insert(colors_.end(), {rgb.x(), rgb.y(), rgb.z()});
}

void GaussianBuilder::append(const GaussianSet& set) {
  if (set.size() == 0) return;
  if (set.sh_degree >= 0) fail("GaussianBuilder::append: expects RGB colours, got SH degree {}", set.sh_degree);
  auto values = [](const torch::Tensor& t) {
    const torch::Tensor c = t.to(torch::kFloat32).contiguous().cpu();
    return std::vector<float>(c.data_ptr<float>(), c.data_ptr<float>() + c.numel());
  };
  const auto m = values(set.means), q = values(set.quats), s = values(set.scales), o = values(set.opacities),
             c = values(set.colors);
  means_.insert(means_.end(), m.begin(), m.end());
  quats_.insert(quats_.end(), q.begin(), q.end());
  scales_.insert(scales_.end(), s.begin(), s.end());
  for (float v : o) opacities_.push_back(std::min(v, static_cast<float>(kMaxOpacity)));
  colors_.insert(colors_.end(), c.begin(), c.end());
}

GaussianSet GaussianBuilder::build() const {
  const int64_t n = static_cast<int64_t>(size());
  GaussianSet g;
  g.means = tensor_from(means_, {n, 3});
  g.quats = tensor_from(quats_, {n, 4});
  g.scales = tensor_from(scales_, {n, 3});
  g.opacities = tensor_from(opacities_, {n});
  g.colors = tensor_from(colors_, {n, 3});
  g.sh_degree = -1;
  return g;
}

Rgb Lighting::shade(const Rgb& albedo, const Eigen::Vector3d& p, const Eigen::Vector3d& n) const {
  double s = ambient + key * std::max(0.0, n.dot(key_direction));
  const double d2 = (p - lamp).squaredNorm();
  s *= 1.0 + lamp_gain * (1.0 / (1.0 + d2 / (lamp_radius * lamp_radius)) - 0.3);

  // Darkening towards the room's edges: for each of the six planes not parallel to this
  // surface, by the distance to it.
  double occlusion = 1.0;
  auto near_plane = [&](double distance, const Eigen::Vector3d& plane_normal) {
    if (std::abs(n.dot(plane_normal)) < 0.5) occlusion *= 1.0 - 0.28 * std::exp(-std::max(0.0, distance) / 0.22);
  };
  near_plane(p.y() - room_min.y(), Eigen::Vector3d::UnitY());
  near_plane(room_max.y() - p.y(), Eigen::Vector3d::UnitY());
  near_plane(p.x() - room_min.x(), Eigen::Vector3d::UnitX());
  near_plane(room_max.x() - p.x(), Eigen::Vector3d::UnitX());
  near_plane(p.z() - room_min.z(), Eigen::Vector3d::UnitZ());
  near_plane(room_max.z() - p.z(), Eigen::Vector3d::UnitZ());

  // Contact shadows of furniture on the floor.
  if (n.y() > 0.7 && p.y() - room_min.y() < 0.02) {
    for (const Contact& c : contacts) {
      const double dx = p.x() - c.centre.x(), dz = p.z() - c.centre.y();
      const double cs = std::cos(c.yaw), sn = std::sin(c.yaw);
      const double lx = std::abs(cs * dx - sn * dz) - c.half.x();
      const double lz = std::abs(sn * dx + cs * dz) - c.half.y();
      const double outside = std::hypot(std::max(lx, 0.0), std::max(lz, 0.0));
      occlusion *= 1.0 - c.strength * std::exp(-outside / 0.12);
    }
  }
  const Rgb c = albedo.cwiseProduct(tint) * static_cast<float>(s * occlusion);
  return c.cwiseMax(0.f).cwiseMin(1.f);
}

void SurfelSampler::emit(const Eigen::Vector3d& p, const Eigen::Vector3d& t1, const Eigen::Vector3d& normal,
                         double size1, double size2, const Rgb& albedo, const Material& material) {
  const Eigen::Vector3d n = normal.normalized();
  Eigen::Vector3d a = t1 - n * n.dot(t1);
  if (a.norm() < 1e-9) a = n.unitOrthogonal();
  a.normalize();
  const Eigen::Vector3d b = n.cross(a);
  Eigen::Matrix3d rotation;
  rotation << a, b, n;
  const Eigen::Vector3d jittered =
      p + a * (rng_.uniform(-kJitter, kJitter) * size1) + b * (rng_.uniform(-kJitter, kJitter) * size2);
  const Eigen::Vector3d scales(kSigmaPerCell * size1, kSigmaPerCell * size2, kThickness * std::min(size1, size2));
  const Rgb colour = material.lit ? lighting_.shade(albedo, jittered, n) : albedo;
  out_.add(jittered, rotation, scales, material.opacity, colour);
}

void SurfelSampler::rect(const Eigen::Vector3d& origin, const Eigen::Vector3d& u, const Eigen::Vector3d& v,
                         double length_u, double length_v, const Material& material, double spacing,
                         const Eigen::Vector2d& uv_offset) {
  if (length_u <= 0 || length_v <= 0) return;
  const int nu = std::max(1, static_cast<int>(std::ceil(length_u / spacing)));
  const int nv = std::max(1, static_cast<int>(std::ceil(length_v / spacing)));
  const double du = length_u / nu, dv = length_v / nv;
  const Eigen::Vector3d normal = u.cross(v);
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const double su = (i + 0.5) * du, sv = (j + 0.5) * dv;
      const Eigen::Vector3d p = origin + u * su + v * sv;
      emit(p, u, normal, du, dv, material.colour(su + uv_offset.x(), sv + uv_offset.y(), p), material);
    }
}

void SurfelSampler::box(const Eigen::Vector3d& centre, const Eigen::Vector3d& half, double yaw,
                        const Material& material, double spacing, bool bottom) {
  const Eigen::Matrix3d r = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Vector3d x = r.col(0), y = r.col(1), z = r.col(2);
  const double hx = half.x(), hy = half.y(), hz = half.z();
  // Each face: corner, axes (u x v points outwards), lengths.
  rect(centre + y * hy - x * hx + z * hz, x, -z, 2 * hx, 2 * hz, material, spacing);  // top
  if (bottom) rect(centre - y * hy - x * hx - z * hz, x, z, 2 * hx, 2 * hz, material, spacing);
  rect(centre + z * hz - x * hx - y * hy, x, y, 2 * hx, 2 * hy, material, spacing);   // +z
  rect(centre - z * hz + x * hx - y * hy, -x, y, 2 * hx, 2 * hy, material, spacing);  // -z
  rect(centre + x * hx + z * hz - y * hy, -z, y, 2 * hz, 2 * hy, material, spacing);  // +x
  rect(centre - x * hx - z * hz - y * hy, z, y, 2 * hz, 2 * hy, material, spacing);   // -x
}

void SurfelSampler::disc(const Eigen::Vector3d& centre, double radius, bool facing_up, const Material& material,
                         double spacing) {
  if (radius <= 0) return;
  const int rings = std::max(1, static_cast<int>(std::ceil(radius / spacing)));
  const double dr = radius / rings;
  const Eigen::Vector3d normal(0, facing_up ? 1.0 : -1.0, 0);
  for (int k = 0; k < rings; ++k) {
    const double rho = (k + 0.5) * dr;
    const int segments = std::max(3, static_cast<int>(std::ceil(2 * M_PI * rho / spacing)));
    const double step = 2 * M_PI * rho / segments;
    const double phase = rng_.uniform(0, 2 * M_PI);
    for (int s = 0; s < segments; ++s) {
      const double th = phase + 2 * M_PI * (s + 0.5) / segments;
      const Eigen::Vector3d p = centre + Eigen::Vector3d(rho * std::cos(th), 0, rho * std::sin(th));
      const Eigen::Vector3d tangent(-std::sin(th), 0, std::cos(th));
      emit(p, tangent, normal, step, dr, material.colour(p.x() - centre.x(), p.z() - centre.z(), p), material);
    }
  }
}

void SurfelSampler::lathe(const Eigen::Vector3d& base, double height, const std::function<double(double)>& radius,
                          const Material& material, double spacing, bool bottom_cap, bool top_cap) {
  if (height <= 0) return;
  // Rings evenly spaced in profile arc length (approximated on a fine polyline).
  constexpr int kFine = 64;
  std::vector<double> arc(kFine + 1, 0.0);
  for (int i = 1; i <= kFine; ++i) {
    const double t0 = double(i - 1) / kFine, t1 = double(i) / kFine;
    arc[i] = arc[i - 1] + std::hypot(radius(t1) - radius(t0), height * (t1 - t0));
  }
  const double length = arc[kFine];
  const int rings = std::max(1, static_cast<int>(std::ceil(length / spacing)));
  const double ds = length / rings;
  double mean_radius = 0;
  for (int i = 0; i <= kFine; ++i) mean_radius += radius(double(i) / kFine) / (kFine + 1);
  for (int k = 0; k < rings; ++k) {
    const double s = (k + 0.5) * ds;
    const int seg = static_cast<int>(std::upper_bound(arc.begin(), arc.end(), s) - arc.begin()) - 1;
    const int i = std::clamp(seg, 0, kFine - 1);
    const double f = (s - arc[i]) / std::max(arc[i + 1] - arc[i], 1e-12);
    const double t = (i + f) / kFine;
    const double r = radius(t);
    if (r <= 1e-6) continue;
    const double h = 1e-3;
    const double drdy = (radius(std::min(1.0, t + h)) - radius(std::max(0.0, t - h))) /
                        (height * (std::min(1.0, t + h) - std::max(0.0, t - h)));
    const int segments = std::max(6, static_cast<int>(std::ceil(2 * M_PI * r / spacing)));
    const double step = 2 * M_PI * r / segments;
    const double phase = rng_.uniform(0, 2 * M_PI);
    for (int j = 0; j < segments; ++j) {
      const double th = phase + 2 * M_PI * (j + 0.5) / segments;
      const double c = std::cos(th), sn = std::sin(th);
      const Eigen::Vector3d p = base + Eigen::Vector3d(r * c, t * height, r * sn);
      const Eigen::Vector3d tangent(-sn, 0, c);
      const Eigen::Vector3d normal(c, -drdy, sn);
      emit(p, tangent, normal, step, ds, material.colour(th * mean_radius, s, p), material);
    }
  }
  if (bottom_cap) disc(base, radius(0.0), false, material, spacing);
  if (top_cap) disc(base + Eigen::Vector3d(0, height, 0), radius(1.0), true, material, spacing);
}

void SurfelSampler::ellipsoid(const Eigen::Vector3d& centre, const Eigen::Vector3d& radii,
                              const Eigen::Matrix3d& rotation, const Material& material, double spacing) {
  const double r_max = radii.maxCoeff();
  if (r_max <= 0) return;
  const int rings = std::max(2, static_cast<int>(std::ceil(M_PI * r_max / spacing)));
  const double dphi = M_PI / rings;
  for (int k = 0; k < rings; ++k) {
    const double phi = (k + 0.5) * dphi;
    const double sp = std::sin(phi), cp = std::cos(phi);
    const int segments = std::max(3, static_cast<int>(std::ceil(2 * M_PI * sp * r_max / spacing)));
    const double dth = 2 * M_PI / segments;
    const double phase = rng_.uniform(0, 2 * M_PI);
    for (int j = 0; j < segments; ++j) {
      const double th = phase + (j + 0.5) * dth;
      const double ct = std::cos(th), st = std::sin(th);
      const Eigen::Vector3d unit(sp * ct, cp, sp * st);
      const Eigen::Vector3d p = centre + rotation * radii.cwiseProduct(unit);
      const Eigen::Vector3d d_theta = rotation * radii.cwiseProduct(Eigen::Vector3d(-sp * st, 0, sp * ct));
      const Eigen::Vector3d d_phi = rotation * radii.cwiseProduct(Eigen::Vector3d(cp * ct, -sp, cp * st));
      const Eigen::Vector3d normal = rotation * unit.cwiseQuotient(radii);
      emit(p, d_theta, normal, d_theta.norm() * dth, d_phi.norm() * dphi, material.colour(th * r_max, phi * r_max, p),
           material);
    }
  }
}

}  // namespace ii::synth
