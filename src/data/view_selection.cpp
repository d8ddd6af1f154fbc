#include "data/view_selection.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <set>

#include <fmt/ranges.h>

#include "common/error.h"

namespace ii {

int input_view_index(const Scene& scene, const std::string& name, const std::string& what) {
  const auto it = std::find_if(scene.views.begin(), scene.views.end(), [&](const View& v) { return v.name == name; });
  if (it != scene.views.end()) return static_cast<int>(it - scene.views.begin());
  std::vector<std::string> known;
  for (const View& v : scene.views) known.push_back(v.name);
  const bool is_test = std::any_of(scene.test_views.begin(), scene.test_views.end(),
                                   [&](const View& v) { return v.name == name; });
  fail("unknown {} '{}'{} (views: {})", what, name, is_test ? " (it is an object-free test view)" : "",
       fmt::join(known, ", "));
}

std::vector<int> context_views_by_name(const Scene& scene, const std::vector<std::string>& names) {
  std::vector<int> out;
  std::set<std::string> seen;
  for (const std::string& name : names) {
    if (!seen.insert(name).second) fail("context view '{}' is listed twice", name);
    out.push_back(input_view_index(scene, name, "context view"));
  }
  return out;
}

namespace {

// The views that may join `reference` in the context: those looking within kNeighbourCone of its
// direction (every view of a forward-facing capture: the statue's and the fern's lie within
// 8-10 degrees), at least `wanted` of them (the nearest in direction when fewer lie in the cone).
// A capture that walks around its object would otherwise get context views from its other sides,
// which see little of what the reference sees.
constexpr double kNeighbourCone = 30.0;  // degrees

std::vector<int> looking_alike(const Scene& scene, int reference, int wanted) {
  const int n = static_cast<int>(scene.views.size());
  // The optical axis: OpenGL camera-to-world, the camera looks along -z.
  auto axis = [&](int i) { return Eigen::Vector3d(-scene.views[static_cast<size_t>(i)].camera.c2w.block<3, 1>(0, 2)); };
  std::vector<std::pair<double, int>> by_angle;
  for (int i = 0; i < n; ++i)
    if (i != reference)
      by_angle.emplace_back(std::acos(std::clamp(axis(i).normalized().dot(axis(reference).normalized()), -1.0, 1.0)),
                            i);
  std::sort(by_angle.begin(), by_angle.end());
  const double cone = kNeighbourCone * M_PI / 180;
  std::vector<int> out;
  for (const auto& [angle, i] : by_angle)
    if (angle <= cone || static_cast<int>(out.size()) < wanted) out.push_back(i);
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace

std::vector<int> select_context_views(const Scene& scene, int count, std::optional<int> reference_view) {
  const int n = static_cast<int>(scene.views.size());
  if (count < 1) fail("the number of context views must be at least 1, got {}", count);
  if (n < count) fail("the scene has {} views, {} context views are needed", n, count);

  Eigen::MatrixXd centres(n, 3);
  for (int i = 0; i < n; ++i) centres.row(i) = scene.views[i].camera.center().transpose();
  const Eigen::RowVector3d mean = centres.colwise().mean();
  const Eigen::MatrixXd centred = centres.rowwise() - mean;

  // Best-fit plane: the two principal directions of the camera centres.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(centred.transpose() * centred);
  const Eigen::Matrix<double, 3, 2> basis = eig.eigenvectors().rightCols<2>();
  const Eigen::MatrixXd p = centred * basis;  // n x 2

  Eigen::Index nearest = 0;
  p.rowwise().squaredNorm().minCoeff(&nearest);
  if (reference_view && (*reference_view < 0 || *reference_view >= n))
    fail("reference view index {} is outside the scene's {} views", *reference_view, n);
  const int reference = reference_view.value_or(static_cast<int>(nearest));
  std::vector<int> chosen = {reference};
  if (count == 1) return chosen;
  const std::vector<int> neighbours = looking_alike(scene, reference, count - 1);

  if (count == 4) {
    auto area = [&](int a, int b, int c) {
      const Eigen::Vector2d u = p.row(b) - p.row(a), v = p.row(c) - p.row(a);
      return std::abs(u.x() * v.y() - u.y() * v.x());
    };
    // Exhaustive over a bounded candidate set keeps this O(n^3) small for long captures.
    std::vector<bool> alike(static_cast<size_t>(n), false);
    for (const int i : neighbours) alike[static_cast<size_t>(i)] = true;
    std::vector<int> candidates;
    const int stride = std::max(1, n / 120);
    for (int i = 0; i < n; i += stride)
      if (alike[static_cast<size_t>(i)]) candidates.push_back(i);
    double best = -1;
    std::array<int, 3> best_triple{};
    const int m = static_cast<int>(candidates.size());
    for (int a = 0; a < m; ++a)
      for (int b = a + 1; b < m; ++b)
        for (int c = b + 1; c < m; ++c) {
          const double s = area(candidates[a], candidates[b], candidates[c]);
          if (s > best) {
            best = s;
            best_triple = {candidates[a], candidates[b], candidates[c]};
          }
        }
    if (best >= 0) {
      chosen.insert(chosen.end(), best_triple.begin(), best_triple.end());
      std::sort(chosen.begin() + 1, chosen.end());
      return chosen;
    }
  }

  // Farthest-point sampling in the plane, starting from the reference.
  std::vector<double> dist(n, std::numeric_limits<double>::infinity());
  while (static_cast<int>(chosen.size()) < count) {
    const int last = chosen.back();
    int next = -1;
    for (const int i : neighbours) {
      dist[i] = std::min(dist[i], (p.row(i) - p.row(last)).squaredNorm());
      if (std::find(chosen.begin(), chosen.end(), i) == chosen.end() && (next < 0 || dist[i] > dist[next]))
        next = i;
    }
    chosen.push_back(next);
  }
  std::sort(chosen.begin() + 1, chosen.end());
  return chosen;
}

}  // namespace ii
