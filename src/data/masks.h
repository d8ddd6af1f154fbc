#pragma once
// Training masks as the paper draws them (spec §6.3): random rectangles (one mask for every
// input view), ellipses carried across views through the reference depth ("3D-consistent"),
// and a scene's own object masks, mixed 1:2:1. Masks are 1-channel Images with values 0/1
// (1 = hidden). Everything here is deterministic given the random engine passed in.
#include <array>
#include <filesystem>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "camera/camera.h"
#include "data/scene.h"
#include "io/image.h"

namespace ii {

using MaskRng = std::mt19937_64;

// Draws defined here rather than by std distributions, whose output differs between standard
// libraries: a seed gives the same masks and samples with any toolchain.
int random_int(MaskRng& rng, int lo, int hi_inclusive);  // uniform over [lo, hi]
double random_unit(MaskRng& rng);                        // uniform over [0, 1)
template <typename T>
void random_shuffle(std::vector<T>& values, MaskRng& rng) {  // Fisher-Yates
  for (int i = static_cast<int>(values.size()) - 1; i > 0; --i) std::swap(values[i], values[random_int(rng, 0, i)]);
}

enum class MaskMode { Instance, Random, Consistent3D };
std::string mask_mode_name(MaskMode mode);  // "instance", "random", "3dconsistent"

// Draws a mode with the given relative weights (instance, random, 3dconsistent). Weights must
// be finite and non-negative with a positive sum.
MaskMode draw_mask_mode(const std::array<double, 3>& weights, MaskRng& rng);

// Dilation with a square kernel (OpenCV's rectangular structuring element), `iterations`
// times. Values stay 0/1.
Image dilate_mask(const Image& mask, int iterations = 1, int kernel_size = 5);

// Union of masks of the same size.
Image mask_union(const Image& a, const Image& b);

struct Rectangle {
  int x = 0, y = 0, width = 0, height = 0;  // top-left corner and size in pixels
};
// `count` axis-aligned rectangles: width in [W/6, W/4), height in [H/6, H/4) (integer
// division; at least one pixel), top-left uniform so the rectangle lies inside the image.
std::vector<Rectangle> random_rectangles(int width, int height, int count, MaskRng& rng);
Image rectangles_mask(int width, int height, const std::vector<Rectangle>& rectangles);

struct Ellipse {
  double center_x = 0, center_y = 0;  // column, row of the centre pixel
  double major = 1, minor = 1;        // semi-axes in pixels
  double angle = 0;                   // radians, in [0, pi)
};
// `count` ellipses: centre anywhere in the image; semi-axes from (H/8, W/6) for up to two
// ellipses, (H/12, W/8) for more: major in [a0+1, a1), minor in [a0, major).
std::vector<Ellipse> random_ellipses(int width, int height, int count, MaskRng& rng);
// Pixel (x = column, y = row) is inside when (x_r/major)^2 + (y_r/minor)^2 <= 1 with
// x_r = dx cos(a) - dy sin(a), y_r = dx sin(a) + dy cos(a), d relative to the centre.
Image ellipses_mask(int width, int height, const std::vector<Ellipse>& ellipses);

// Carries a reference-view mask into other views: every masked reference pixel is placed in
// 3D at its z-depth (`reference_depth`, 1 channel at the reference camera's size, same units
// as the camera translations; non-finite or non-positive values are skipped), projected with
// each camera's exact intrinsics, splatted into the pixel it falls in, and the splat mask is
// dilated `dilations` times with a 5x5 kernel (spec: twice). Points behind a camera are
// dropped. Occlusion is ignored, as in the official code. One mask per camera, each at
// that camera's size.
std::vector<Image> carry_mask_through_depth(const Image& reference_mask, const Image& reference_depth,
                                            const Camera& reference_camera,
                                            const std::vector<Camera>& cameras, int dilations = 2);

// A depth map of a view from a file: a .npy float array of shape (H, W) or (H, W, 1) holding
// z-depth in the scene's units, or a 16-bit PNG whose levels times `png_scale` are (level 0 =
// unknown). Errors name the file: another size than width x height, another format.
Image read_depth_map(const std::filesystem::path& file, int width, int height, double png_scale = 0.001);

// Per-view depth of a scene, when it has one: `<scene root>/<folder>/<view stem>.npy`, a float
// array of shape (H, W) or (H, W, 1) at the view image's size holding z-depth in the scene's
// units (0, negative or non-finite = unknown). nullopt when the file does not exist. Synthetic
// scenes also have `depth_clean/`: the depth of the object-free image in `clean/`.
std::optional<Image> load_view_depth(const Scene& scene, const View& view, const std::string& folder = "depth");

// The depth of a fronto-parallel plane that stands in for the scene when it has no depth
// maps, seen from `reference` (a camera of the scene, scene units). Sources, first that
// applies: the median z-depth of the scene's COLMAP points in front of the reference
// (LLFF and COLMAP scenes with sparse/0/points3D.*; read once per scene, 2000 kept);
// sqrt(near * far) of the scene's depth bounds (LLFF); the depth of the point nearest to the
// optical axes of `cameras` (captures that look at a subject); twice the spread of the
// camera centres. Always positive.
double typical_scene_depth(const Scene& scene, const Camera& reference, const std::vector<Camera>& cameras);

// A view's z-depth at `points` (scene frame; the nearest where several meet a pixel), 0 elsewhere.
Image points_depth(const std::vector<Eigen::Vector3d>& points, const Camera& camera);

// Which of a scene's geometries gave its points (scene_geometry_points), and in words.
enum class PointsSource { None, DepthMaps, Colmap, Photos };
struct PointsOrigin {
  PointsSource kind = PointsSource::None;
  std::string description = "none";  // e.g. "4 views' depth maps (64 points)"; with None, why
};

// The 3D points a scene carries, in its own frame: points of its input views' depth maps
// (synthetic scenes' depth/, every `stride`-th pixel of each), else, with `colmap`, its COLMAP
// model's (at most 2000, read once per scene), else, with `triangulate_from` (indices into
// scene.views), points triangulated from those views' photos and their neighbours
// (data/photo_points.h; once per scene and views); empty when it has none. `origin` (optional)
// says which.
std::vector<Eigen::Vector3d> scene_geometry_points(const Scene& scene, bool colmap, PointsOrigin* origin = nullptr,
                                                   int stride = 8, const std::vector<int>& triangulate_from = {});

}  // namespace ii
