// `instainpaint capture`: a video or a folder of photos to a posed scene the other commands
// read (library: src/capture).
#include <fmt/core.h>
#include <spdlog/spdlog.h>

#include "capture/capture.h"
#include "cli/commands.h"
#include "common/stopwatch.h"

namespace ii::cli {

namespace {

struct CaptureArgs {
  std::string input;
  std::string out;
  CaptureOptions options;
};

void run(const CaptureArgs& a) {
  CaptureOptions o = a.options;
  Stopwatch clock;
  o.on_stage = [&clock](int k, int n, const std::string& what) {
    spdlog::info("[{}/{}] {} ({:.0f} s so far)", k, n, what, clock.ms() / 1000);
  };
  // COLMAP's progress every 5 seconds, and when a step starts.
  std::string last_step;
  Stopwatch since_shown;
  o.on_colmap_progress = [&](const std::string& step, int done, int total, double eta_s) {
    if (step == last_step && since_shown.ms() < 5000) return;
    last_step = step;
    since_shown.lap();
    spdlog::info("      COLMAP {}: {} of {}{}", step, done, total,
                 eta_s >= 0 ? fmt::format(", about {:.0f} s left", eta_s) : std::string());
  };
  const nlohmann::json report = capture_scene(a.input, a.out, o);
  if (report.contains("compared_with")) fmt::print("{}\n", comparison_line(report["compared_with"]));
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
                  "COLMAP matching: auto (a video's frames in turn; photos in name order first, every pair only when "
                  "that leaves some unposed), sequential or exhaustive (every pair: photos in no order)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "sequential", "exhaustive"}));
  cmd->add_option("--colmap", a->options.colmap, "The colmap executable")->capture_default_str();
  cmd->add_option("--compare", a->options.compare,
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
