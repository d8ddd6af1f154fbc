#include "io/colmap.h"

#include <charconv>
#include <cmath>
#include <limits>
#include <string_view>

#include "common/error.h"
#include "common/files.h"
#include "io/byte_reader.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

struct ModelInfo {
  int id;
  const char* name;
  int params;
};
// COLMAP's model table (ids are what cameras.bin stores).
constexpr ModelInfo kModels[] = {
    {0, "SIMPLE_PINHOLE", 3}, {1, "PINHOLE", 4},           {2, "SIMPLE_RADIAL", 4},
    {3, "RADIAL", 5},         {4, "OPENCV", 8},            {5, "OPENCV_FISHEYE", 8},
    {6, "FULL_OPENCV", 12},   {7, "FOV", 5},               {8, "SIMPLE_RADIAL_FISHEYE", 4},
    {9, "RADIAL_FISHEYE", 5}, {10, "THIN_PRISM_FISHEYE", 12}, {11, "RAD_TAN_THIN_PRISM_FISHEYE", 16}};
constexpr int kMinParams = 3;
constexpr int kMaxSide = 1000000;  // larger than any sensor; catches garbage sizes

const ModelInfo* model_by_id(int id) {
  for (const auto& m : kModels)
    if (m.id == id) return &m;
  return nullptr;
}
const ModelInfo* model_by_name(std::string_view name) {
  for (const auto& m : kModels)
    if (name == m.name) return &m;
  return nullptr;
}

void check_finite(const fs::path& file, double v, const char* what, int64_t id) {
  if (!std::isfinite(v)) fail_file(file, "the {} of entry {} is NaN or infinite", what, id);
}

template <typename T>
void check_size(const fs::path& file, T w, T h, int id) {
  if (w < T(1) || h < T(1) || w > T(kMaxSide) || h > T(kMaxSide))
    fail_file(file, "camera {} has implausible size {}x{}", id, w, h);
}

template <typename Map, typename Key>
void insert_unique(const fs::path& file, Map& map, Key id, typename Map::mapped_type value, const char* what) {
  if (!map.emplace(id, std::move(value)).second) fail_file(file, "duplicate {} id {}", what, id);
}

// ---- binary ----------------------------------------------------------------------------

// Every count in a binary file is checked against the bytes left before anything is
// allocated: each record needs at least `min_record` bytes.
uint64_t read_count(ByteReader& r, size_t min_record, const char* what) {
  const uint64_t n = r.read<uint64_t>(what);
  if (n > r.remaining() / min_record)
    fail_file(r.file(), "{} {} cannot fit in the {} bytes left (truncated or corrupt file)", n, what, r.remaining());
  return n;
}

// Bytes after the last record mean the count in the header was wrong: refuse rather than
// silently drop data.
void expect_end(const ByteReader& r, uint64_t n, const char* what) {
  if (r.remaining() != 0)
    fail_file(r.file(), "{} bytes left over after {} {} (corrupt file or wrong count)", r.remaining(), n, what);
}

std::map<int, ColmapCamera> read_cameras_bin(const fs::path& file) {
  const auto bytes = read_file_bytes(file);
  ByteReader r(bytes.data(), bytes.size(), file);
  std::map<int, ColmapCamera> out;
  const uint64_t n = read_count(r, 4 + 4 + 8 + 8 + 8 * kMinParams, "cameras");
  for (uint64_t i = 0; i < n; ++i) {
    ColmapCamera c;
    c.id = r.read<int32_t>("camera id");
    const int model = r.read<int32_t>("camera model");
    const ModelInfo* m = model_by_id(model);
    if (!m) fail_file(file, "camera {} has unknown model id {}", c.id, model);
    c.model = m->name;
    const uint64_t w = r.read<uint64_t>("width"), h = r.read<uint64_t>("height");
    check_size(file, w, h, c.id);
    c.width = static_cast<int>(w);
    c.height = static_cast<int>(h);
    c.params.resize(m->params);
    for (double& p : c.params) {
      p = r.read<double>("camera parameters");
      check_finite(file, p, "camera parameters", c.id);
    }
    insert_unique(file, out, c.id, std::move(c), "camera");
  }
  expect_end(r, n, "cameras");
  return out;
}

std::map<int, ColmapImage> read_images_bin(const fs::path& file) {
  const auto bytes = read_file_bytes(file);
  ByteReader r(bytes.data(), bytes.size(), file);
  std::map<int, ColmapImage> out;
  const uint64_t n = read_count(r, 4 + 32 + 24 + 4 + 1 + 8, "images");
  for (uint64_t i = 0; i < n; ++i) {
    ColmapImage im;
    im.id = r.read<int32_t>("image id");
    for (int k = 0; k < 4; ++k) im.qvec[k] = r.read<double>("qvec");
    for (int k = 0; k < 3; ++k) im.tvec[k] = r.read<double>("tvec");
    for (int k = 0; k < 4; ++k) check_finite(file, im.qvec[k], "rotation", im.id);
    for (int k = 0; k < 3; ++k) check_finite(file, im.tvec[k], "translation", im.id);
    im.camera_id = r.read<int32_t>("camera id");
    im.name = r.read_cstring("image name");
    if (im.name.empty()) fail_file(file, "image {} has an empty name", im.id);
    const uint64_t points = read_count(r, 24, "2D points");
    im.xys.resize(points);
    im.point3d_ids.resize(points);
    for (uint64_t k = 0; k < points; ++k) {
      im.xys[k].x() = r.read<double>("point x");
      im.xys[k].y() = r.read<double>("point y");
      im.point3d_ids[k] = r.read<int64_t>("point3D id");
    }
    insert_unique(file, out, im.id, std::move(im), "image");
  }
  expect_end(r, n, "images");
  return out;
}

std::map<int64_t, ColmapPoint> read_points_bin(const fs::path& file) {
  const auto bytes = read_file_bytes(file);
  ByteReader r(bytes.data(), bytes.size(), file);
  std::map<int64_t, ColmapPoint> out;
  const uint64_t n = read_count(r, 8 + 24 + 3 + 8 + 8, "points");
  for (uint64_t i = 0; i < n; ++i) {
    ColmapPoint p;
    p.id = r.read<int64_t>("point id");
    for (int k = 0; k < 3; ++k) p.xyz[k] = r.read<double>("point xyz");
    for (int k = 0; k < 3; ++k) check_finite(file, p.xyz[k], "position", p.id);
    for (int k = 0; k < 3; ++k) p.rgb[k] = r.read<uint8_t>("point colour");
    p.error = r.read<double>("point error");
    const uint64_t len = read_count(r, 8, "track entries");
    p.track.resize(len);
    for (auto& t : p.track) {
      t.first = r.read<int32_t>("track image id");
      t.second = r.read<int32_t>("track point index");
    }
    insert_unique(file, out, p.id, std::move(p), "point");
  }
  expect_end(r, n, "points");
  return out;
}

// ---- text ------------------------------------------------------------------------------

std::string_view trim(std::string_view s) {
  const char* ws = " \t\r\v\f";
  const size_t a = s.find_first_not_of(ws);
  if (a == std::string_view::npos) return {};
  return s.substr(a, s.find_last_not_of(ws) - a + 1);
}

// Physical lines, trimmed, with 1-based numbers for messages.
struct TextLines {
  fs::path file;
  std::string text;
  std::vector<std::string_view> lines;

  explicit TextLines(const fs::path& f) : file(f), text(read_file_text(f)) {
    std::string_view all(text);
    while (!all.empty()) {
      const size_t nl = all.find('\n');
      lines.push_back(trim(all.substr(0, nl)));
      if (nl == std::string_view::npos) break;
      all.remove_prefix(nl + 1);
    }
  }
  static bool skippable(std::string_view l) { return l.empty() || l[0] == '#'; }
};

// Whitespace-separated tokens of one line; numbers parse locale-free with from_chars.
class Tokens {
 public:
  Tokens(const fs::path& file, size_t line_no, std::string_view line) : file_(file), line_no_(line_no), rest_(line) {}

  bool done() const { return trim(rest_).empty(); }
  std::string_view rest() const { return trim(rest_); }

  std::string_view next(const char* what) {
    rest_ = rest_.substr(std::min(rest_.size(), rest_.find_first_not_of(" \t")));
    if (rest_.empty()) fail_file(file_, "line {}: missing {}", line_no_, what);
    const size_t end = std::min(rest_.size(), rest_.find_first_of(" \t"));
    const std::string_view tok = rest_.substr(0, end);
    rest_.remove_prefix(end);
    return tok;
  }

  template <typename T>
  T number(const char* what) {
    const std::string_view tok = next(what);
    T v{};
    const auto [ptr, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    if (ec != std::errc() || ptr != tok.data() + tok.size())
      fail_file(file_, "line {}: '{}' is not a valid {}", line_no_, tok, what);
    return v;
  }

  int integer(const char* what) { return number<int>(what); }

 private:
  const fs::path& file_;
  size_t line_no_;
  std::string_view rest_;
};

std::map<int, ColmapCamera> read_cameras_txt(const fs::path& file) {
  const TextLines t(file);
  std::map<int, ColmapCamera> out;
  for (size_t i = 0; i < t.lines.size(); ++i) {
    if (TextLines::skippable(t.lines[i])) continue;
    Tokens tok(file, i + 1, t.lines[i]);
    ColmapCamera c;
    c.id = tok.integer("camera id");
    c.model = std::string(tok.next("camera model"));
    const ModelInfo* m = model_by_name(c.model);
    if (!m) fail_file(file, "line {}: camera {} has unknown model {}", i + 1, c.id, c.model);
    const int64_t w = tok.number<int64_t>("width"), h = tok.number<int64_t>("height");
    check_size(file, w, h, c.id);
    c.width = static_cast<int>(w);
    c.height = static_cast<int>(h);
    while (!tok.done()) c.params.push_back(tok.number<double>("camera parameter"));
    if (static_cast<int>(c.params.size()) != m->params)
      fail_file(file, "line {}: camera {} ({}) has {} parameters, expected {}", i + 1, c.id, c.model, c.params.size(),
                m->params);
    for (double v : c.params) check_finite(file, v, "camera parameters", c.id);
    insert_unique(file, out, c.id, std::move(c), "camera");
  }
  return out;
}

std::map<int, ColmapImage> read_images_txt(const fs::path& file) {
  const TextLines t(file);
  std::map<int, ColmapImage> out;
  for (size_t i = 0; i < t.lines.size(); ++i) {
    if (TextLines::skippable(t.lines[i])) continue;
    Tokens tok(file, i + 1, t.lines[i]);
    ColmapImage im;
    im.id = tok.integer("image id");
    for (int k = 0; k < 4; ++k) im.qvec[k] = tok.number<double>("quaternion component");
    for (int k = 0; k < 3; ++k) im.tvec[k] = tok.number<double>("translation component");
    im.camera_id = tok.integer("camera id");
    // The name is the rest of the line, so names with spaces survive.
    im.name = std::string(tok.rest());
    if (im.name.empty()) fail_file(file, "line {}: missing image name", i + 1);
    for (int k = 0; k < 4; ++k) check_finite(file, im.qvec[k], "rotation", im.id);
    for (int k = 0; k < 3; ++k) check_finite(file, im.tvec[k], "translation", im.id);
    // As in COLMAP, the line right after an image line holds its 2D points (possibly
    // empty); a missing last line means no points.
    if (i + 1 < t.lines.size()) {
      ++i;
      if (!t.lines[i].empty() && t.lines[i][0] == '#')
        fail_file(file, "line {}: expected the 2D points of image {}, found a comment", i + 1, im.id);
      Tokens pts(file, i + 1, t.lines[i]);
      while (!pts.done()) {
        const double x = pts.number<double>("point x");
        const double y = pts.number<double>("point y");
        im.xys.emplace_back(x, y);
        im.point3d_ids.push_back(pts.number<int64_t>("point3D id"));
      }
    }
    insert_unique(file, out, im.id, std::move(im), "image");
  }
  return out;
}

std::map<int64_t, ColmapPoint> read_points_txt(const fs::path& file) {
  const TextLines t(file);
  std::map<int64_t, ColmapPoint> out;
  for (size_t i = 0; i < t.lines.size(); ++i) {
    if (TextLines::skippable(t.lines[i])) continue;
    Tokens tok(file, i + 1, t.lines[i]);
    ColmapPoint p;
    p.id = tok.number<int64_t>("point id");
    for (int k = 0; k < 3; ++k) p.xyz[k] = tok.number<double>("point coordinate");
    for (int k = 0; k < 3; ++k) {
      const int c = tok.integer("colour");
      if (c < 0 || c > 255) fail_file(file, "line {}: colour {} is outside 0..255", i + 1, c);
      p.rgb[k] = static_cast<uint8_t>(c);
    }
    p.error = tok.number<double>("point error");
    for (int k = 0; k < 3; ++k) check_finite(file, p.xyz[k], "position", p.id);
    while (!tok.done()) {
      const int image = tok.integer("track image id");
      p.track.emplace_back(image, tok.integer("track point index"));
    }
    insert_unique(file, out, p.id, std::move(p), "point");
  }
  return out;
}

// ---- writing ---------------------------------------------------------------------------

template <typename T>
void put(std::string& out, T v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

// Refuse what would not read back the same (or would not read back at all).
void validate_for_writing(const fs::path& dir, const ColmapModel& model, bool binary) {
  for (const auto& [id, c] : model.cameras) {
    const ModelInfo* m = model_by_name(c.model);
    if (!m) fail_file(dir, "camera {}: unknown camera model '{}'", id, c.model);
    if (static_cast<int>(c.params.size()) != m->params)
      fail_file(dir, "camera {}: model {} needs {} parameters, got {}", id, c.model, m->params, c.params.size());
    check_size(dir, c.width, c.height, id);
    for (double p : c.params) check_finite(dir, p, "camera parameters", id);
  }
  for (const auto& [id, im] : model.images) {
    if (im.xys.size() != im.point3d_ids.size())
      fail_file(dir, "image {}: {} 2D points but {} point3D ids", id, im.xys.size(), im.point3d_ids.size());
    if (!im.qvec.allFinite() || !im.tvec.allFinite()) fail_file(dir, "image {}: pose is NaN or infinite", id);
    const bool bad_char = im.name.find_first_of(std::string_view("\n\r\0", 3)) != std::string::npos;
    const bool untrimmed = !binary && trim(im.name) != im.name;
    if (im.name.empty() || bad_char || untrimmed)
      fail_file(dir, "image {}: name '{}' cannot be stored in a COLMAP file", id, im.name);
  }
  for (const auto& [id, p] : model.points)
    if (!p.xyz.allFinite()) fail_file(dir, "point {}: position is NaN or infinite", id);
}

}  // namespace

int colmap_model_params(const std::string& model) {
  const ModelInfo* m = model_by_name(model);
  return m ? m->params : -1;
}

int colmap_model_id(const std::string& model) {
  const ModelInfo* m = model_by_name(model);
  return m ? m->id : -1;
}

std::map<int, ColmapCamera> read_colmap_cameras(const fs::path& file) {
  return file.extension() == ".txt" ? read_cameras_txt(file) : read_cameras_bin(file);
}

ColmapModel read_colmap_model(const fs::path& dir) {
  // Per file, binary wins over text (COLMAP writes binary; text is the export).
  auto pick = [&](const char* stem) -> fs::path {
    for (const char* ext : {".bin", ".txt"}) {
      const fs::path p = dir / (std::string(stem) + ext);
      if (fs::exists(p)) return p;
    }
    return {};
  };
  const fs::path cameras = pick("cameras"), images = pick("images"), points = pick("points3D");
  if (cameras.empty()) fail_file(dir, "no COLMAP model here (cameras.bin or cameras.txt)");
  ColmapModel m;
  m.cameras = read_colmap_cameras(cameras);
  if (!images.empty())
    m.images = images.extension() == ".bin" ? read_images_bin(images) : read_images_txt(images);
  if (!points.empty())
    m.points = points.extension() == ".bin" ? read_points_bin(points) : read_points_txt(points);
  return m;
}

void write_colmap_model(const fs::path& dir, const ColmapModel& model, bool binary) {
  validate_for_writing(dir, model, binary);
  fs::create_directories(dir);
  if (binary) {
    std::string cams, ims, pts;
    put<uint64_t>(cams, model.cameras.size());
    for (const auto& [id, c] : model.cameras) {
      put<int32_t>(cams, id);
      put<int32_t>(cams, colmap_model_id(c.model));
      put<uint64_t>(cams, static_cast<uint64_t>(c.width));
      put<uint64_t>(cams, static_cast<uint64_t>(c.height));
      for (double p : c.params) put<double>(cams, p);
    }
    put<uint64_t>(ims, model.images.size());
    for (const auto& [id, im] : model.images) {
      put<int32_t>(ims, id);
      for (int k = 0; k < 4; ++k) put<double>(ims, im.qvec[k]);
      for (int k = 0; k < 3; ++k) put<double>(ims, im.tvec[k]);
      put<int32_t>(ims, im.camera_id);
      ims += im.name;
      ims.push_back('\0');
      put<uint64_t>(ims, im.xys.size());
      for (size_t k = 0; k < im.xys.size(); ++k) {
        put<double>(ims, im.xys[k].x());
        put<double>(ims, im.xys[k].y());
        put<int64_t>(ims, im.point3d_ids[k]);
      }
    }
    put<uint64_t>(pts, model.points.size());
    for (const auto& [id, p] : model.points) {
      put<int64_t>(pts, id);
      for (int k = 0; k < 3; ++k) put<double>(pts, p.xyz[k]);
      for (int k = 0; k < 3; ++k) put<uint8_t>(pts, p.rgb[k]);
      put<double>(pts, p.error);
      put<uint64_t>(pts, p.track.size());
      for (const auto& t : p.track) {
        put<int32_t>(pts, t.first);
        put<int32_t>(pts, t.second);
      }
    }
    write_file_atomic(dir / "cameras.bin", cams);
    write_file_atomic(dir / "images.bin", ims);
    write_file_atomic(dir / "points3D.bin", pts);
    return;
  }
  // fmt's "{}" prints a double in its shortest form that parses back to the same bits.
  std::string cams = fmt::format(
      "# Camera list with one line of data per camera:\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
      "# Number of cameras: {}\n",
      model.cameras.size());
  for (const auto& [id, c] : model.cameras) {
    cams += fmt::format("{} {} {} {}", id, c.model, c.width, c.height);
    for (double p : c.params) cams += fmt::format(" {}", p);
    cams += "\n";
  }
  std::string ims = fmt::format(
      "# Image list with two lines of data per image:\n"
      "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
      "# Number of images: {}\n",
      model.images.size());
  for (const auto& [id, im] : model.images) {
    ims += fmt::format("{} {} {} {} {} {} {} {} {} {}\n", id, im.qvec[0], im.qvec[1], im.qvec[2], im.qvec[3],
                       im.tvec[0], im.tvec[1], im.tvec[2], im.camera_id, im.name);
    for (size_t k = 0; k < im.xys.size(); ++k)
      ims += fmt::format("{}{} {} {}", k ? " " : "", im.xys[k].x(), im.xys[k].y(), im.point3d_ids[k]);
    ims += "\n";
  }
  std::string pts = fmt::format(
      "# 3D point list with one line of data per point:\n"
      "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n# Number of points: {}\n",
      model.points.size());
  for (const auto& [id, p] : model.points) {
    pts += fmt::format("{} {} {} {} {} {} {} {}", id, p.xyz[0], p.xyz[1], p.xyz[2], p.rgb[0], p.rgb[1], p.rgb[2],
                       p.error);
    for (const auto& t : p.track) pts += fmt::format(" {} {}", t.first, t.second);
    pts += "\n";
  }
  write_file_atomic(dir / "cameras.txt", cams);
  write_file_atomic(dir / "images.txt", ims);
  write_file_atomic(dir / "points3D.txt", pts);
}

}  // namespace ii
