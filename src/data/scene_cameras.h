#pragma once
// Cameras to render a scene from (`render --scene`): its views as they are, a smooth path
// through them, or the official video orbit (spec §5.6), in the scene's frame or the
// pose-normalised one that `infer` writes Gaussians in.
#include <string>
#include <vector>

#include "camera/trajectory.h"
#include "data/scene.h"

namespace ii {

struct SceneCameraOptions {
  std::vector<std::string> views;  // by name; empty = every view (or every test view)
  bool test_views = false;
  bool normalize = false;          // the pose-normalised frame (scene_normalization)
  std::string trajectory;          // "" = the views themselves, "path" or "orbit"
  std::string orbit_center;        // the view whose position the orbit turns around; "" = central
  double radius = 0;               // orbit radius; 0 = the official 4 scene units
  int frames = 72;                 // path and orbit
  int width = 0, height = 0;       // 0 = the cameras' own size (orbit: 512 x 512)
};

std::vector<NamedCamera> scene_cameras(const Scene& scene, const SceneCameraOptions& options);

}  // namespace ii
