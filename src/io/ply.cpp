#include "io/ply.h"

#include <cmath>
#include <cstring>
#include <map>
#include <sstream>

#include <fmt/format.h>

#include "common/error.h"
#include "common/files.h"
#include "io/byte_reader.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

struct Property {
  std::string name, type;
  size_t size = 0;
};

struct Element {
  std::string name;
  uint64_t count = 0;
  std::vector<Property> properties;
  size_t row_size() const {
    size_t s = 0;
    for (const auto& p : properties) s += p.size;
    return s;
  }
  int index(const std::string& n) const {
    for (size_t i = 0; i < properties.size(); ++i)
      if (properties[i].name == n) return static_cast<int>(i);
    return -1;
  }
};

size_t type_size(const std::string& t) {
  static const std::map<std::string, size_t> sizes = {
      {"char", 1}, {"uchar", 1}, {"int8", 1}, {"uint8", 1}, {"short", 2}, {"ushort", 2}, {"int16", 2}, {"uint16", 2},
      {"int", 4},  {"uint", 4},  {"int32", 4}, {"uint32", 4}, {"float", 4}, {"float32", 4}, {"double", 8}, {"float64", 8}};
  auto it = sizes.find(t);
  return it == sizes.end() ? 0 : it->second;
}

double load_binary(const uint8_t* p, const std::string& t) {
  auto get = [&](auto v) {
    std::memcpy(&v, p, sizeof(v));
    return static_cast<double>(v);
  };
  if (t == "float" || t == "float32") return get(float{});
  if (t == "double" || t == "float64") return get(double{});
  if (t == "uchar" || t == "uint8") return get(uint8_t{});
  if (t == "char" || t == "int8") return get(int8_t{});
  if (t == "short" || t == "int16") return get(int16_t{});
  if (t == "ushort" || t == "uint16") return get(uint16_t{});
  if (t == "int" || t == "int32") return get(int32_t{});
  return get(uint32_t{});
}

struct Header {
  bool ascii = false;
  std::vector<Element> elements;
  size_t body_offset = 0;
};

Header parse_header(const std::vector<uint8_t>& bytes, const fs::path& path) {
  if (bytes.size() < 4 || std::memcmp(bytes.data(), "ply\n", 4) != 0)
    fail_file(path, "not a PLY file (missing 'ply' magic)");
  const std::string text(reinterpret_cast<const char*>(bytes.data()), std::min<size_t>(bytes.size(), 1 << 20));
  const size_t end = text.find("end_header\n");
  if (end == std::string::npos) fail_file(path, "PLY header has no end_header line");
  Header h;
  h.body_offset = end + 11;
  std::istringstream in(text.substr(4, end - 4));
  std::string line;
  bool have_format = false;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ls(line);
    std::string word;
    ls >> word;
    if (word.empty() || word == "comment" || word == "obj_info") continue;
    if (word == "format") {
      std::string fmt_name;
      ls >> fmt_name;
      if (fmt_name == "ascii") h.ascii = true;
      else if (fmt_name != "binary_little_endian")
        fail_file(path, "unsupported PLY format '{}' (binary_little_endian or ascii)", fmt_name);
      have_format = true;
    } else if (word == "element") {
      Element e;
      if (!(ls >> e.name >> e.count)) fail_file(path, "malformed PLY element line '{}'", line);
      h.elements.push_back(e);
    } else if (word == "property") {
      if (h.elements.empty()) fail_file(path, "PLY property before any element");
      Property p;
      ls >> p.type;
      if (p.type == "list") fail_file(path, "list properties are not supported in splat files (element {})", h.elements.back().name);
      ls >> p.name;
      p.size = type_size(p.type);
      if (p.size == 0) fail_file(path, "unknown PLY property type '{}'", p.type);
      h.elements.back().properties.push_back(p);
    } else {
      fail_file(path, "unexpected PLY header line '{}'", line);
    }
  }
  if (!have_format) fail_file(path, "PLY header has no format line");
  return h;
}

// Column-major float values of one element.
using Columns = std::vector<std::vector<float>>;

Columns read_element(const Element& e, ByteReader& r, std::istringstream* ascii, const fs::path& path) {
  Columns cols(e.properties.size());
  const size_t row = e.row_size();
  if (!ascii && (row == 0 || e.count > r.remaining() / row))
    fail_file(path, "truncated PLY body: {} {} rows of {} bytes do not fit in the {} bytes left", e.count, e.name, row, r.remaining());
  if (ascii && e.count > (1ULL << 32)) fail_file(path, "implausible element count {}", e.count);
  for (auto& c : cols) c.resize(e.count);
  for (uint64_t i = 0; i < e.count; ++i) {
    if (ascii) {
      for (size_t k = 0; k < cols.size(); ++k) {
        double v;
        if (!(*ascii >> v)) fail_file(path, "truncated or malformed ASCII PLY body at {} row {}", e.name, i);
        cols[k][i] = static_cast<float>(v);
      }
    } else {
      const uint8_t* p = r.current();
      size_t off = 0;
      for (size_t k = 0; k < cols.size(); ++k) {
        cols[k][i] = static_cast<float>(load_binary(p + off, e.properties[k].type));
        off += e.properties[k].size;
      }
      r.skip(row, "row");
    }
  }
  return cols;
}

const std::vector<float>& column(const Element& e, const Columns& cols, const std::string& name, const fs::path& path) {
  const int i = e.index(name);
  if (i < 0) fail_file(path, "{} element has no '{}' property", e.name, name);
  return cols[i];
}

float unorm(uint32_t v, int bits) { return static_cast<float>(v & ((1u << bits) - 1)) / static_cast<float>((1u << bits) - 1); }

}  // namespace

SplatCloud read_splat_ply(const fs::path& path) {
  const std::vector<uint8_t> bytes = read_file_bytes(path);
  const Header h = parse_header(bytes, path);
  ByteReader r(bytes.data(), bytes.size(), path);
  r.seek(h.body_offset, "PLY body");
  std::istringstream ascii_body;
  if (h.ascii) ascii_body.str(std::string(bytes.begin() + h.body_offset, bytes.end()));

  const Element* vertex = nullptr;
  const Element* chunk = nullptr;
  const Element* sh = nullptr;
  std::map<std::string, Columns> columns;
  std::map<std::string, size_t> offsets;
  for (const Element& e : h.elements) {
    offsets[e.name] = r.position();
    columns[e.name] = read_element(e, r, h.ascii ? &ascii_body : nullptr, path);
    if (e.name == "vertex") vertex = &e;
    if (e.name == "chunk") chunk = &e;
    if (e.name == "sh") sh = &e;
  }
  if (!vertex) fail_file(path, "PLY file has no vertex element");
  const Columns& vc = columns.at("vertex");
  const size_t n = vertex->count;

  if (chunk && vertex->index("packed_position") >= 0) {
    if (h.ascii) fail_file(path, "compressed PLY must be binary");
    const Columns& cc = columns.at("chunk");
    if (chunk->count * 256 < n) fail_file(path, "compressed PLY has {} chunks for {} splats (256 per chunk)", chunk->count, n);
    auto ccol = [&](const char* name) -> const std::vector<float>& { return column(*chunk, cc, name, path); };
    const char* packed_names[] = {"packed_position", "packed_rotation", "packed_scale", "packed_color"};
    int packed_index[4];
    for (int k = 0; k < 4; ++k) {
      packed_index[k] = vertex->index(packed_names[k]);
      if (packed_index[k] < 0) fail_file(path, "compressed PLY vertex has no '{}' property", packed_names[k]);
      if (vertex->properties[packed_index[k]].type != "uint" && vertex->properties[packed_index[k]].type != "uint32")
        fail_file(path, "compressed PLY property '{}' must be uint32", packed_names[k]);
    }
    const bool colour_range = chunk->index("min_r") >= 0;
    const size_t row = vertex->row_size();
    SplatCloud c;
    c.means.resize(n * 3);
    c.normals.assign(n * 3, 0.f);
    c.sh_dc.resize(n * 3);
    c.opacity_logit.resize(n);
    c.log_scales.resize(n * 3);
    c.rotations.resize(n * 4);
    const float norm = static_cast<float>(1.0 / (std::sqrt(2.0) * 0.5));
    constexpr float kSh0 = 0.28209479177387814f;
    for (size_t i = 0; i < n; ++i) {
      const size_t ci = i / 256;
      uint32_t packed[4];
      for (int k = 0; k < 4; ++k) {
        size_t off = 0;
        for (int q = 0; q < packed_index[k]; ++q) off += vertex->properties[q].size;
        std::memcpy(&packed[k], bytes.data() + offsets["vertex"] + i * row + off, 4);
      }
      auto lerp = [&](const char* lo, const char* hi, float t) { return ccol(lo)[ci] * (1 - t) + ccol(hi)[ci] * t; };
      // position / scale: 11 / 10 / 11 bits
      c.means[i * 3 + 0] = lerp("min_x", "max_x", unorm(packed[0] >> 21, 11));
      c.means[i * 3 + 1] = lerp("min_y", "max_y", unorm(packed[0] >> 11, 10));
      c.means[i * 3 + 2] = lerp("min_z", "max_z", unorm(packed[0], 11));
      c.log_scales[i * 3 + 0] = lerp("min_scale_x", "max_scale_x", unorm(packed[2] >> 21, 11));
      c.log_scales[i * 3 + 1] = lerp("min_scale_y", "max_scale_y", unorm(packed[2] >> 11, 10));
      c.log_scales[i * 3 + 2] = lerp("min_scale_z", "max_scale_z", unorm(packed[2], 11));
      // rotation: the largest of rot_0..3 is dropped (2-bit index), the others stored in
      // order as 10-bit values in [-1/sqrt2, 1/sqrt2]; the dropped one follows from |q| = 1.
      const float a = (unorm(packed[1] >> 20, 10) - 0.5f) * norm;
      const float b = (unorm(packed[1] >> 10, 10) - 0.5f) * norm;
      const float d = (unorm(packed[1], 10) - 0.5f) * norm;
      const float m = std::sqrt(std::max(0.f, 1.f - (a * a + b * b + d * d)));
      const uint32_t largest = packed[1] >> 30;
      float q[4];
      int src = 0;
      const float others[3] = {a, b, d};
      for (uint32_t k = 0; k < 4; ++k) q[k] = (k == largest) ? m : others[src++];
      std::memcpy(&c.rotations[i * 4], q, sizeof(q));
      // colour: 8 bits per channel within the chunk's colour range; opacity 8 bits, activated
      const float rgb[3] = {unorm(packed[3] >> 24, 8), unorm(packed[3] >> 16, 8), unorm(packed[3] >> 8, 8)};
      const char* lo[3] = {"min_r", "min_g", "min_b"};
      const char* hi[3] = {"max_r", "max_g", "max_b"};
      for (int k = 0; k < 3; ++k) {
        const float colour = colour_range ? lerp(lo[k], hi[k], rgb[k]) : rgb[k];
        c.sh_dc[i * 3 + k] = (colour - 0.5f) / kSh0;
      }
      const float alpha = std::clamp(unorm(packed[3], 8), 1e-6f, 1.f - 1e-6f);
      c.opacity_logit[i] = -std::log(1.f / alpha - 1.f);
    }
    if (sh) {
      const Columns& sc = columns.at("sh");
      if (sh->count != n) fail_file(path, "sh element has {} rows for {} splats", sh->count, n);
      const size_t k = sh->properties.size();
      if (k % 3 != 0) fail_file(path, "sh element has {} coefficients, not a multiple of 3", k);
      c.sh_rest_per_channel = static_cast<int>(k / 3);
      c.sh_rest.resize(n * k);
      for (size_t i = 0; i < n; ++i)
        for (size_t j = 0; j < k; ++j) c.sh_rest[i * k + j] = (sc[j][i] / 256.f - 0.5f) * 8.f;
    }
    return c;
  }

  auto get = [&](const std::string& name) -> const std::vector<float>& { return column(*vertex, vc, name, path); };
  SplatCloud c;
  c.means.resize(n * 3);
  c.normals.assign(n * 3, 0.f);
  c.sh_dc.resize(n * 3);
  c.opacity_logit = get("opacity");
  c.log_scales.resize(n * 3);
  c.rotations.resize(n * 4);
  const bool has_normals = vertex->index("nx") >= 0;
  for (int a = 0; a < 3; ++a) {
    const auto& m = get(std::string(1, "xyz"[a]));
    const auto& dc = get(fmt::format("f_dc_{}", a));
    const auto& s = get(fmt::format("scale_{}", a));
    for (size_t i = 0; i < n; ++i) {
      c.means[i * 3 + a] = m[i];
      c.sh_dc[i * 3 + a] = dc[i];
      c.log_scales[i * 3 + a] = s[i];
    }
    if (has_normals) {
      const auto& nn = get(std::string("n") + "xyz"[a]);
      for (size_t i = 0; i < n; ++i) c.normals[i * 3 + a] = nn[i];
    }
  }
  for (int a = 0; a < 4; ++a) {
    const auto& q = get(fmt::format("rot_{}", a));
    for (size_t i = 0; i < n; ++i) c.rotations[i * 4 + a] = q[i];
  }
  int rest = 0;
  while (vertex->index(fmt::format("f_rest_{}", rest)) >= 0) ++rest;
  if (rest % 3 != 0) fail_file(path, "{} f_rest properties is not a multiple of 3", rest);
  c.sh_rest_per_channel = rest / 3;
  c.sh_rest.resize(n * rest);
  for (int j = 0; j < rest; ++j) {
    const auto& col = get(fmt::format("f_rest_{}", j));
    for (size_t i = 0; i < n; ++i) c.sh_rest[i * rest + j] = col[i];
  }
  return c;
}

void write_splat_ply(const fs::path& path, const SplatCloud& c) {
  const size_t n = c.size();
  const int rest = c.sh_rest_per_channel * 3;
  if (c.means.size() != n * 3 || c.sh_dc.size() != n * 3 || c.log_scales.size() != n * 3 ||
      c.rotations.size() != n * 4 || c.sh_rest.size() != n * rest || (!c.normals.empty() && c.normals.size() != n * 3))
    fail_file(path, "splat cloud arrays do not all describe {} splats", n);
  std::string header = fmt::format("ply\nformat binary_little_endian 1.0\ncomment written by instainpaint\nelement vertex {}\n", n);
  std::vector<std::string> props = {"x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"};
  for (int j = 0; j < rest; ++j) props.push_back(fmt::format("f_rest_{}", j));
  for (const char* p : {"opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"}) props.push_back(p);
  for (const auto& p : props) header += "property float " + p + "\n";
  header += "end_header\n";
  std::string out = header;
  const size_t row = props.size();
  std::vector<float> values(n * row);
  for (size_t i = 0; i < n; ++i) {
    float* v = &values[i * row];
    for (int a = 0; a < 3; ++a) {
      v[a] = c.means[i * 3 + a];
      v[3 + a] = c.normals.empty() ? 0.f : c.normals[i * 3 + a];
      v[6 + a] = c.sh_dc[i * 3 + a];
    }
    for (int j = 0; j < rest; ++j) v[9 + j] = c.sh_rest[i * rest + j];
    v[9 + rest] = c.opacity_logit[i];
    for (int a = 0; a < 3; ++a) v[10 + rest + a] = c.log_scales[i * 3 + a];
    for (int a = 0; a < 4; ++a) v[13 + rest + a] = c.rotations[i * 4 + a];
  }
  out.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(float));
  write_file_atomic(path, out);
}

}  // namespace ii
