#include "data/colmap_run.h"

#include <vector>

#include "common/error.h"
#include "common/process.h"
#include "io/colmap.h"

namespace ii {

namespace fs = std::filesystem;

fs::path find_colmap(const std::string& executable) { return find_executable(executable); }

fs::path run_colmap(const fs::path& scene_dir, const ColmapRunOptions& options) {
  const fs::path exe = find_colmap(options.executable);
  if (exe.empty())
    fail("COLMAP is not installed ('{}' not found{}): install it (e.g. `apt install colmap`) or give the path to the "
         "executable, or pose the images with another tool and use its transforms.json / sparse model",
         options.executable, options.executable.find('/') == std::string::npos ? " on PATH" : "");
  if (options.matcher != "exhaustive" && options.matcher != "sequential")
    fail("unknown COLMAP matcher '{}' (expected exhaustive or sequential)", options.matcher);
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
  auto run_step = [&](const std::vector<std::string>& args) { run_logged(exe, args, log, "colmap " + args[0]); };
  run_step({"feature_extractor", "--database_path", db.string(), "--image_path", images.string(),
            "--ImageReader.camera_model", options.camera_model, "--ImageReader.single_camera",
            options.single_camera ? "1" : "0", "--SiftExtraction.use_gpu", gpu});
  run_step({options.matcher + "_matcher", "--database_path", db.string(), "--SiftMatching.use_gpu", gpu});
  run_step({"mapper", "--database_path", db.string(), "--image_path", images.string(), "--output_path", sparse.string()});

  // The mapper writes one numbered folder per disconnected reconstruction.
  fs::path best;
  size_t best_images = 0;
  for (const auto& e : fs::directory_iterator(sparse)) {
    if (!e.is_directory()) continue;
    const fs::path p = e.path();
    if (!fs::exists(p / "cameras.bin") && !fs::exists(p / "cameras.txt")) continue;
    const size_t n = read_colmap_model(p).images.size();
    if (n > best_images) {
      best_images = n;
      best = p;
    }
  }
  if (best.empty())
    fail_file(sparse, "COLMAP reconstructed nothing (too few matches between the images?); see {}", log.string());
  return best;
}

}  // namespace ii
