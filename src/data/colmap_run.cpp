#include "data/colmap_run.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <string_view>
#include <vector>

#include "common/error.h"
#include "common/files.h"
#include "io/colmap.h"

extern char** environ;

namespace ii {

namespace fs = std::filesystem;

namespace {

bool is_executable(const fs::path& p) { return fs::is_regular_file(p) && ::access(p.c_str(), X_OK) == 0; }

// The last `n` lines of a log, for error messages.
std::string log_tail(const fs::path& log, int n) {
  std::string text;
  try {
    text = read_file_text(log);
  } catch (const Error&) {
    return "(no log)";
  }
  size_t pos = text.size();
  while (pos > 0 && (text[pos - 1] == '\n' || text[pos - 1] == '\r')) --pos;
  const size_t end = pos;
  for (int lines = 0; pos > 0; --pos)
    if (text[pos - 1] == '\n' && ++lines == n) break;
  return text.substr(pos, end - pos);
}

// Runs argv[0] with its output appended to `log`; no shell, so paths need no quoting.
void run_step(const fs::path& exe, const std::vector<std::string>& args, const fs::path& log) {
  std::vector<char*> argv;
  argv.push_back(const_cast<char*>(exe.c_str()));
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, exe.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) fail("colmap {}: could not start {}: {}", args[0], exe.string(), std::strerror(rc));
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0)
    if (errno != EINTR) fail("colmap {}: waiting for the process failed: {}", args[0], std::strerror(errno));
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return;
  const std::string how = WIFEXITED(status) ? fmt::format("exited with status {}", WEXITSTATUS(status))
                                            : fmt::format("was killed by signal {}", WTERMSIG(status));
  fail("colmap {} {} (log: {}); last lines:\n{}", args[0], how, log.string(), log_tail(log, 15));
}

}  // namespace

fs::path find_colmap(const std::string& executable) {
  if (executable.empty()) return {};
  if (executable.find('/') != std::string::npos) {
    const fs::path p = fs::absolute(executable);
    return is_executable(p) ? p : fs::path();
  }
  const char* path = std::getenv("PATH");
  std::string_view dirs = path ? path : "/usr/local/bin:/usr/bin:/bin";
  while (true) {
    const size_t colon = dirs.find(':');
    const std::string_view dir = dirs.substr(0, colon);
    const fs::path candidate = fs::path(dir.empty() ? "." : std::string(dir)) / executable;
    if (is_executable(candidate)) return fs::absolute(candidate);
    if (colon == std::string_view::npos) break;
    dirs.remove_prefix(colon + 1);
  }
  return {};
}

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
  run_step(exe,
           {"feature_extractor", "--database_path", db.string(), "--image_path", images.string(),
            "--ImageReader.camera_model", options.camera_model, "--ImageReader.single_camera",
            options.single_camera ? "1" : "0", "--SiftExtraction.use_gpu", gpu},
           log);
  run_step(exe, {options.matcher + "_matcher", "--database_path", db.string(), "--SiftMatching.use_gpu", gpu}, log);
  run_step(exe,
           {"mapper", "--database_path", db.string(), "--image_path", images.string(), "--output_path", sparse.string()},
           log);

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
