// `instainpaint scene-info`: what a scene reader found, as a table or JSON.
#include <nlohmann/json.hpp>
#include <fmt/core.h>

#include <cmath>
#include <iostream>

#include "capture/capture.h"
#include "cli/commands.h"
#include "data/scene.h"

namespace ii::cli {

namespace {

nlohmann::json view_json(const View& v) {
  const Intrinsics& K = v.camera.K;
  const Eigen::Vector3d c = v.camera.center();
  nlohmann::json j = {{"name", v.name},
                      {"image", v.image_path.string()},
                      {"width", K.width},
                      {"height", K.height},
                      {"fx", K.fx},
                      {"fy", K.fy},
                      {"cx", K.cx},
                      {"cy", K.cy},
                      {"fov_x_deg", K.fov_x() * 180.0 / M_PI},
                      {"fov_y_deg", K.fov_y() * 180.0 / M_PI},
                      {"center", {c.x(), c.y(), c.z()}}};
  j["mask"] = v.mask_path ? v.mask_path->string() : (v.mask_from_alpha ? "alpha" : "");
  if (v.distortion.any()) j["distortion"] = v.distortion.coeffs;
  return j;
}

void print_views(const char* title, const std::vector<View>& views) {
  fmt::print("{} ({}):\n", title, views.size());
  if (views.empty()) return;
  fmt::print("  {:<16} {:>11} {:>9} {:>9} {:>8} {:>8} {:>7} {:>7}  {:<6} {}\n", "name", "size",
             "fx", "fy", "cx", "cy", "fov_x", "fov_y", "mask", "centre");
  for (const View& v : views) {
    const Intrinsics& K = v.camera.K;
    const Eigen::Vector3d c = v.camera.center();
    const char* mask = v.mask_path ? "file" : (v.mask_from_alpha ? "alpha" : "-");
    fmt::print("  {:<16} {:>5}x{:<5} {:>9.2f} {:>9.2f} {:>8.2f} {:>8.2f} {:>6.1f}° {:>6.1f}°  {:<6} "
               "({:.3f}, {:.3f}, {:.3f}){}\n",
               v.name, K.width, K.height, K.fx, K.fy, K.cx, K.cy, K.fov_x() * 180 / M_PI,
               K.fov_y() * 180 / M_PI, mask, c.x(), c.y(), c.z(),
               v.distortion.any() ? "  distorted" : "");
  }
}

}  // namespace

void add_scene_info_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("scene-info", "Print what was read from a scene folder");
  auto scene_dir = std::make_shared<std::string>();
  auto options = std::make_shared<SceneOptions>();
  auto as_json = std::make_shared<bool>(false);
  auto compare = std::make_shared<std::string>();
  add_scene_options(cmd, *scene_dir, *options);
  cmd->add_flag("--json", *as_json, "Print JSON instead of a table");
  cmd->add_option("--compare", *compare,
                  "Another posing of the same views (any scene format): the cameras' rotation and position errors "
                  "after the best similarity, views matched by name (as capture --compare)")
      ->check(CLI::ExistingDirectory);
  cmd->footer(
      "Examples:\n"
      "  instainpaint scene-info --scene ../shared/data/statue\n"
      "  instainpaint scene-info --scene my_capture --compare the_datasets_poses --json");
  cmd->callback([=] {
    const Scene scene = load_scene(*scene_dir, *options);
    nlohmann::json compared;
    if (!compare->empty())
      compared = comparison_json(compare_poses(poses_of_scene(scene), poses_of_scene(*compare)), *compare);
    if (*as_json) {
      nlohmann::json j = {{"root", scene.root.string()}, {"format", scene.format}};
      j["views"] = nlohmann::json::array();
      for (const View& v : scene.views) j["views"].push_back(view_json(v));
      j["test_views"] = nlohmann::json::array();
      for (const View& v : scene.test_views) j["test_views"].push_back(view_json(v));
      if (scene.near) j["near"] = *scene.near;
      if (scene.far) j["far"] = *scene.far;
      j["warnings"] = scene.warnings;
      j["notes"] = scene.notes;
      if (!compared.is_null()) j["compared_with"] = compared;
      std::cout << j.dump(2) << "\n";
      return;
    }
    int masked = 0;
    for (const View& v : scene.views) masked += (v.mask_path || v.mask_from_alpha) ? 1 : 0;
    fmt::print("scene   {}\nformat  {}\nviews   {} ({} with object masks), test views {}\n",
               scene.root.string(), scene.format, scene.views.size(), masked, scene.test_views.size());
    if (scene.near && scene.far) fmt::print("depth   near {:.3f}, far {:.3f}\n", *scene.near, *scene.far);
    print_views("views", scene.views);
    print_views("test views (object-free ground truth)", scene.test_views);
    if (!compared.is_null()) fmt::print("{}\n", comparison_line(compared));
  });
}

}  // namespace ii::cli
