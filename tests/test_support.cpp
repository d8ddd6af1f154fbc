#include "test_support.h"

#include <cstdlib>
#include <fstream>
#include <iterator>
#include <random>

#include <sys/wait.h>

namespace ii::test {

namespace fs = std::filesystem;

fs::path shared_path(const std::string& relative) {
  const char* env = std::getenv("INSTAINPAINT_SHARED");
  const fs::path root = (env && *env) ? fs::path(env) : fs::path(INSTAINPAINT_SHARED_DIR);
  return root / relative;
}

namespace {
struct TempRoot {
  fs::path path;
  TempRoot() {
    std::random_device rd;
    path = fs::temp_directory_path() / ("instainpaint-test-" + std::to_string(rd()));
    fs::create_directories(path);
  }
  ~TempRoot() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};
}  // namespace

std::string file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void write_bytes(const fs::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}

fs::path temp_dir(const std::string& tag) {
  static TempRoot root;
  static int counter = 0;
  fs::path p = root.path / (tag + "-" + std::to_string(counter++));
  fs::create_directories(p);
  return p;
}

fs::path cli_executable() {
  return fs::read_symlink("/proc/self/exe").parent_path().parent_path() / "instainpaint";
}

int run_command(const std::string& command, const fs::path& log) {
  const std::string cmd = command + " > '" + log.string() + "' 2>&1";
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace ii::test
