#include "io/splat_file.h"

#include <algorithm>
#include <cctype>
#include <optional>

#include "common/error.h"
#include "io/sog.h"
#include "io/spz.h"

namespace ii {

namespace {
std::string lower_name(const std::filesystem::path& path) {
  std::string name = path.filename().string();
  std::transform(name.begin(), name.end(), name.begin(), [](unsigned char ch) { return std::tolower(ch); });
  return name;
}
bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}
}  // namespace

namespace {
// The format a name says, if any: the one list of suffixes both functions below read.
std::optional<SplatFormat> format_by_name(const std::filesystem::path& path) {
  const std::string name = lower_name(path);
  if (ends_with(name, ".compressed.ply")) return SplatFormat::CompressedPly;
  if (ends_with(name, ".ply")) return SplatFormat::Ply;
  if (ends_with(name, ".spz")) return SplatFormat::Spz;
  if (ends_with(name, ".sog") || name == "meta.json") return SplatFormat::Sog;
  return std::nullopt;
}
}  // namespace

bool is_splat_file_name(const std::filesystem::path& path) { return format_by_name(path).has_value(); }

SplatFormat splat_format_of(const std::filesystem::path& path) {
  if (const std::optional<SplatFormat> format = format_by_name(path)) return *format;
  fail_file(path,
            "not a splat file name: use .ply (3DGS), .compressed.ply (SuperSplat), .spz (Niantic) or .sog (PlayCanvas)");
}

std::string splat_format_name(SplatFormat format) {
  switch (format) {
    case SplatFormat::Ply: return "PLY";
    case SplatFormat::CompressedPly: return "compressed PLY";
    case SplatFormat::Spz: return "SPZ";
    case SplatFormat::Sog: return "SOG";
  }
  return "?";
}

SplatCloud read_splats(const std::filesystem::path& path) {
  switch (splat_format_of(path)) {
    case SplatFormat::Spz: return read_spz(path);
    case SplatFormat::Sog: return read_sog(path);
    default: return read_splat_ply(path);  // a PLY says by its properties whether it is compressed
  }
}

void write_splats(const std::filesystem::path& path, const SplatCloud& cloud) {
  switch (splat_format_of(path)) {
    case SplatFormat::Ply: return write_splat_ply(path, cloud);
    case SplatFormat::CompressedPly: return write_compressed_splat_ply(path, cloud);
    case SplatFormat::Spz: return write_spz(path, cloud);
    case SplatFormat::Sog:
      if (lower_name(path) == "meta.json") fail_file(path, "SOG is written as one .sog bundle, not as meta.json and images");
      return write_sog(path, cloud);
  }
}

}  // namespace ii
