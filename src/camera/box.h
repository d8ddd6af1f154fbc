#pragma once
// A box in a scene's own frame, as a user gives it (fill --box, the page's box).
#include <Eigen/Dense>

#include <string>

namespace ii {

// A box: centre, full size along its own axes, turned by `rotation_deg` about x, then y, then z.
struct OrientedBox {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  Eigen::Vector3d size = Eigen::Vector3d::Ones();
  Eigen::Vector3d rotation_deg = Eigen::Vector3d::Zero();

  bool contains(const Eigen::Vector3d& point) const;
  std::string describe() const;  // "centre (x, y, z), size (...)[, turned (...) degrees]"
};
// "cx,cy,cz,sx,sy,sz" or "cx,cy,cz,sx,sy,sz,rx,ry,rz" (degrees); an Error naming --box otherwise.
OrientedBox parse_box(const std::string& text);

}  // namespace ii
