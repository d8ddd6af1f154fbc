#include "test_support.h"

#include <algorithm>
#include <cmath>
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

std::string shared_missing(const std::string& relative) {
  const fs::path path = shared_path(relative);
  const fs::path rel(relative);
  auto part = rel.begin();
  if (part != rel.end() && *part == "data" && ++part != rel.end()) {
    const fs::path folder = shared_path("data") / *part;
    if (!fs::exists(folder / "PROVENANCE.md"))
      return "shared data missing: " + folder.string() + " is absent or incomplete (no PROVENANCE.md)";
  }
  if (!fs::exists(path)) return "shared data missing: " + path.string();
  return {};
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

std::vector<fs::path> truncated_copies(const fs::path& file, const fs::path& dir) {
  const std::string bytes = file_bytes(file);
  std::vector<fs::path> out;
  for (const size_t keep : {size_t{0}, size_t{100}, bytes.size() / 2, bytes.size() - 30}) {
    out.push_back(dir / ("cut" + std::to_string(keep) + file.extension().string()));
    write_bytes(out.back(), bytes.substr(0, keep));
  }
  return out;
}

fs::path temp_dir(const std::string& tag) {
  static TempRoot root;
  static int counter = 0;
  fs::path p = root.path / (tag + "-" + std::to_string(counter++));
  fs::create_directories(p);
  return p;
}

std::string png_header(uint32_t width, uint32_t height) {
  auto be32 = [](uint32_t v) {
    return std::string{static_cast<char>(v >> 24), static_cast<char>(v >> 16), static_cast<char>(v >> 8),
                       static_cast<char>(v)};
  };
  // Signature, then the IHDR chunk: size, type, width, height, 8 bits, RGB, deflate, no filter
  // or interlace, and a CRC that no header probe checks.
  return std::string("\x89PNG\r\n\x1a\n", 8) + be32(13) + "IHDR" + be32(width) + be32(height) +
         std::string("\x08\x02\x00\x00\x00", 5) + be32(0);
}

double peak_rss_mb() {
  std::ifstream status("/proc/self/status");
  for (std::string key; status >> key;) {
    double kb = 0;
    if (key == "VmHWM:" && status >> kb) return kb / 1024.0;
  }
  return 0;
}

fs::path cli_executable() {
  return fs::read_symlink("/proc/self/exe").parent_path().parent_path() / "instainpaint";
}

int run_command(const std::string& command, const fs::path& log) {
  const std::string cmd = command + " > '" + log.string() + "' 2>&1";
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

SplatCloud random_splats(size_t n, int rest, uint32_t seed, float extent) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  SplatCloud c;
  c.sh_rest_per_channel = rest;
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      c.means.push_back(extent * u(rng));
      c.sh_dc.push_back(1.5f * u(rng));
      c.log_scales.push_back(-4 + 3 * u(rng));
    }
    for (int k = 0; k < 3 * rest; ++k) c.sh_rest.push_back(0.9f * u(rng));
    c.opacity_logit.push_back(5 * u(rng));
    for (int a = 0; a < 4; ++a) c.rotations.push_back(u(rng));
  }
  return c;
}

double rotation_angle(const float* a, const float* b) {
  double dot = 0, na = 0, nb = 0;
  for (int k = 0; k < 4; ++k) {
    dot += double(a[k]) * b[k];
    na += double(a[k]) * a[k];
    nb += double(b[k]) * b[k];
  }
  return 2 * std::acos(std::min(1.0, std::abs(dot) / std::sqrt(na * nb)));
}

}  // namespace ii::test
