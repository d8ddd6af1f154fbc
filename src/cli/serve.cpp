#include <spdlog/spdlog.h>

#include <csignal>
#include <memory>
#include <optional>
#include <thread>

#include "cli/commands.h"
#include "cli/edit_options.h"
#include "models/cache.h"
#include "inpaint/lama_inpainter.h"
#include "cli/runtime.h"
#include "common/error.h"
#include "io/splat_file.h"
#include "web/server.h"

namespace ii::cli {

namespace {

struct ServeArgs {
  std::string scene_dir;
  SceneOptions scene;
  std::vector<std::string> plys;
  std::string out = "serve-out";
  std::string host = "127.0.0.1";
  int port = 8080;
  int height = 256;
  int views = 4;
  std::string token;
  bool no_token = false;
  std::string checkpoint;
  std::string segmenter, inpainter;
  GeometryOptions geometry;
  RuntimeOptions runtime;
};

WebServer* running_server = nullptr;

// The model, the inpainter and the segmenter the server runs, into `o` and `predictor`.
void load_networks(const ServeArgs& a, ServeOptions& o, std::optional<Predictor>& predictor) {
  if (o.scene_dir || !o.plys.empty()) {
    const Runtime runtime = apply_runtime_options(a.runtime);
    // On a CPU the released checkpoint takes about 11 s an edit at 256 rows (2 cores): auto keeps
    // the built-in model's instant Run and offers the released one as a slower, better Run.
    std::string checkpoint = a.checkpoint;
    if ((checkpoint.empty() || checkpoint == "auto") && runtime.device.is_cpu())
      if (const auto released = cached_model(catalogue_entry("instainpaint"))) {
        o.slower_checkpoint = released->file;
        checkpoint = "default";
        spdlog::info("the released checkpoint from the cache is offered as the page's slower Run (on a CPU)");
      }
    predictor.emplace(checkpoint, runtime.device, runtime.precision);
    spdlog::info("model {} on {}", predictor->model_name(), runtime.device.str());
  }
  o.inpainter = inpainter_from_flag(a.inpainter, "ns");
  if (o.inpainter.learned) spdlog::info("inpainter {}", o.inpainter.describe()["network"].get<std::string>());
  if (const auto path = segmenter_path(a.segmenter)) {
    o.segmenter = std::make_shared<const Segmenter>(Segmenter::load(
        *path, parse_segmenter_precision(a.runtime.precision)));
    spdlog::info("segmenter {} ({})", o.segmenter->description(), path->string());
  }
}

void run(const ServeArgs& a) {
  ServeOptions o;
  if (!a.scene_dir.empty()) o.scene_dir = a.scene_dir;
  o.scene = a.scene;
  for (const std::string& p : a.plys) {
    // The page's viewer (Spark) is given the file as it is.
    if (splat_format_of(p) == SplatFormat::Sog)
      fail("{}: the page shows PLY, compressed PLY and SPZ files: convert it first (instainpaint convert {} x.spz)", p, p);
    o.plys.emplace_back(p);
  }
  o.out = a.out;
  o.host = a.host;
  o.port = a.port;
  o.height = a.height;
  o.views = a.views;
  o.geometry = a.geometry;
  o.token = a.token;
  o.no_token = a.no_token;
  o.reconstruct_at_start = true;
  if (a.no_token)
    spdlog::warn("--no-token: any program on this machine and any website open in its browser can drive this server");
  if (o.host != "127.0.0.1" && o.host != "localhost" && o.host != "::1")
    spdlog::warn("listening on {}: anyone who can reach this machine can see the scene and run edits", o.host);

  // The networks are read on the thread that runs every job and click (common/compute_thread.h):
  // LibTorch's work on this one too would slow all of it. The model is loaded once, before the
  // first request, when there is a scene to edit or splats to fill.
  o.compute = std::make_shared<ComputeThread>();
  std::optional<Predictor> predictor;
  o.compute->run([&] { load_networks(a, o, predictor); });
  WebServer server(o, predictor ? &*predictor : nullptr);
  const int port = server.bind();
  const std::string host = o.host.find(':') != std::string::npos ? "[" + o.host + "]" : o.host;
  const std::string query = server.token().empty() ? "" : "?token=" + server.token();
  fmt::print("instainpaint serve: open http://{}:{}/{} (Ctrl-C stops)\n", host, port, query);
  std::fflush(stdout);
  running_server = &server;
  std::signal(SIGINT, [](int) { running_server->stop(); });
  std::signal(SIGTERM, [](int) { running_server->stop(); });
  server.run();
  running_server = nullptr;
  spdlog::info("stopped");
}

}  // namespace

void add_serve_command(CLI::App& app) {
  auto args = std::make_shared<ServeArgs>();
  auto* cmd = app.add_subcommand("serve", "Look at splats, edit a scene, or fill the hole of an object removed from "
                                          "any splat file, in the browser");
  cmd->add_option("--scene", args->scene_dir, "Scene to show and edit (its views, cameras and masks)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--format", args->scene.format, "Scene format")
      ->check(CLI::IsMember({"auto", "llff", "nerfstudio", "colmap"}))
      ->capture_default_str();
  cmd->add_option("--images", args->scene.image_folder, "Image sub-folder of the scene (e.g. images_4)");
  cmd->add_option("--hold-out-every", args->scene.hold_out_every,
                  "Hold out views 0, N, 2N, ... as test views for the evaluation report (see infer --help)")
      ->check(CLI::Range(1, 1000));
  cmd->add_option("--splats,--ply", args->plys,
                  "Splat files to show (3DGS PLY, SuperSplat compressed PLY, Niantic SPZ); several allowed")
      ->check(CLI::ExistingFile);
  cmd->add_option("--out", args->out, "Folder for the edits' results")->capture_default_str();
  cmd->add_option("--host", args->host, "Address to listen on (anything but loopback is reachable by others)")
      ->capture_default_str();
  cmd->add_option("--port", args->port, "Port (0 = any free one)")->capture_default_str()->check(CLI::Range(0, 65535));
  cmd->add_option("--segmenter", args->segmenter,
                  kSegmenterHelp + ". With one, the page's clicks draw its outline at once (shift-click: another point "
                  "on the object, alt-click: a point that is not)");
  cmd->add_option("--inpainter", args->inpainter,
                  kInpainterHelp + std::string("ns. With a LaMa file, the page's Run and Fill paint with it"));
  cmd->add_option("--height", args->height, "Working height of edits in pixels")
      ->capture_default_str()
      ->check(CLI::Range(8, 4096));
  cmd->add_option("--views", args->views, "Context views of an edit")->capture_default_str()->check(CLI::Range(1, 64));
  cmd->add_option("--token", args->token,
                  "The token every request must carry (default: a random one, printed in the address to open)");
  cmd->add_flag("--no-token", args->no_token, "Serve without a token (not recommended: websites can then drive it)")
      ->excludes("--token");
  cmd->add_option("--checkpoint", args->checkpoint, kCheckpointHelp + ". On a CPU, auto keeps the built-in model for the page's instant Run and offers the cache's released checkpoint as a slower one");
  add_geometry_options(cmd, args->geometry);
  add_runtime_options(cmd, args->runtime);
  cmd->footer(
      "Examples:\n"
      "  instainpaint serve --scene ../shared/data/statue --ply out/statue/gaussians.ply\n"
      "  instainpaint serve --ply guitar.compressed.ply --port 0\n"
      "  instainpaint serve --splats room.ply     (remove an object with a box or a stroke, and fill the hole)\n"
      "Open the printed address (http://127.0.0.1:8080/?token=...): the page then keeps the token in a cookie.\n"
      "Scripts send it as ?token= or as the X-Instainpaint-Token header.");
  cmd->callback([args] { run(*args); });
}

}  // namespace ii::cli
