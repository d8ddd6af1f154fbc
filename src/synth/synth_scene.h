#pragma once
// Procedural scenes with exact ground truth for object removal: a little room made of 3D
// Gaussians (textured floor, walls, ceiling, wall decorations, furniture-like primitives)
// and, near its centre, an inserted object (a procedural composition of primitives, or one
// of the real captured splats). Cameras follow a smooth random path looking at the object.
// Because the object is a separate Gaussian set, rendering the background alone gives the
// exact object-free image of any view (synth_views.h). Everything is a function of the
// options and the seed (own RNG, synth/random.h): same seed, same bytes.
//
// World frame: y up, the floor at y = 0, the object standing near the origin. Cameras are
// OpenGL camera-to-world (camera/camera.h), square pixels, centred principal point.
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "render/rasterizer.h"
#include "camera/trajectory.h"

namespace ii::synth {

enum class ObjectSource { procedural, splat, mixed };
// "procedural" | "splat" | "mixed"; throws Error naming `what` otherwise.
ObjectSource parse_object_source(const std::string& text, const std::string& what = "--object");
std::string to_string(ObjectSource source);

struct SynthOptions {
  int views = 24;      // training views: the object is in them
  int test_views = 8;  // object-free test views (SPIn-NeRF style), between the training views
  int width = 256;
  int height = 256;
  // procedural: composed primitives; splat: a real captured splat from splat_dir (error if
  // none); mixed: a splat in about a third of the scenes when splat_dir has any, else
  // procedural (the choice is drawn first, so procedural scenes do not depend on the folder).
  ObjectSource object = ObjectSource::mixed;
  std::filesystem::path splat_dir;  // *.ply objects (3DGS or compressed PLY); may be absent
  // Gaussian density: 1 gives Gaussians about 2.5 pixels apart where the cameras see them
  // closest; higher is sharper and slower.
  double detail = 1.0;
  // Objects to remove at once (1-3). Several are procedural, stand apart on the floor around
  // the centre, and form one object set (the mask is their union).
  int objects = 1;
  // 0: cameras on a random arc or forward path (what the model card's rooms use). 1 or 2: cameras
  // all around the object, evenly over 360 degrees of azimuth on as many rings (at two heights,
  // alternating), test views between them on the same rings: a capture seen from every side.
  int rings = 0;
};

struct SynthScene {
  uint64_t seed = 0;
  GaussianSet background;               // everything except the object, RGB colours
  GaussianSet object;                   // the inserted object, RGB colours
  std::vector<NamedCamera> views;       // training views, in path order ("view_000", ...)
  std::vector<NamedCamera> test_views;  // test views, in path order ("test_000", ...)
  int reference = 0;                    // index into `views` of the reference view
  std::vector<int> context;             // reference first, then 3 views spanning the path
  Eigen::Vector3d object_centre = Eigen::Vector3d::Zero();
  double object_radius = 0;                                  // bounding sphere around object_centre
  std::array<float, 3> render_background{0.5f, 0.5f, 0.5f};  // shows only through gaps
  nlohmann::json description;                                // room, furniture, object, camera path
};

// The captured splat objects of a folder (*.ply), sorted by name; empty when the folder is
// missing.
std::vector<std::filesystem::path> list_splat_objects(const std::filesystem::path& dir);

// The seed of scene `index` in a run started with `run_seed`.
uint64_t scene_seed(uint64_t run_seed, int index);

// Builds one scene. Throws Error for options out of range (views < 4, sizes < 16, ...) and
// when a splat object is required but splat_dir holds none.
SynthScene generate_scene(const SynthOptions& options, uint64_t seed);

// The background and the object in one set (background first), as captured.
GaussianSet combined_gaussians(const SynthScene& scene);

}  // namespace ii::synth
