#include "fuzz_target.h"

#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <sstream>

#include "common/error.h"

namespace ii::fuzz {

namespace fs = std::filesystem;

namespace {
std::vector<FuzzTarget>& registry() {
  static std::vector<FuzzTarget> all;
  return all;
}
}  // namespace

bool register_target(FuzzTarget target) {
  registry().push_back(std::move(target));
  return true;
}

const std::vector<FuzzTarget>& targets() { return registry(); }

const FuzzTarget* find_target(const std::string& name) {
  for (const FuzzTarget& t : registry())
    if (t.name == name) return &t;
  return nullptr;
}

const fs::path& scratch_dir() {
  static const fs::path dir = [] {
    const char* tmp = std::getenv("TMPDIR");
    fs::path d = fs::path(tmp && *tmp ? tmp : "/tmp") / ("instainpaint-fuzz-" + std::to_string(getpid()));
    fs::remove_all(d);
    fs::create_directories(d);
    std::atexit([] { std::error_code ec; fs::remove_all(scratch_dir(), ec); });
    return d;
  }();
  return dir;
}

void write_file(const fs::path& path, const uint8_t* data, size_t size) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  if (!out) fail_file(path, "fuzz harness could not write its input");
}

void write_file(const fs::path& path, const std::string& bytes) {
  write_file(path, reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size());
}

std::string bytes_written_by(const std::function<void(const fs::path&)>& write) {
  const fs::path path = scratch_dir() / "seed.tmp";
  write(path);
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  fs::remove(path);
  return s.str();
}

}  // namespace ii::fuzz
