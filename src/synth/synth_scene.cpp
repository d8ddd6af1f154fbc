// generate_scene(): the plan (object size, support, camera path, room) drawn first, then
// cameras, then the Gaussians, as dense as the cameras need them.
#include "synth/synth_scene.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "common/error.h"
#include "synth/random.h"
#include "synth/scene_parts.h"

namespace ii::synth {

namespace {

using Eigen::Vector3d;

constexpr double kDeg = M_PI / 180.0;

// Independent random streams per part of a scene: changing how one part draws does not
// change the others.
enum Stream : uint64_t { kPlanStream = 1, kCameraStream = 2, kRoomStream = 3, kObjectStream = 4, kLayoutStream = 5 };

// Where one object stands and how big it is.
struct ObjectSlot {
  Eigen::Vector3d base;
  double height, footprint;
};

struct CameraPath {
  bool arc = true;
  Vector3d target;
  double object_radius = 0.3;
  double distance = 2;
  double theta0 = 0, span = 1;  // arc: centre angle and angular extent (radians)
  double elevation = 0.3, elevation_wobble = 0.05;
  double sweep = 0.5, bob = 0.1;  // forward: horizontal and vertical extent (metres)
  double f1 = 1, f2 = 1, f3 = 1, p1 = 0, p2 = 0, p3 = 0;
  double roll = 0.02;
  double min_height = 0.3, max_height = 2.5;
  Intrinsics K;
  int rings = 0;                         // > 0: cameras all around (ring_at), not along the path
  double ring_elevations[2] = {0.3, 0.6};  // radians, the lower ring first

  // The camera at path parameter t in [0, 1]; `distance_scale` and `lift` move it off the
  // path (test views).
  Camera at(double t, double distance_scale = 1.0, double lift = 0.0) const {
    const double w1 = std::sin(2 * M_PI * f1 * t + p1), w2 = std::sin(2 * M_PI * f2 * t + p2),
                 w3 = std::sin(2 * M_PI * f3 * t + p3);
    Vector3d eye;
    if (arc) {
      const double theta = theta0 + span * (t - 0.5) + 0.04 * w3;
      const double r = distance * distance_scale * (1.0 + 0.07 * w1);
      const double e = elevation + elevation_wobble * w2;
      eye = target + Vector3d(r * std::cos(theta) * std::cos(e), r * std::sin(e), r * std::sin(theta) * std::cos(e));
    } else {
      const Vector3d back(std::cos(theta0) * std::cos(elevation), std::sin(elevation),
                          std::sin(theta0) * std::cos(elevation));
      const Vector3d right = Vector3d::UnitY().cross(back).normalized();
      const Vector3d up = back.cross(right);
      eye = target + back * (distance * distance_scale * (1.0 + 0.05 * w1)) + right * (sweep * (2 * t - 1 + 0.1 * w3)) +
            up * (bob * w2);
    }
    eye.y() = std::clamp(eye.y() + lift, min_height, max_height);
    const Vector3d look = target + object_radius * 0.15 * Vector3d(w2, 0.5 * w3, w1);
    Camera c;
    c.K = K;
    c.c2w = look_at(eye, look, Vector3d::UnitY());
    const double r = roll * w3;
    c.c2w.block<3, 3>(0, 0) = c.c2w.block<3, 3>(0, 0) * Eigen::AngleAxisd(r, Vector3d::UnitZ()).toRotationMatrix();
    return c;
  }
};

// The camera at `fraction` of the way around ring `ring` (azimuth theta0 + 2 pi fraction), looking
// at the object; `distance_scale` and `lift` move it off the ring (test views).
Camera ring_at(const CameraPath& path, double fraction, int ring, double distance_scale = 1.0, double lift = 0.0) {
  const double theta = path.theta0 + 2 * M_PI * fraction, e = path.ring_elevations[ring];
  const double r = path.distance * distance_scale;
  Vector3d eye =
      path.target + Vector3d(r * std::cos(theta) * std::cos(e), r * std::sin(e), r * std::sin(theta) * std::cos(e));
  eye.y() = std::clamp(eye.y() + lift, path.min_height, path.max_height);
  Camera c;
  c.K = path.K;
  c.c2w = look_at(eye, path.target, Vector3d::UnitY());
  return c;
}

// Height-normalised horizontal radius of a splat object (99th percentile of the means).
double splat_footprint(const GaussianSet& g) {
  const torch::Tensor r = torch::hypot(g.means.select(1, 0), g.means.select(1, 2)).contiguous();
  std::vector<float> v(r.data_ptr<float>(), r.data_ptr<float>() + r.numel());
  const size_t k = static_cast<size_t>(0.99 * (v.size() - 1));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return std::max(0.05f, v[k]);
}

void check_options(const SynthOptions& o) {
  if (o.views < 4) fail("synth: need at least 4 views (got {})", o.views);
  if (o.views > 10000) fail("synth: at most 10000 views (got {})", o.views);
  if (o.test_views < 0 || o.test_views > 10000) fail("synth: test views must be in [0, 10000] (got {})", o.test_views);
  if (o.width < 16 || o.height < 16 || o.width > 8192 || o.height > 8192)
    fail("synth: image size must be between 16 and 8192 pixels a side (got {}x{})", o.width, o.height);
  if (!(o.detail > 0.05 && o.detail <= 8)) fail("synth: detail must be in (0.05, 8] (got {})", o.detail);
  if (o.objects < 1 || o.objects > 3) fail("synth: 1 to 3 objects (got {})", o.objects);
  if (o.rings < 0 || o.rings > 2) fail("synth: rings must be 0 (a path), 1 or 2 (got {})", o.rings);
  if (o.objects > 1 && o.object == ObjectSource::splat)
    fail("synth: several objects are procedural: use --object procedural or mixed");
}

}  // namespace

ObjectSource parse_object_source(const std::string& text, const std::string& what) {
  if (text == "procedural") return ObjectSource::procedural;
  if (text == "splat") return ObjectSource::splat;
  if (text == "mixed") return ObjectSource::mixed;
  fail("{}: unknown object source '{}' (expected procedural, splat or mixed)", what, text);
}

std::string to_string(ObjectSource source) {
  switch (source) {
    case ObjectSource::procedural:
      return "procedural";
    case ObjectSource::splat:
      return "splat";
    default:
      return "mixed";
  }
}

uint64_t scene_seed(uint64_t run_seed, int index) { return mix_seed(run_seed, static_cast<uint64_t>(index)); }

DetailMap::DetailMap(std::vector<Camera> cameras, double pixels_per_gaussian, double min_spacing, double max_spacing)
    : cameras_(std::move(cameras)), pixels_(pixels_per_gaussian), min_(min_spacing), max_(max_spacing) {
  for (const Camera& c : cameras_) w2c_.push_back(c.w2c_opencv());
}

double DetailMap::spacing(const std::vector<Eigen::Vector3d>& samples) const {
  // A sample stands for its neighbourhood: half the distance to the farthest other sample.
  double extent = 0;
  for (const Vector3d& s : samples) extent = std::max(extent, (s - samples.front()).norm());
  return spacing_sphere_points(samples, extent / 4);
}

double DetailMap::spacing_sphere(const Eigen::Vector3d& centre, double radius) const {
  return spacing_sphere_points({centre}, radius);
}

double DetailMap::spacing_sphere_points(const std::vector<Eigen::Vector3d>& points, double radius) const {
  double best = max_;
  for (size_t k = 0; k < cameras_.size(); ++k) {
    const Intrinsics& K = cameras_[k].K;
    // Inward unit normals of the four side planes of the view frustum (OpenCV camera axes).
    const std::array<Vector3d, 4> sides = {
        Vector3d(K.fx, 0, K.cx).normalized(), Vector3d(-K.fx, 0, K.width - K.cx).normalized(),
        Vector3d(0, K.fy, K.cy).normalized(), Vector3d(0, -K.fy, K.height - K.cy).normalized()};
    for (const Vector3d& p : points) {
      const Vector3d x = (w2c_[k] * p.homogeneous()).head<3>();
      if (x.z() + radius < 0.05) continue;  // behind the camera
      bool inside = true;
      for (const Vector3d& n : sides) inside = inside && n.dot(x) >= -radius;
      if (!inside) continue;
      // The nearest the sphere comes to the camera along its axis.
      const double z = std::max(0.05, x.z() - radius);
      best = std::min(best, z / K.fx * pixels_);
    }
  }
  return std::clamp(best, min_, max_);
}

namespace {

// The object: a captured splat or a procedural one, its height and footprint (of the largest of
// several), and the radius that bounds it.
struct ObjectPlan {
  const GaussianSet* splat = nullptr;
  std::filesystem::path splat_file;
  double height = 0, footprint = 0, bounding = 0;
};

ObjectPlan plan_object(const SynthOptions& options, SynthRng& plan_rng) {
  ObjectPlan o;
  const bool want_splat =
      options.object == ObjectSource::splat || (options.object == ObjectSource::mixed && plan_rng.chance(1.0 / 3.0));
  const auto splat_files = list_splat_objects(options.splat_dir);
  if (want_splat && !splat_files.empty() && options.objects == 1) {
    o.splat_file = plan_rng.pick(splat_files);
    o.splat = &normalized_splat_object(o.splat_file);
  } else if (options.object == ObjectSource::splat) {
    fail("synth: --object splat needs captured splats (*.ply) in '{}'", options.splat_dir.string());
  }
  if (o.splat) {
    o.height = plan_rng.uniform(0.45, 0.9);
    o.footprint = splat_footprint(*o.splat) * o.height;
  } else {
    o.height = plan_rng.uniform(0.22, 0.6);
    o.footprint = o.height * plan_rng.uniform(0.3, 0.65);
  }
  o.bounding = std::hypot(o.height / 2, o.footprint);
  return o;
}

// Where the object stands (on the floor or on a support) or, with several, where each stands:
// on the floor, evenly around the centre and far enough apart that their masks are separate
// regions in most views. Widens object.bounding to all of them.
std::vector<ObjectSlot> place_objects(const SynthOptions& options, uint64_t seed, SynthRng& plan_rng,
                                      ObjectPlan& object, RoomPlan& plan) {
  plan.object_footprint = object.footprint;
  plan.support = plan_rng.weighted({0.5, 0.17, 0.17, 0.16});
  double support_top = 0;
  if (plan.support != 0) {
    support_top = plan.support == 3 ? plan_rng.uniform(0.3, 0.8) : plan_rng.uniform(0.45, 0.75);
    plan.support_size =
        std::min(object.footprint + plan_rng.uniform(0.05, 0.25), std::max(0.45, object.footprint + 0.05));
  }
  plan.object_base = Vector3d(0, support_top, 0);
  std::vector<ObjectSlot> slots = {{plan.object_base, object.height, object.footprint}};
  if (options.objects == 1) return slots;
  SynthRng layout_rng(mix_seed(seed, kLayoutStream));
  plan.support = 0;
  plan.support_size = 0;
  plan.object_base = Vector3d::Zero();
  const double spread = 1.6 * object.footprint + 0.15, turn = layout_rng.uniform(0, 2 * M_PI);
  slots.clear();
  for (int i = 0; i < options.objects; ++i) {
    const double angle = turn + 2 * M_PI * i / options.objects;
    slots.push_back({Vector3d(spread * std::cos(angle), 0, spread * std::sin(angle)),
                     object.height * layout_rng.uniform(0.7, 1.0), object.footprint * layout_rng.uniform(0.7, 1.0)});
  }
  object.bounding = spread + object.bounding;
  plan.object_footprint = spread + object.footprint;
  return slots;
}

// The cameras' path around (arc) or in front of (forward) the object, and their intrinsics.
CameraPath draw_camera_path(const SynthOptions& options, const RoomPlan& plan, const ObjectPlan& object,
                            SynthRng& camera_rng, double& fov_y) {
  CameraPath path;
  path.arc = camera_rng.chance(0.65);
  path.target = plan.object_base + Vector3d(0, object.height / 2, 0);
  path.object_radius = object.bounding;
  const double coverage = camera_rng.uniform(0.17, 0.3);  // bounding radius / camera distance
  path.distance = std::clamp(object.bounding / coverage, std::max(object.bounding + 0.4, plan.support_size + 0.5), 4.0);
  fov_y = camera_rng.uniform(45, 62) * kDeg;
  path.K.width = options.width;
  path.K.height = options.height;
  path.K.fy = options.height / (2.0 * std::tan(fov_y / 2));
  path.K.fx = path.K.fy;  // square pixels: the LLFF layout stores one focal length
  path.K.cx = options.width / 2.0;
  path.K.cy = options.height / 2.0;
  path.theta0 = camera_rng.uniform(0, 2 * M_PI);
  path.span = camera_rng.uniform(50, 160) * kDeg;
  path.elevation = camera_rng.uniform(10, 35) * kDeg;
  path.elevation_wobble = camera_rng.uniform(0, 8) * kDeg;
  path.sweep = path.distance * camera_rng.uniform(0.25, 0.45);
  path.bob = path.distance * camera_rng.uniform(0.05, 0.15);
  path.f1 = camera_rng.uniform(0.5, 1.5);
  path.f2 = camera_rng.uniform(0.5, 2.0);
  path.f3 = camera_rng.uniform(0.5, 1.5);
  path.p1 = camera_rng.uniform(0, 2 * M_PI);
  path.p2 = camera_rng.uniform(0, 2 * M_PI);
  path.p3 = camera_rng.uniform(0, 2 * M_PI);
  path.roll = camera_rng.uniform(0, 2.5) * kDeg;
  if (options.rings > 0) {  // after every draw above: the arc scenes of a seed stay as they were
    path.arc = true;
    path.rings = options.rings;
    path.span = 2 * M_PI;
    path.ring_elevations[0] = options.rings == 1 ? path.elevation : 15 * kDeg;
    path.ring_elevations[1] = 40 * kDeg;
  }
  return path;
}

// The room's walls: the cameras' ring stays free for the object alone. Bounds the path's heights.
void plan_room(RoomPlan& plan, CameraPath& path, SynthRng& plan_rng) {
  plan.keep_out = path.distance * 1.2 + 0.3;
  const double room_height = plan_rng.uniform(2.5, 3.2);
  plan.room_min =
      Vector3d(-(plan.keep_out + plan_rng.uniform(0.7, 2.0)), 0, -(plan.keep_out + plan_rng.uniform(0.7, 2.0)));
  plan.room_max =
      Vector3d(plan.keep_out + plan_rng.uniform(0.7, 2.0), room_height, plan.keep_out + plan_rng.uniform(0.7, 2.0));
  path.min_height = 0.25;
  path.max_height = room_height - 0.3;
}

// Cameras all around: view k at k / v of the way around ring k % rings, test view k halfway
// between two views on ring k % rings. The reference is the first view; the context the views a
// quarter, a half and three quarters of the way around from it (the object seen from four sides).
std::vector<Camera> place_ring_cameras(const SynthOptions& options, const CameraPath& path, SynthRng& camera_rng,
                                       SynthScene& scene, int digits) {
  std::vector<Camera> all;
  const int v = options.views, t = options.test_views;
  for (int k = 0; k < v; ++k) {
    scene.views.push_back({fmt::format("view_{:0{}d}", k, digits), ring_at(path, double(k) / v, k % path.rings)});
    all.push_back(scene.views.back().camera);
  }
  for (int k = 0; k < t; ++k) {
    const double scale = 1.0 + camera_rng.uniform(-0.08, 0.08);
    const double lift = camera_rng.uniform(-0.05, 0.05) * path.distance;
    scene.test_views.push_back(
        {fmt::format("test_{:0{}d}", k, digits), ring_at(path, (k + 0.5) / t, k % path.rings, scale, lift)});
    all.push_back(scene.test_views.back().camera);
  }
  scene.reference = 0;
  scene.context = {0, v / 4, v / 2, 3 * v / 4};
  return all;
}

// The input and test views along the path, and the reference and context as the official
// training recipe picks them from a clip of 15: inputs at 0, 4, 9, 14 with 4 or 9 as the
// reference, moved to the front. Returns every camera.
std::vector<Camera> place_cameras(const SynthOptions& options, const CameraPath& path, SynthRng& camera_rng,
                                  SynthScene& scene) {
  std::vector<Camera> all;
  const int v = options.views, t = options.test_views;
  // Zero-padded so that name order is path order (and test_* sorts before view_*).
  const int digits = std::max<int>(3, static_cast<int>(std::to_string(std::max(v, t) - 1).size()));
  if (path.rings > 0) return place_ring_cameras(options, path, camera_rng, scene, digits);
  for (int k = 0; k < v; ++k) {
    double s = double(k) / (v - 1);
    if (k > 0 && k < v - 1) s += camera_rng.uniform(-0.3, 0.3) / (v - 1);
    scene.views.push_back({fmt::format("view_{:0{}d}", k, digits), path.at(s)});
    all.push_back(scene.views.back().camera);
  }
  for (int k = 0; k < t; ++k) {
    const double s = (k + 0.5) / t;
    const double scale = 1.0 + camera_rng.uniform(-0.08, 0.08);
    const double lift = camera_rng.uniform(-0.08, 0.08) * path.distance;
    scene.test_views.push_back({fmt::format("test_{:0{}d}", k, digits), path.at(s, scale, lift)});
    all.push_back(scene.test_views.back().camera);
  }
  const auto at_fraction = [&](double f) { return static_cast<int>(std::lround(f * (v - 1))); };
  const int a = at_fraction(4.0 / 14), b = at_fraction(9.0 / 14);
  scene.reference = camera_rng.chance(0.5) ? a : b;
  scene.context = {scene.reference, 0, scene.reference == a ? b : a, v - 1};
  return all;
}

// A key light, an ambient share, a lamp under the ceiling and a tint.
Lighting draw_lighting(const RoomPlan& plan, SynthRng& plan_rng) {
  Lighting lighting;
  lighting.room_min = plan.room_min;
  lighting.room_max = plan.room_max;
  const double key_azimuth = plan_rng.uniform(0, 2 * M_PI), key_elevation = plan_rng.uniform(30, 70) * kDeg;
  lighting.key_direction = Vector3d(std::cos(key_azimuth) * std::cos(key_elevation), std::sin(key_elevation),
                                    std::sin(key_azimuth) * std::cos(key_elevation));
  lighting.ambient = plan_rng.uniform(0.5, 0.7);
  lighting.key = 1.0 - lighting.ambient + plan_rng.uniform(-0.1, 0.1);
  lighting.lamp = Vector3d(plan_rng.uniform(plan.room_min.x(), plan.room_max.x()) * 0.5, plan.room_max.y() - 0.02,
                           plan_rng.uniform(plan.room_min.z(), plan.room_max.z()) * 0.5);
  lighting.lamp_gain = plan_rng.uniform(0.15, 0.35);
  lighting.tint = hsv(plan_rng.chance(0.6) ? 0.1 : 0.6, plan_rng.uniform(0, 0.12), 1.0);
  return lighting;
}

// The object's Gaussians (the splat placed, or each slot's procedural object) and what
// scene.json says of it; sets the scene's object centre and radius.
nlohmann::json build_object(const ObjectPlan& object, const RoomPlan& plan, const std::vector<ObjectSlot>& slots,
                            const DetailMap& detail, const Lighting& lighting, uint64_t seed, SynthScene& scene) {
  SynthRng object_rng(mix_seed(seed, kObjectStream));
  nlohmann::json object_json;
  if (object.splat) {
    scene.object = place_splat_object(*object.splat, plan.object_base, object.height, object_rng.uniform(0, 2 * M_PI));
    object_json = {{"kind", "splat"},
                   {"file", object.splat_file.filename().string()},
                   {"height", object.height},
                   {"footprint", object.footprint}};
  } else {
    GaussianBuilder builder;
    for (const ObjectSlot& slot : slots) {
      nlohmann::json part;
      build_procedural_object(slot.base, slot.height, slot.footprint, detail, lighting, object_rng, builder, part);
      if (slots.size() == 1) object_json = part;
      else object_json["parts"].push_back(part);
    }
    scene.object = builder.build();
  }
  const torch::Tensor lo = std::get<0>(scene.object.means.min(0)), hi = std::get<0>(scene.object.means.max(0));
  const torch::Tensor centre = (lo + hi) / 2;
  scene.object_centre = Vector3d(centre[0].item<double>(), centre[1].item<double>(), centre[2].item<double>());
  const double reach = (scene.object.means - centre).norm(2, 1).max().item<double>();
  scene.object_radius = reach + 3.0 * scene.object.scales.max().item<double>();
  object_json["gaussians"] = scene.object.size();
  return object_json;
}

}  // namespace

// The plan's draws come from one stream in a fixed order (object, support, room, lighting), the
// cameras' from another: the steps below keep that order.
SynthScene generate_scene(const SynthOptions& options, uint64_t seed) {
  check_options(options);
  SynthScene scene;
  scene.seed = seed;
  SynthRng plan_rng(mix_seed(seed, kPlanStream));
  ObjectPlan object = plan_object(options, plan_rng);
  RoomPlan plan;
  const std::vector<ObjectSlot> slots = place_objects(options, seed, plan_rng, object, plan);

  SynthRng camera_rng(mix_seed(seed, kCameraStream));
  double fov_y = 0;
  CameraPath path = draw_camera_path(options, plan, object, camera_rng, fov_y);
  plan_room(plan, path, plan_rng);
  const std::vector<Camera> all = place_cameras(options, path, camera_rng, scene);

  const DetailMap detail(all, 2.5 / options.detail, 0.003, 0.3);
  Lighting lighting = draw_lighting(plan, plan_rng);  // build_room adds the contact shadows
  nlohmann::json description;
  GaussianBuilder background;
  SynthRng room_rng(mix_seed(seed, kRoomStream));
  build_room(plan, detail, lighting, room_rng, background, description);
  scene.background = background.build();
  description["object"] = build_object(object, plan, slots, detail, lighting, seed, scene);
  description["camera_path"] = {{"kind", path.arc ? "arc" : "forward"},
                                {"distance", path.distance},
                                {"fov_y_deg", fov_y / kDeg},
                                {"span_deg", path.arc ? path.span / kDeg : 0.0},
                                {"rings", path.rings},
                                {"elevation_deg", path.elevation / kDeg},
                                {"target", {path.target.x(), path.target.y(), path.target.z()}}};
  description["background_gaussians"] = scene.background.size();
  scene.description = description;
  return scene;
}

GaussianSet combined_gaussians(const SynthScene& scene) {
  GaussianSet g;
  g.means = torch::cat({scene.background.means, scene.object.means});
  g.quats = torch::cat({scene.background.quats, scene.object.quats});
  g.scales = torch::cat({scene.background.scales, scene.object.scales});
  g.opacities = torch::cat({scene.background.opacities.reshape({-1}), scene.object.opacities.reshape({-1})});
  g.colors = torch::cat({scene.background.colors, scene.object.colors});
  g.sh_degree = -1;
  return g;
}

}  // namespace ii::synth
