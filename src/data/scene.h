#pragma once
// The common scene representation every reader ends in: posed views with optional object
// masks, and optional object-free test views. Nothing after a reader asks which format a
// scene came from. Images are loaded on demand (a scene may hold hundreds of views).
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "camera/camera.h"
#include "io/image.h"

namespace ii {

struct View {
  std::string name;                  // file stem, unique within the scene
  std::filesystem::path image_path;
  std::optional<std::filesystem::path> mask_path;  // object mask file (1 = object)
  bool mask_from_alpha = false;      // mask = alpha channel of the image, alpha 0 = object
  Camera camera;                     // intrinsics for the image file's own size
  Distortion distortion;             // undistorted on load when non-zero
  bool shows_object = false;         // a test view held out from the inputs (SceneOptions::hold_out_every)
};

struct Scene {
  std::filesystem::path root;
  std::string format;             // "llff", "nerfstudio", "colmap"
  std::vector<View> views;        // input candidates (with the object)
  // Ground-truth views never given to the network: object-free (SPIn-NeRF), or input views
  // held out (`shows_object`; compared outside their masks). May be empty.
  std::vector<View> test_views;
  std::optional<double> near, far;  // depth bounds when the format stores them
  std::vector<std::string> warnings;  // non-fatal oddities found while reading
  std::vector<std::string> notes;     // how the reader interpreted an ambiguous layout

  bool has_masks() const;
  const View* find(const std::string& name) const;  // in views, then test_views
};

struct SceneOptions {
  std::string format = "auto";     // auto | llff | nerfstudio | colmap
  std::string image_folder;        // e.g. "images_4"; empty = the format's default
  std::optional<std::filesystem::path> mask_dir;  // masks matched by stem or "<file>.png"
  bool alpha_masks = false;        // take masks from the images' alpha channel
  // > 0: input views 0, N, 2N, ... (3DGS's LLFF hold-out) become test views that show the
  // object, for scenes without object-free test views (they need masks).
  int hold_out_every = 0;
  // With hold_out_every: a reconstruction (nothing removed), so the held-out views need no
  // masks and are compared whole.
  bool hold_out_whole = false;
};

// Reads a scene folder in any supported format (detected from its files when
// options.format is "auto").
Scene load_scene(const std::filesystem::path& dir, const SceneOptions& options = {});

// The normalisation the official evaluation uses: over all cameras of the scene, input and
// test views alike (spec §5.1, normalize_mode "all").
PoseNormalization scene_normalization(const Scene& scene);

// The points of the scene's COLMAP model (sparse/0, sparse or the root, when points3D and
// cameras files are there) in the world frame of its cameras; empty for other formats
// (nerfstudio files usually re-orient the world) and scenes without points.
std::vector<Eigen::Vector3d> load_scene_points(const Scene& scene);

// Decodes a view's image as RGB in [0,1] (alpha composited on white), undistorted when the
// view has distortion.
Image load_view_image(const View& view);
// The view's binary object mask at the image's size, or nullopt when it has none. A mask
// file a few pixels off the image size is resized nearest-neighbour with a warning.
std::optional<Image> load_view_mask(const View& view);
// Whether a mask a few pixels off an image's size (as annotation tools export them: SPIn-NeRF's
// 1008x576 masks of 1008x567 photos) may be resized to it: within 4 pixels or 2 % of its side.
bool mask_near_size(const Image& mask, int width, int height);
// `mask` (read from `source`) at its image's size: as it is, resized nearest-neighbour with a
// warning when near it, else an Error naming `source` and both sizes.
Image mask_at_image_size(Image mask, int width, int height, const std::filesystem::path& source);

// Attaches masks from a folder: for each view, "<stem>.*" or "<image file name>.png".
// Views without a matching file keep no mask. Returns the number matched.
int attach_mask_folder(Scene& scene, const std::filesystem::path& mask_dir);

}  // namespace ii
