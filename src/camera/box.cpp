#include "camera/box.h"

#include <fmt/format.h>

#include <cmath>
#include <sstream>
#include <vector>

#include "common/error.h"

namespace ii {

namespace {

Eigen::Matrix3d box_rotation(const Eigen::Vector3d& deg) {
  const Eigen::Vector3d r = deg * M_PI / 180.0;
  return (Eigen::AngleAxisd(r.z(), Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(r.y(), Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(r.x(), Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

}  // namespace

bool OrientedBox::contains(const Eigen::Vector3d& point) const {
  const Eigen::Vector3d local = box_rotation(rotation_deg).transpose() * (point - centre);
  return (local.array().abs() <= size.array() / 2).all();
}

std::string OrientedBox::describe() const {
  std::string s = fmt::format("centre ({:.4g}, {:.4g}, {:.4g}), size ({:.4g}, {:.4g}, {:.4g})", centre.x(), centre.y(),
                              centre.z(), size.x(), size.y(), size.z());
  if (!rotation_deg.isZero())
    s += fmt::format(", turned ({:.4g}, {:.4g}, {:.4g}) degrees", rotation_deg.x(), rotation_deg.y(), rotation_deg.z());
  return s;
}

OrientedBox parse_box(const std::string& text) {
  std::vector<double> v;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    char* end = nullptr;
    const double x = std::strtod(item.c_str(), &end);
    if (item.empty() || end != item.c_str() + item.size() || !std::isfinite(x))
      fail("--box '{}': '{}' is not a number (expected cx,cy,cz,sx,sy,sz[,rx,ry,rz])", text, item);
    v.push_back(x);
  }
  if (v.size() != 6 && v.size() != 9)
    fail("--box '{}': {} numbers, expected 6 (centre, size) or 9 (centre, size, rotation in degrees)", text, v.size());
  OrientedBox box;
  box.centre = {v[0], v[1], v[2]};
  box.size = {v[3], v[4], v[5]};
  if (v.size() == 9) box.rotation_deg = {v[6], v[7], v[8]};
  if ((box.size.array() <= 0).any()) fail("--box '{}': the size must be positive along every axis", text);
  return box;
}

}  // namespace ii
