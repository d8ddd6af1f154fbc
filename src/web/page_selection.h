#pragma once
// The page's click tools (`POST /api/select`): a click on the splats on screen selects the object
// under it among them (fill/region.h's region_from_clicks); a click on one of the scene's photos
// selects it among the scene's reconstruction and carves its outline by the photo, as
// `masks --click` does (edit/select.h). Each answer holds the selection's count and its mask in
// the view as the page draws it. What a click reads is kept between clicks: the splats of the
// last file (read once), the reconstruction's coloured points (made at the first click on a view).
// Safe to call from the server's threads side by side.
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <future>
#include <map>
#include <string>
#include <memory>
#include <mutex>
#include <thread>
#include <optional>
#include <vector>

#include <nlohmann/json.hpp>

#include "camera/camera.h"
#include "common/compute_thread.h"
#include "camera/click.h"
#include "data/scene.h"
#include "edit/select.h"
#include "gaussians/gaussians.h"
#include "io/ply.h"
#include "segment/segmenter.h"

namespace ii {

class PageSelection {
 public:
  PageSelection() = default;
  ~PageSelection();  // stops the encoding behind (after the view it is on)
  PageSelection(const PageSelection&) = delete;
  PageSelection& operator=(const PageSelection&) = delete;

  // The splats of `ply`, read once per file (read ahead when the page's click tool is chosen: a
  // click answers in well under a second on a million splats, and reading them again would
  // double that).
  std::shared_ptr<const SplatCloud> splats(const std::filesystem::path& ply);

  // With a segmenter (serve --segmenter), clicks are its points: on the object (`clicks`) and not
  // (`not_clicks`); each view's photo is encoded behind the page (encode_views_behind) or at its
  // first click, the page's render of the splats at its click, and kept, so a later click runs
  // only the decoder.
  void set_segmenter(std::shared_ptr<const Segmenter> segmenter);

  // With a segmenter: every view's photo encoded behind the page, one after another in the order
  // given, so that a click on any view runs the decoder alone (a click on a view being encoded
  // waits for it; none is encoded twice). Between views it waits while `busy()` (a job runs).
  // Each encoding runs on `compute`, the server's thread for LibTorch's work.
  void encode_views_behind(std::vector<View> views, std::function<bool()> busy, ComputeThread& compute);
  // How many views' photos are encoded so far.
  int views_encoded() const;

  // The objects under `clicks` among the splats of `ply` seen by `camera` (the page's view):
  // {selected, total, pixels, width, height, runs, how, ms: {read, select, draw}}. With a
  // segmenter, its outline of the splats' render taken as a stroke (ms: {read, render, encode,
  // decode, select}). Errors (a click outside the view, on nothing) name the click.
  nlohmann::json select_splats(const std::filesystem::path& ply, const Camera& camera, const std::vector<Click>& clicks,
                               const std::vector<Click>& not_clicks = {});

  // The scene's reconstruction (pose-normalised frame) that clicks on the scene's views select in;
  // replaces the one before.
  void set_reconstruction(const GaussianSet& reconstruction);

  // The objects under `clicks` on `view` (its camera in the reconstruction's frame) among the
  // reconstruction's opaque Gaussians, their outline carved by the view's photo:
  // {selected, total, pixels, width, height, runs, ms: {"select and carve"}}; nullopt while no
  // reconstruction has been made.
  // With a segmenter: its mask of the view's photo ({..., how: "segmenter", ms: {encode, decode}}),
  // with or without a reconstruction.
  // `box`: a box around the object on the photo, with or without clicks: with a segmenter its
  // prompt, without GrabCut in it (edit/box_select.h; {..., how: "GrabCut in the box", ms: {grabcut}}).
  // `scene_far`: the scene's far depth bound in the reconstruction's frame, when known
  // (SelectOptions::scene_far).
  std::optional<nlohmann::json> select_on_view(const View& view, const Camera& camera, const std::vector<Click>& clicks,
                                               const std::vector<Click>& not_clicks = {},
                                               std::optional<double> scene_far = std::nullopt,
                                               const std::optional<ViewBox>& box = std::nullopt);

 private:
  mutable std::mutex mutex_;
  std::filesystem::path splats_file_;
  std::shared_ptr<const SplatCloud> splats_;
  std::optional<GaussianSet> reconstruction_;
  std::shared_ptr<const ColouredPoints> points_;  // of the reconstruction, made at the first click
  std::shared_ptr<const Segmenter> segmenter_;
  // The last render of the splats the segmenter encoded, and what it was (the file and the camera).
  std::string encoded_key_;
  std::shared_ptr<const SegmenterImage> encoded_;
  // Each view's photo, encoded or being encoded ("view NAME").
  using Encoding = std::shared_future<std::shared_ptr<const SegmenterImage>>;
  std::map<std::string, Encoding> view_encodings_;
  std::thread encoder_;
  std::atomic<bool> stopping_{false};
  // The view's encoding: the one made or being made, else made here.
  std::shared_ptr<const SegmenterImage> view_encoding(const View& view, double& encode_ms);
  // The encoding of `key` (made by `make` when another was kept); `encode_ms` gets its time (0 when kept).
  std::shared_ptr<const SegmenterImage> encoding(const std::string& key, const std::function<Image()>& make,
                                                 double& encode_ms);
};

}  // namespace ii
