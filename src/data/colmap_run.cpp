#include "data/colmap_run.h"

#include <algorithm>
#include <chrono>
#include <regex>
#include <tuple>
#include <vector>

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "common/stopwatch.h"
#include "common/process.h"
#include "io/colmap.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

std::string step_name(const std::string& command) {
  if (command == "feature_extractor") return "features";
  if (command == "mapper") return "mapping";
  return "matching";
}

// The last "[i/n]" counter of a step in its log: "Processed file [i/n]" (features), "Matching
// image [i/n]" or "Matching block [i/n, ...]" (matching), "Registering image #k (i)" (mapping,
// of all images). {0, total} before the first.
std::pair<int, int> step_counter(const std::string& tail, const std::string& step, int images) {
  static const std::regex features(R"(Processed file \[(\d+)/(\d+)\])"),
      matching(R"(Matching (?:image|block) \[(\d+)/(\d+))"), mapping(R"(Registering image #\d+ \((\d+)\))");
  const std::regex& pattern = step == "features" ? features : step == "matching" ? matching : mapping;
  std::pair<int, int> last{0, step == "matching" ? 0 : images};
  for (std::sregex_iterator it(tail.begin(), tail.end(), pattern), end; it != end; ++it)
    last = step == "mapping" ? std::pair<int, int>{std::stoi((*it)[1]), images}
                             : std::pair<int, int>{std::stoi((*it)[1]), std::stoi((*it)[2])};
  return last;
}

// The numbered model folder with the most images, and their count (empty path, 0: none).
std::pair<fs::path, int> largest_model(const fs::path& sparse) {
  std::pair<fs::path, int> best{{}, 0};
  for (const auto& e : fs::directory_iterator(sparse)) {
    if (!e.is_directory()) continue;
    const fs::path p = e.path();
    if (!fs::exists(p / "cameras.bin") && !fs::exists(p / "cameras.txt")) continue;
    const int n = static_cast<int>(read_colmap_model(p).images.size());
    if (n > best.second) best = {p, n};
  }
  return best;
}

}  // namespace

fs::path find_colmap(const std::string& executable) { return find_executable(executable); }

fs::path run_colmap(const fs::path& scene_dir, const ColmapRunOptions& options) {
  return run_colmap_steps(scene_dir, options).model;
}

ColmapRun run_colmap_steps(const fs::path& scene_dir, const ColmapRunOptions& options) {
  const fs::path exe = find_colmap(options.executable);
  if (exe.empty())
    fail("COLMAP is not installed ('{}' not found{}): install it (e.g. `apt install colmap`) or give the path to the "
         "executable, or pose the images with another tool and use its transforms.json / sparse model",
         options.executable, options.executable.find('/') == std::string::npos ? " on PATH" : "");
  const bool fallback = options.matcher == "sequential+exhaustive";
  if (options.sequential_overlap < 1)
    fail("COLMAP's sequential overlap must be at least 1, got {}", options.sequential_overlap);
  if (options.matcher != "exhaustive" && options.matcher != "sequential" && !fallback)
    fail("unknown COLMAP matcher '{}' (expected exhaustive, sequential or sequential+exhaustive)", options.matcher);
  const fs::path dir = fs::absolute(scene_dir);
  const fs::path images = dir / options.image_folder;
  if (!fs::is_directory(images)) fail_file(images, "image folder not found");

  const fs::path db = dir / "database.db", sparse = dir / "sparse", log = dir / "colmap.log";
  // Never overwrite (or mix with) a model that is already there.
  if (fs::is_directory(sparse) && !fs::is_empty(sparse))
    fail_file(sparse, "already holds a model; move it away to reconstruct again");
  // A database from an earlier run would mix old features into the new model.
  fs::remove(db);
  fs::remove(log);
  fs::create_directories(sparse);
  const std::string gpu = options.use_gpu ? "1" : "0";
  const int images_count = static_cast<int>(std::count_if(fs::directory_iterator(images), fs::directory_iterator(),
                                                          [](const fs::directory_entry& e) { return e.is_regular_file(); }));
  auto run_step = [&](const std::vector<std::string>& args) {
    std::function<void()> poll;
    const auto started = std::chrono::steady_clock::now();
    if (options.progress)
      poll = [&, step = step_name(args[0]), most = 0]() mutable {
        // The counter only goes up (the last 40 lines may hold none of it).
        const auto [counted, total] = step_counter(log_tail(log, 40), step, images_count);
        const int done = most = std::max(most, counted);
        const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
        options.progress(step, done, total, done > 0 ? elapsed / done * (total - done) : -1);
      };
    run_logged(exe, args, log, "colmap " + args[0], poll);
  };
  ColmapRun run;
  Stopwatch step;
  run_step({"feature_extractor", "--database_path", db.string(), "--image_path", images.string(),
            "--ImageReader.camera_model", options.camera_model, "--ImageReader.single_camera",
            options.single_camera ? "1" : "0", "--SiftExtraction.use_gpu", gpu, "--SiftExtraction.max_num_features",
            std::to_string(options.max_features)});
  run.features_s = step.lap() / 1000;
  auto match = [&](const std::string& matcher) {
    std::vector<std::string> args = {matcher + "_matcher", "--database_path", db.string(), "--SiftMatching.use_gpu", gpu};
    if (matcher == "sequential")
      args.insert(args.end(), {"--SequentialMatching.overlap", std::to_string(options.sequential_overlap)});
    run_step(args);
    run.matchers.push_back(matcher);
    run.matching_s += step.lap() / 1000;
  };
  auto map = [&] {
    std::vector<std::string> args = {"mapper", "--database_path", db.string(), "--image_path", images.string(),
                                     "--output_path", sparse.string()};
    args.insert(args.end(), options.mapper_options.begin(), options.mapper_options.end());
    run_step(args);
    run.mapping_s += step.lap() / 1000;
    // The mapper writes one numbered folder per disconnected reconstruction.
    std::tie(run.model, run.registered) = largest_model(sparse);
  };
  match(fallback ? "sequential" : options.matcher);
  map();
  if (fallback && run.registered < images_count) {
    spdlog::info("sequential matching posed {} of {} images: matching the other pairs too", run.registered,
                 images_count);
    match("exhaustive");
    fs::remove_all(sparse);
    fs::create_directories(sparse);
    map();
  }
  if (run.model.empty())
    fail_file(sparse, "COLMAP reconstructed nothing (too few matches between the images?); see {}", log.string());
  return run;
}

}  // namespace ii
