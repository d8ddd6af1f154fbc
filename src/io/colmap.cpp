#include "io/colmap.h"

#include <cmath>
#include <fstream>
#include <sstream>

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
constexpr ModelInfo kModels[] = {{0, "SIMPLE_PINHOLE", 3}, {1, "PINHOLE", 4},          {2, "SIMPLE_RADIAL", 4},
                                 {3, "RADIAL", 5},         {4, "OPENCV", 8},           {5, "OPENCV_FISHEYE", 8},
                                 {6, "FULL_OPENCV", 12},   {7, "FOV", 5},              {8, "SIMPLE_RADIAL_FISHEYE", 4},
                                 {9, "RADIAL_FISHEYE", 5}, {10, "THIN_PRISM_FISHEYE", 12}};

const ModelInfo* model_by_id(int id) {
  for (const auto& m : kModels)
    if (m.id == id) return &m;
  return nullptr;
}
const ModelInfo* model_by_name(const std::string& name) {
  for (const auto& m : kModels)
    if (name == m.name) return &m;
  return nullptr;
}

// Every count in a binary file is checked against the bytes left before anything is
// allocated: a record needs at least `min_record` bytes.
uint64_t read_count(ByteReader& r, size_t min_record, const char* what) {
  const uint64_t n = r.read<uint64_t>(what);
  if (min_record > 0 && n > r.remaining() / min_record)
    fail_file(r.file(), "{} {} cannot fit in the {} bytes left (truncated or corrupt file)", n, what, r.remaining());
  return n;
}

void check_finite(const fs::path& file, double v, const char* what, int id) {
  if (!std::isfinite(v)) fail_file(file, "{} of entry {} is NaN or infinite", what, id);
}

std::map<int, ColmapCamera> read_cameras_bin(const fs::path& file) {
  const auto bytes = read_file_bytes(file);
  ByteReader r(bytes.data(), bytes.size(), file);
  std::map<int, ColmapCamera> out;
  const uint64_t n = read_count(r, 24, "cameras");
  for (uint64_t i = 0; i < n; ++i) {
    ColmapCamera c;
    c.id = r.read<int32_t>("camera id");
    const int model = r.read<int32_t>("camera model");
    const ModelInfo* m = model_by_id(model);
    if (!m) fail_file(file, "camera {} has unknown model id {}", c.id, model);
    c.model = m->name;
    const uint64_t w = r.read<uint64_t>("width"), h = r.read<uint64_t>("height");
    if (w == 0 || h == 0 || w > 1000000 || h > 1000000) fail_file(file, "camera {} has implausible size {}x{}", c.id, w, h);
    c.width = static_cast<int>(w);
    c.height = static_cast<int>(h);
    c.params.resize(m->params);
    for (double& p : c.params) {
      p = r.read<double>("camera parameter");
      check_finite(file, p, "a camera parameter", c.id);
    }
    out[c.id] = c;
  }
  return out;
}

std::map<int, ColmapImage> read_images_bin(const fs::path& file) {
  const auto bytes = read_file_bytes(file);
  ByteReader r(bytes.data(), bytes.size(), file);
  std::map<int, ColmapImage> out;
  const uint64_t n = read_count(r, 4 + 56 + 4 + 1 + 8, "images");
  for (uint64_t i = 0; i < n; ++i) {
    ColmapImage im;
    im.id = r.read<int32_t>("image id");
    for (int k = 0; k < 4; ++k) im.qvec[k] = r.read<double>("qvec");
    for (int k = 0; k < 3; ++k) im.tvec[k] = r.read<double>("tvec");
    for (int k = 0; k < 4; ++k) check_finite(file, im.qvec[k], "the rotation", im.id);
    for (int k = 0; k < 3; ++k) check_finite(file, im.tvec[k], "the translation", im.id);
    im.camera_id = r.read<int32_t>("camera id");
    im.name = r.read_cstring("image name");
    const uint64_t points = read_count(r, 24, "2D points");
    im.xys.resize(points);
    im.point3d_ids.resize(points);
    for (uint64_t k = 0; k < points; ++k) {
      im.xys[k].x() = r.read<double>("point x");
      im.xys[k].y() = r.read<double>("point y");
      im.point3d_ids[k] = r.read<int64_t>("point3D id");
    }
    out[im.id] = std::move(im);
  }
  return out;
}

std::map<int64_t, ColmapPoint> read_points_bin(const fs::path& file) {
  const auto bytes = read_file_bytes(file);
  ByteReader r(bytes.data(), bytes.size(), file);
  std::map<int64_t, ColmapPoint> out;
  const uint64_t n = read_count(r, 8 + 24 + 3 + 8 + 8, "points");
  for (uint64_t i = 0; i < n; ++i) {
    ColmapPoint p;
    p.id = static_cast<int64_t>(r.read<uint64_t>("point id"));
    for (int k = 0; k < 3; ++k) p.xyz[k] = r.read<double>("point xyz");
    for (int k = 0; k < 3; ++k) p.rgb[k] = r.read<uint8_t>("point colour");
    p.error = r.read<double>("point error");
    const uint64_t len = read_count(r, 8, "track entries");
    p.track.resize(len);
    for (auto& t : p.track) {
      t.first = r.read<int32_t>("track image id");
      t.second = r.read<int32_t>("track point index");
    }
    out[p.id] = std::move(p);
  }
  return out;
}

// Non-comment, non-empty lines of a text file.
std::vector<std::string> data_lines(const fs::path& file) {
  std::istringstream in(read_file_text(file));
  std::vector<std::string> lines;
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') {
      // images.txt: an image with no points has an empty second line; keep it.
      if (line.empty()) lines.push_back(line);
      continue;
    }
    lines.push_back(line);
  }
  return lines;
}

std::map<int, ColmapCamera> read_cameras_txt(const fs::path& file) {
  std::map<int, ColmapCamera> out;
  int line_no = 0;
  for (const std::string& line : data_lines(file)) {
    ++line_no;
    if (line.empty()) continue;
    std::istringstream ls(line);
    ColmapCamera c;
    if (!(ls >> c.id >> c.model >> c.width >> c.height)) fail_file(file, "malformed camera line '{}'", line);
    const ModelInfo* m = model_by_name(c.model);
    if (!m) fail_file(file, "camera {} has unknown model {}", c.id, c.model);
    double p;
    while (ls >> p) c.params.push_back(p);
    if (static_cast<int>(c.params.size()) != m->params)
      fail_file(file, "camera {} ({}) has {} parameters, expected {}", c.id, c.model, c.params.size(), m->params);
    for (double v : c.params) check_finite(file, v, "a camera parameter", c.id);
    out[c.id] = c;
  }
  return out;
}

std::map<int, ColmapImage> read_images_txt(const fs::path& file) {
  std::map<int, ColmapImage> out;
  const auto lines = data_lines(file);
  for (size_t i = 0; i < lines.size(); ++i) {
    if (lines[i].empty()) continue;
    std::istringstream ls(lines[i]);
    ColmapImage im;
    if (!(ls >> im.id >> im.qvec[0] >> im.qvec[1] >> im.qvec[2] >> im.qvec[3] >> im.tvec[0] >> im.tvec[1] >> im.tvec[2] >>
          im.camera_id) ||
        !(ls >> std::ws) || !std::getline(ls, im.name) || im.name.empty())
      fail_file(file, "malformed image line '{}'", lines[i]);
    for (int k = 0; k < 4; ++k) check_finite(file, im.qvec[k], "the rotation", im.id);
    for (int k = 0; k < 3; ++k) check_finite(file, im.tvec[k], "the translation", im.id);
    if (i + 1 < lines.size()) {
      std::istringstream ps(lines[++i]);
      double x, y;
      int64_t id;
      while (ps >> x >> y >> id) {
        im.xys.emplace_back(x, y);
        im.point3d_ids.push_back(id);
      }
    }
    out[im.id] = std::move(im);
  }
  return out;
}

std::map<int64_t, ColmapPoint> read_points_txt(const fs::path& file) {
  std::map<int64_t, ColmapPoint> out;
  for (const std::string& line : data_lines(file)) {
    if (line.empty()) continue;
    std::istringstream ls(line);
    ColmapPoint p;
    int r, g, b;
    if (!(ls >> p.id >> p.xyz[0] >> p.xyz[1] >> p.xyz[2] >> r >> g >> b >> p.error))
      fail_file(file, "malformed point line '{}'", line);
    p.rgb = {static_cast<uint8_t>(r), static_cast<uint8_t>(g), static_cast<uint8_t>(b)};
    int im, idx;
    while (ls >> im >> idx) p.track.emplace_back(im, idx);
    out[p.id] = std::move(p);
  }
  return out;
}

template <typename T>
void put(std::string& out, T v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

}  // namespace

int colmap_model_params(const std::string& model) {
  const ModelInfo* m = model_by_name(model);
  return m ? m->params : -1;
}

std::map<int, ColmapCamera> read_colmap_cameras(const fs::path& file) {
  return file.extension() == ".txt" ? read_cameras_txt(file) : read_cameras_bin(file);
}

ColmapModel read_colmap_model(const fs::path& dir) {
  ColmapModel m;
  const bool binary = fs::exists(dir / "cameras.bin");
  if (!binary && !fs::exists(dir / "cameras.txt"))
    fail_file(dir, "no COLMAP model here (cameras.bin or cameras.txt)");
  if (binary) {
    m.cameras = read_cameras_bin(dir / "cameras.bin");
    if (fs::exists(dir / "images.bin")) m.images = read_images_bin(dir / "images.bin");
    if (fs::exists(dir / "points3D.bin")) m.points = read_points_bin(dir / "points3D.bin");
  } else {
    m.cameras = read_cameras_txt(dir / "cameras.txt");
    if (fs::exists(dir / "images.txt")) m.images = read_images_txt(dir / "images.txt");
    if (fs::exists(dir / "points3D.txt")) m.points = read_points_txt(dir / "points3D.txt");
  }
  return m;
}

void write_colmap_model(const fs::path& dir, const ColmapModel& model, bool binary) {
  for (const auto& [id, c] : model.cameras)
    if (!model_by_name(c.model) || static_cast<int>(c.params.size()) != colmap_model_params(c.model))
      fail_file(dir, "camera {} has model {} with {} parameters", id, c.model, c.params.size());
  if (binary) {
    std::string cams, ims, pts;
    put<uint64_t>(cams, model.cameras.size());
    for (const auto& [id, c] : model.cameras) {
      put<int32_t>(cams, id);
      put<int32_t>(cams, model_by_name(c.model)->id);
      put<uint64_t>(cams, c.width);
      put<uint64_t>(cams, c.height);
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
      put<uint64_t>(pts, static_cast<uint64_t>(id));
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
  // Text: 17 significant digits keep doubles exact through the round trip.
  std::string cams = "# Camera list: CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n", ims, pts;
  for (const auto& [id, c] : model.cameras) {
    cams += fmt::format("{} {} {} {}", id, c.model, c.width, c.height);
    for (double p : c.params) cams += fmt::format(" {:.17g}", p);
    cams += "\n";
  }
  ims = "# IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n# POINTS2D[] as (X, Y, POINT3D_ID)\n";
  for (const auto& [id, im] : model.images) {
    ims += fmt::format("{} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {} {}\n", id, im.qvec[0], im.qvec[1],
                       im.qvec[2], im.qvec[3], im.tvec[0], im.tvec[1], im.tvec[2], im.camera_id, im.name);
    for (size_t k = 0; k < im.xys.size(); ++k)
      ims += fmt::format("{}{:.17g} {:.17g} {}", k ? " " : "", im.xys[k].x(), im.xys[k].y(), im.point3d_ids[k]);
    ims += "\n";
  }
  pts = "# POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n";
  for (const auto& [id, p] : model.points) {
    pts += fmt::format("{} {:.17g} {:.17g} {:.17g} {} {} {} {:.17g}", id, p.xyz[0], p.xyz[1], p.xyz[2], p.rgb[0], p.rgb[1],
                       p.rgb[2], p.error);
    for (const auto& t : p.track) pts += fmt::format(" {} {}", t.first, t.second);
    pts += "\n";
  }
  write_file_atomic(dir / "cameras.txt", cams);
  write_file_atomic(dir / "images.txt", ims);
  write_file_atomic(dir / "points3D.txt", pts);
}

}  // namespace ii
