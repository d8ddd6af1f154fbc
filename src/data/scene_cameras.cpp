#include "data/scene_cameras.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "common/error.h"

namespace ii {

namespace {

const View* pick_view(const Scene& scene, const std::string& name) {
  const View* v = scene.find(name);
  if (!v) fail("--orbit-center: no view named '{}' in {}", name, scene.root.string());
  return v;
}

}  // namespace

std::vector<NamedCamera> scene_cameras(const Scene& scene, const SceneCameraOptions& a) {
  const PoseNormalization norm = scene_normalization(scene);
  auto frame = [&](const Camera& c) { return a.normalize ? norm.apply(c) : c; };

  std::vector<const View*> selected;
  if (!a.views.empty()) {
    for (const std::string& name : a.views) {
      const View* v = scene.find(name);
      if (!v) fail("--views: no view named '{}' in {}", name, scene.root.string());
      selected.push_back(v);
    }
  } else {
    const auto& list = a.test_views ? scene.test_views : scene.views;
    if (list.empty()) fail("{} has no {}", scene.root.string(), a.test_views ? "test views" : "views");
    for (const View& v : list) selected.push_back(&v);
  }

  std::vector<NamedCamera> out;
  if (a.trajectory.empty()) {
    for (const View* v : selected) out.push_back({v->name, resized_to(frame(v->camera), a.width, a.height)});
    return out;
  }
  if (a.trajectory == "path") {
    std::vector<Camera> keys;
    for (const View* v : selected) keys.push_back(frame(v->camera));
    const Intrinsics K = resized_to(keys.front(), a.width, a.height).K;
    for (const Camera& c : smooth_path(keys, a.frames, K)) out.push_back({fmt::format("{:04d}", out.size()), c});
    return out;
  }
  // orbit (spec §5.6): the training cameras define the plane; fov_x = fov_y of the first
  // target camera; 512 x 512 unless given.
  std::vector<Camera> train;
  for (const View& v : scene.views) train.push_back(frame(v.camera));
  Eigen::Vector3d centre;
  if (!a.orbit_center.empty()) {
    centre = frame(pick_view(scene, a.orbit_center)->camera).center();
  } else {
    centre = central_camera_position(train);  // no vis_centroid file
  }
  const double radius = a.radius > 0 ? a.radius : (a.normalize ? kOfficialOrbitRadius / norm.scale : kOfficialOrbitRadius);
  const Camera& first = selected.front()->camera;
  const int w = a.width > 0 ? a.width : 512, h = a.height > 0 ? a.height : 512;
  const Intrinsics K = intrinsics_fov_y(w, h, first.K.fov_y());
  spdlog::info("orbit: radius {:.3g} around ({:.3g}, {:.3g}, {:.3g})", radius, centre.x(), centre.y(), centre.z());
  for (const Camera& c : orbit_path(train, centre, radius, a.frames, K))
    out.push_back({fmt::format("{:04d}", out.size()), c});
  return out;
}

}  // namespace ii
