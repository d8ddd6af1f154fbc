// `instainpaint capture`: a video or a folder of photos to a posed scene the other commands
// read (library: src/capture).
#include <fmt/core.h>
#include <spdlog/spdlog.h>

#include "capture/capture.h"
#include "cli/commands.h"
#include "common/files.h"
#include "common/stopwatch.h"

namespace ii::cli {

namespace fs = std::filesystem;

namespace {

struct CaptureArgs {
  std::string input;
  std::string out;
  std::string compare;
  CaptureOptions options;
};

void run(const CaptureArgs& a) {
  CaptureOptions o = a.options;
  Stopwatch clock;
  o.on_stage = [&clock](int k, int n, const std::string& what) {
    spdlog::info("[{}/{}] {} ({:.0f} s so far)", k, n, what, clock.ms() / 1000);
  };
  nlohmann::json report = capture_scene(a.input, a.out, o);
  if (!a.compare.empty()) {
    const PoseComparison c =
        compare_poses(poses_of(read_colmap_model(fs::path(a.out) / "sparse" / "0")), poses_of_scene(a.compare));
    report["compared_with"] = {{"scene", a.compare},
                               {"matched", c.matched},
                               {"median_rotation_deg", c.median_rotation_deg},
                               {"max_rotation_deg", c.max_rotation_deg},
                               {"median_position", c.median_position},
                               {"max_position", c.max_position},
                               {"position_unit", "largest distance between two reference cameras"}};
    write_file_atomic(fs::path(a.out) / "capture.json", report.dump(2) + "\n");
    fmt::print("against {} ({} views matched): rotation median {:.3f} deg (max {:.3f}), position median {:.4f} "
               "(max {:.4f}) of the camera spread\n",
               a.compare, c.matched, c.median_rotation_deg, c.max_rotation_deg, c.median_position, c.max_position);
  }
  fmt::print("{}: {} of {} images posed, {} points, in {:.0f} s (frames {:.0f} s, COLMAP {:.0f} s, undistortion {:.0f} s)\n",
             a.out, report["registered"].get<int>(), report["images"].get<int>(), report["points"].get<size_t>(),
             report["timings"]["total_s"].get<double>(), report["timings"]["frames_s"].get<double>(),
             report["timings"]["colmap_s"].get<double>(), report["timings"]["undistort_s"].get<double>());
  fmt::print("next: instainpaint serve --scene {}   (or infer / render --trajectory on it)\n", a.out);
}

}  // namespace

void add_capture_command(CLI::App& app) {
  auto a = std::make_shared<CaptureArgs>();
  auto* cmd = app.add_subcommand("capture", "Pose a video or a folder of photos with COLMAP into a scene folder");
  cmd->add_option("input", a->input, "A video (any format ffmpeg reads) or a folder of photos")->required();
  cmd->add_option("--out", a->out, "The scene folder to make (new or empty)")->required();
  cmd->add_option("--frames", a->options.frames, "Frames taken from a video: the sharpest of each equal stretch")
      ->capture_default_str()
      ->check(CLI::Range(3, 2000));
  cmd->add_option("--max-size", a->options.max_size, "Long side of the posed images, in pixels")
      ->capture_default_str()
      ->check(CLI::Range(64, 8192));
  cmd->add_option("--matcher", a->options.matcher,
                  "COLMAP matching: auto (sequential for a video, exhaustive for photos), sequential or exhaustive")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "sequential", "exhaustive"}));
  cmd->add_option("--colmap", a->options.colmap, "The colmap executable")->capture_default_str();
  cmd->add_option("--compare", a->compare,
                  "A posed scene of the same views (any format) to measure the recovered poses against")
      ->check(CLI::ExistingDirectory);
  cmd->footer(
      "Examples:\n"
      "  instainpaint capture my-video.mp4 --out my-scene\n"
      "  instainpaint capture photos/ --out my-scene --max-size 1008\n"
      "  instainpaint serve --scene my-scene      # then paint the object on one view");
  cmd->callback([a] { run(*a); });
}

}  // namespace ii::cli
