#pragma once
// Per-view preprocessing as the official evaluation does it (spec §5.3): resize to a target
// height (area filter for photos, nearest for masks), then centre-crop the width (and the
// height if needed) to a multiple of the patch size. Unlike the official code, the camera
// intrinsics follow the crop exactly (the official SPIn-NeRF path keeps the uncropped
// field of view; see docs/architecture.md).
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <tuple>

#include "camera/camera.h"
#include "data/scene.h"
#include "io/image.h"

namespace ii {

struct PreprocessOptions {
  int height = 512;  // working height in pixels
  int patch = 8;     // width and height are cropped to multiples of this
};

struct PreparedView {
  std::string name;
  Image rgb;                  // 3 channels, [0,1], working size
  std::optional<Image> mask;  // 1 channel {0,1}, working size
  Camera camera;              // exact for the working image
};

// How a source image becomes a working image, in inference and in training alike: resized to
// resized_width x resized_height, then the width x height window at (crop_x, crop_y) kept.
struct WorkingSize {
  int resized_width = 0, resized_height = 0;  // after resize
  int width = 0, height = 0;                  // after the crop
  int crop_x = 0, crop_y = 0;

  // The camera of the working image, exact: `source` (of the source image) resized and cropped.
  Camera working_camera(const Camera& source) const;
};
// Inference (the official evaluation): width int(W * height / H) (truncation, as the official
// code), then both centre-cropped down to multiples of the patch.
WorkingSize working_size(int source_width, int source_height, const PreprocessOptions& options);
// Training: the smallest resize (aspect kept) that covers width x height, and the window at
// fractions (crop_fx, crop_fy) in [0, 1) of the room left on each axis.
WorkingSize covering_size(int source_width, int source_height, int width, int height, double crop_fx, double crop_fy);

// Applies resize + crop to an image (area filter) or a mask (nearest).
Image to_working_size(const Image& image, const WorkingSize& size, bool is_mask = false);

PreparedView prepare_view(const View& view, const PreprocessOptions& options);

// A picture of a view (a 2D inpainter's reference) brought to the working size `target` of that
// view's photo_width x photo_height photo. It may come at the photo's size, at `target` itself, or
// at the photo's working size for its own height (the official evaluation's 904x512 crop of a
// 1008x567 photo: put back in its uncropped frame, edges repeated, then resized). nullopt when it
// is none of these.
std::optional<Image> view_picture_at_working_size(const Image& picture, int photo_width, int photo_height,
                                                  const WorkingSize& target, int patch);

// Views prepared once and kept, by name and working size: a server's edits read the same few
// views again and again (decoding and resizing them was most of an edit's CPU time).
// Thread-safe; get() returns a copy.
class PreparedViewCache {
 public:
  PreparedView get(const View& view, const PreprocessOptions& options);
  // A view made elsewhere (a render at the working size), kept as if prepared from `view`.
  void put(const View& view, const PreprocessOptions& options, PreparedView prepared);

 private:
  std::mutex mutex_;
  std::map<std::tuple<std::string, int, int>, PreparedView> views_;
};

}  // namespace ii
