#pragma once
// The page's click tools (`POST /api/select`): a click on the splats on screen selects the object
// under it among them (fill/region.h's region_from_clicks); a click on one of the scene's photos
// selects it among the scene's reconstruction and carves its outline by the photo, as
// `masks --click` does (edit/select.h). Each answer holds the selection's count and its mask in
// the view as the page draws it. What a click reads is kept between clicks: the splats of the
// last file (read once), the reconstruction's coloured points (made at the first click on a view).
// Safe to call from the server's threads side by side.
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include <nlohmann/json.hpp>

#include "camera/camera.h"
#include "camera/click.h"
#include "data/scene.h"
#include "edit/select.h"
#include "gaussians/gaussians.h"
#include "io/ply.h"

namespace ii {

class PageSelection {
 public:
  // The splats of `ply`, read once per file (read ahead when the page's click tool is chosen: a
  // click answers in well under a second on a million splats, and reading them again would
  // double that).
  std::shared_ptr<const SplatCloud> splats(const std::filesystem::path& ply);

  // The objects under `clicks` among the splats of `ply` seen by `camera` (the page's view):
  // {selected, total, pixels, width, height, runs, ms: {read, select, draw}}. Errors (a click
  // outside the view, on nothing) name the click.
  nlohmann::json select_splats(const std::filesystem::path& ply, const Camera& camera, const std::vector<Click>& clicks);

  // The scene's reconstruction (pose-normalised frame) that clicks on the scene's views select in;
  // replaces the one before.
  void set_reconstruction(const GaussianSet& reconstruction);

  // The objects under `clicks` on `view` (its camera in the reconstruction's frame) among the
  // reconstruction's opaque Gaussians, their outline carved by the view's photo:
  // {selected, total, pixels, width, height, runs, ms: {select, carve}}; nullopt while no
  // reconstruction has been made.
  std::optional<nlohmann::json> select_on_view(const View& view, const Camera& camera, const std::vector<Click>& clicks);

 private:
  std::mutex mutex_;
  std::filesystem::path splats_file_;
  std::shared_ptr<const SplatCloud> splats_;
  std::optional<GaussianSet> reconstruction_;
  std::shared_ptr<const ColouredPoints> points_;  // of the reconstruction, made at the first click
};

}  // namespace ii
