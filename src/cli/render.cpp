// `instainpaint render`: images and a video of a splat PLY from scene cameras, a camera
// list, or a camera path.
#include <fmt/core.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "camera/trajectory.h"
#include "cli/commands.h"
#include "common/error.h"
#include "common/files.h"
#include "common/stopwatch.h"
#include "data/scene_cameras.h"
#include "gaussians/gaussians.h"
#include "io/image.h"
#include "io/splat_file.h"
#include "io/video.h"
#include "model/device.h"
#include "render/frames.h"
#include "render/rasterizer.h"
#include "tensor/image_tensor.h"

namespace ii::cli {

namespace fs = std::filesystem;

namespace {

struct RenderArgs {
  std::string ply;
  std::string scene_dir;
  SceneOptions scene;
  bool normalize = false;
  std::vector<std::string> views;
  bool test_views = false;
  std::string cameras;
  std::string trajectory;
  std::string orbit_center;
  double radius = 0;  // 0 = default
  int frames = 72;
  int width = 0, height = 0;
  double fov = 50;  // degrees, turntable
  double elevation = 20;
  std::string up = "-y";
  std::vector<float> background{1.f, 1.f, 1.f};
  int sh_degree = 3;
  bool depth = false, alpha = false, no_video = false;
  int fps = 24;
  int threads = 0;
  std::string device = "auto";
  std::string out = "render-out";
};

// Around the splat cloud itself (no scene needed): looks at the centre of the box that
// holds 96% of the (not too transparent) splats along each axis, from far enough that the
// box's bounding sphere fits the field of view.
std::vector<NamedCamera> turntable_cameras(const RenderArgs& a, const GaussianSet& g) {
  if (g.size() == 0) fail("{}: no splats to frame", a.ply);
  const BoundingSphere bounds = visible_bounds(g);
  Eigen::Vector3d up;
  const std::string u = a.up;
  if (u == "y") up = Eigen::Vector3d::UnitY();
  else if (u == "-y") up = -Eigen::Vector3d::UnitY();
  else if (u == "z") up = Eigen::Vector3d::UnitZ();
  else if (u == "-z") up = -Eigen::Vector3d::UnitZ();
  else if (u == "x") up = Eigen::Vector3d::UnitX();
  else up = -Eigen::Vector3d::UnitX();
  const int w = a.width > 0 ? a.width : 512, h = a.height > 0 ? a.height : 512;
  std::vector<NamedCamera> out;
  for (const Camera& c : turntable_around_sphere(bounds.centre, bounds.radius, a.fov * M_PI / 180.0, a.elevation, up,
                                                a.frames, w, h))
    out.push_back({fmt::format("{:04d}", out.size()), c});
  return out;
}

void progress(int done, int total, double seconds) {
  const int width = 30, filled = total > 0 ? done * width / total : width;
  std::fprintf(stderr, "\r[%s%s] %d/%d frames, %.1f frames/s", std::string(filled, '#').c_str(),
               std::string(width - filled, ' ').c_str(), done, total, seconds > 0 ? done / seconds : 0.0);
  if (done == total) std::fprintf(stderr, "\n");
  std::fflush(stderr);
}

// The CUDA rasterizer when asked for (or, with auto, when there is one), else the CPU.
torch::Device chosen_render_device(const std::string& name) {
  const torch::Device device = resolve_device(name);
  if (device.is_cuda() && !render_has_cuda() && name != "auto")
    fail("--device {}: this build has no CUDA rasterizer (no nvcc when it was configured)", name);
  return render_device(device);
}

void run(const RenderArgs& a) {
  const torch::Device device = chosen_render_device(a.device);
  set_cpu_threads(a.threads);
  const int sources = !a.scene_dir.empty() + !a.cameras.empty();
  if (sources > 1) fail("give cameras either with --scene or with --cameras, not both");
  if (a.trajectory == "turntable" && sources > 0) fail("--trajectory turntable frames the PLY itself: drop --scene/--cameras");
  if ((a.trajectory == "orbit" || a.trajectory == "path") && a.scene_dir.empty())
    fail("--trajectory {} needs --scene (turntable works without one)", a.trajectory);
  if (sources == 0 && a.trajectory.empty()) fail("no cameras: give --scene, --cameras or --trajectory turntable");
  if (a.background.size() != 3) fail("--background needs three values r,g,b in [0,1]");

  Stopwatch total;
  const SplatCloud cloud = read_splats(a.ply);
  const GaussianSet loaded = gaussians_from_splats(cloud, a.sh_degree);
  spdlog::info("{}: {} splats, SH degree {}, rendering on {}", a.ply, loaded.size(), loaded.sh_degree, device.str());

  std::vector<NamedCamera> cams;
  if (!a.cameras.empty()) {
    for (NamedCamera& nc : read_camera_json(a.cameras)) cams.push_back({nc.name, resized_to(nc.camera, a.width, a.height)});
  } else if (!a.scene_dir.empty()) {
    SceneCameraOptions o;
    o.views = a.views;
    o.test_views = a.test_views;
    o.normalize = a.normalize;
    o.trajectory = a.trajectory;
    o.orbit_center = a.orbit_center;
    o.radius = a.radius;
    o.frames = a.frames;
    o.width = a.width;
    o.height = a.height;
    cams = scene_cameras(load_scene(a.scene_dir, a.scene), o);
  } else {
    cams = turntable_cameras(a, loaded);
  }
  const GaussianSet g = loaded.to(device);

  const fs::path out(a.out);
  RenderOptions options;
  options.background = {a.background[0], a.background[1], a.background[2]};
  const int n = static_cast<int>(cams.size());
  Stopwatch watch;
  progress(0, n, 0);
  const double render_ms =
      render_frames(g, cams, options, {out / "rgb", a.depth ? out / "depth" : fs::path(), a.alpha ? out / "alpha" : fs::path()},
                    [&](int done, int total) { progress(done, total, watch.ms() / 1000.0); });
  write_camera_json(out / "cameras.json", cams);

  nlohmann::json videos = nlohmann::json::array();
  if (n > 1 && !a.no_video) {
    if (!ffmpeg_available()) {
      spdlog::warn("ffmpeg not found (scripts/install-deps.sh installs it): frames written, no video");
    } else {
      for (const char* kind : {"rgb", "depth", "alpha"}) {
        if ((kind == std::string("depth") && !a.depth) || (kind == std::string("alpha") && !a.alpha)) continue;
        const fs::path video = out / (kind + std::string(".mp4"));
        if (encode_video(out / kind, video, a.fps))
          videos.push_back(video.filename().string());
        else
          spdlog::warn("ffmpeg failed to write {}", video.string());
      }
    }
  }
  const nlohmann::json summary = {{"ply", a.ply},
                                  {"splats", g.size()},
                                  {"sh_degree", g.sh_degree},
                                  {"frames", n},
                                  {"threads", torch::get_num_threads()},
                                  {"device", device.str()},
                                  {"render_ms_per_frame", n ? render_ms / n : 0.0},
                                  {"total_ms", total.ms()},
                                  {"outputs", {{"cameras", "cameras.json"}, {"videos", videos}}}};
  write_file_atomic(out / "render.json", summary.dump(2) + "\n");
  fmt::print("rendered {} frames of {} splats ({:.0f} ms per frame) into {}{}\n", n, g.size(),
             n ? render_ms / n : 0.0, out.string(), videos.empty() ? "" : fmt::format(", video {}", videos[0].get<std::string>()));
}

}  // namespace

void add_render_command(CLI::App& app) {
  auto a = std::make_shared<RenderArgs>();
  auto* cmd = app.add_subcommand("render", "Render a splat file (PLY, compressed PLY, SPZ, SOG) to images and a video");
  cmd->add_option("--splats,--ply", a->ply,
                  "Gaussian splat file: standard 3DGS PLY, SuperSplat compressed PLY, Niantic SPZ or PlayCanvas SOG")
      ->required()
      ->check(CLI::ExistingFile);
  add_scene_options(cmd, a->scene_dir, a->scene);
  cmd->get_option("--scene")->required(false)->description(
      "Scene whose cameras to render (any format instainpaint reads); see --normalize");
  cmd->add_flag("--normalize", a->normalize,
                "Put the scene's cameras in the pose-normalised frame (centres minus their mean, divided by the "
                "largest offset, over all cameras of the scene): the frame of splats written by `infer --normalized` "
                "(infer, fill and 3DGS trainers write the scene's own frame, which needs no flag)");
  cmd->add_option("--views", a->views, "Scene views to render (or to pass through with --trajectory path), by name")
      ->delimiter(',');
  cmd->add_flag("--test-views", a->test_views, "Render the scene's object-free test views instead of its views");
  cmd->add_option("--cameras", a->cameras, "Camera list JSON (format below)")->check(CLI::ExistingFile);
  cmd->add_option("--trajectory", a->trajectory,
                  "Camera path: orbit (official video circle, needs --scene), path (smooth path through the scene "
                  "views), turntable (around the PLY's splats, no scene needed)")
      ->check(CLI::IsMember({"orbit", "path", "turntable"}));
  cmd->add_option("--frames", a->frames, "Frames of a trajectory")->capture_default_str()->check(CLI::Range(1, 100000));
  cmd->add_option("--orbit-center", a->orbit_center,
                  "Orbit: view whose position is the circle's centre (official: the vis_centroid view; default: the "
                  "view nearest the mean camera centre)");
  cmd->add_option("--radius", a->radius,
                  "Orbit radius in the cameras' frame (default: the official 4 / cam_loc_scale normalised units = 4 "
                  "scene units)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--fov", a->fov, "Turntable vertical field of view, degrees")->capture_default_str()->check(CLI::Range(1.0, 170.0));
  cmd->add_option("--elevation", a->elevation, "Turntable elevation, degrees")->capture_default_str();
  cmd->add_option("--up", a->up, "Turntable up axis of the PLY (3DGS captures: -y)")
      ->capture_default_str()
      ->check(CLI::IsMember({"x", "-x", "y", "-y", "z", "-z"}));
  cmd->add_option("--width", a->width, "Image width (default: the camera's; trajectories 512; with only --height, "
                                       "follows the aspect ratio)")
      ->check(CLI::Range(1, 16384));
  cmd->add_option("--height", a->height, "Image height (see --width)")->check(CLI::Range(1, 16384));
  cmd->add_option("--background", a->background, "Background colour r,g,b in [0,1]")
      ->delimiter(',')
      ->expected(3)
      ->capture_default_str();
  cmd->add_option("--sh-degree", a->sh_degree, "Highest SH degree to use from the PLY")
      ->capture_default_str()
      ->check(CLI::Range(0, 3));
  cmd->add_flag("--depth", a->depth, "Also write depth colour maps (and depth.mp4)");
  cmd->add_flag("--alpha", a->alpha, "Also write alpha (coverage) images (and alpha.mp4)");
  cmd->add_flag("--no-video", a->no_video, "Write only PNG frames");
  cmd->add_option("--fps", a->fps, "Video frame rate")->capture_default_str()->check(CLI::Range(1, 240));
  cmd->add_option("--threads", a->threads, "CPU threads (0 = all cores)")->capture_default_str();
  cmd->add_option("--device", a->device, "Where to render: auto (the CUDA rasterizer when there is a GPU), cpu, cuda, "
                                         "cuda:N")
      ->capture_default_str();
  cmd->add_option("--out", a->out, "Output folder")->capture_default_str();
  cmd->footer(
      "Writes OUT/rgb/NNNN.png (OUT/depth, OUT/alpha with --depth/--alpha), OUT/rgb.mp4 via ffmpeg,\n"
      "OUT/cameras.json (the cameras used, in the --cameras format) and OUT/render.json.\n"
      "\n"
      "--cameras JSON: {\"convention\": \"opengl\", \"cameras\": [{\"name\": \"a\", \"width\": 512, \"height\": 512,\n"
      "  \"fx\": 600, \"fy\": 600, \"cx\": 256, \"cy\": 256, \"c2w\": [[1,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]}]}\n"
      "  fov_x_deg/fov_y_deg may replace fx/fy; cx, cy default to the centre; \"w2c\" may replace \"c2w\";\n"
      "  convention \"opengl\" (x right, y up, looking along -z; default) or \"opencv\" (y down, +z).\n"
      "\n"
      "Examples:\n"
      "  instainpaint render --ply out/statue/gaussians.ply --scene ../shared/data/statue --trajectory orbit\n"
      "  instainpaint render --ply guitar.compressed.ply --trajectory turntable --frames 48 --depth");
  cmd->callback([a] { run(*a); });
}

}  // namespace ii::cli
