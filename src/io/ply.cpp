#include "io/ply.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <optional>
#include <string_view>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "common/error.h"
#include "common/files.h"
#include "common/parallel.h"
#include "io/byte_reader.h"
#include "io/splat_quantize.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

enum class Type { I8, U8, I16, U16, I32, U32, F32, F64 };

std::optional<Type> parse_type(const std::string& t) {
  if (t == "char" || t == "int8") return Type::I8;
  if (t == "uchar" || t == "uint8") return Type::U8;
  if (t == "short" || t == "int16") return Type::I16;
  if (t == "ushort" || t == "uint16") return Type::U16;
  if (t == "int" || t == "int32") return Type::I32;
  if (t == "uint" || t == "uint32") return Type::U32;
  if (t == "float" || t == "float32") return Type::F32;
  if (t == "double" || t == "float64") return Type::F64;
  return std::nullopt;
}

size_t type_size(Type t) {
  switch (t) {
    case Type::I8: case Type::U8: return 1;
    case Type::I16: case Type::U16: return 2;
    case Type::I32: case Type::U32: case Type::F32: return 4;
    case Type::F64: return 8;
  }
  return 0;
}

double load(const uint8_t* p, Type t) {
  auto get = [p](auto v) {
    std::memcpy(&v, p, sizeof(v));
    return static_cast<double>(v);
  };
  switch (t) {
    case Type::I8: return get(int8_t{});
    case Type::U8: return get(uint8_t{});
    case Type::I16: return get(int16_t{});
    case Type::U16: return get(uint16_t{});
    case Type::I32: return get(int32_t{});
    case Type::U32: return get(uint32_t{});
    case Type::F32: return get(float{});
    case Type::F64: return get(double{});
  }
  return 0;
}

struct Property {
  std::string name, type_name;
  Type type = Type::F32;        // the value type (the item type for lists)
  bool is_list = false;
  Type count_type = Type::U8;   // lists only
};

struct Element {
  std::string name;
  uint64_t count = 0;
  std::vector<Property> props;
  // Filled while walking the body:
  size_t offset = 0;          // binary: byte offset of the first row (fixed-size rows)
  std::vector<float> values;  // ASCII: count x props, row-major (kept elements only)

  bool has_list() const {
    return std::any_of(props.begin(), props.end(), [](const Property& p) { return p.is_list; });
  }
  size_t row_size() const {
    size_t s = 0;
    for (const auto& p : props) s += type_size(p.type);
    return s;
  }
  int index(std::string_view n) const {
    for (size_t i = 0; i < props.size(); ++i)
      if (props[i].name == n) return static_cast<int>(i);
    return -1;
  }
};

struct PlyHeader {
  bool ascii = false;
  std::vector<Element> elements;
  size_t body_offset = 0;

  Element* find(std::string_view name) {
    for (auto& e : elements)
      if (e.name == name) return &e;
    return nullptr;
  }
};

// Header lines go into error messages: keep them short and printable.
std::string printable(std::string_view s) {
  std::string out;
  for (char c : s.substr(0, 80)) out += (c >= 32 && c < 127) ? c : '?';
  if (s.size() > 80) out += "...";
  return out;
}

std::vector<std::string> split(std::string_view line) {
  std::vector<std::string> out;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) out.emplace_back(line.substr(start, i - start));
  }
  return out;
}

PlyHeader parse_header(const std::vector<uint8_t>& bytes, const fs::path& path) {
  const std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  size_t pos;
  if (text.substr(0, 4) == "ply\n") pos = 4;
  else if (text.substr(0, 5) == "ply\r\n") pos = 5;
  else fail_file(path, "not a PLY file (missing 'ply' magic)");

  PlyHeader h;
  bool have_format = false;
  while (true) {
    const size_t nl = text.find('\n', pos);
    if (nl == std::string_view::npos) fail_file(path, "PLY header has no end_header line");
    std::string_view line = text.substr(pos, nl - pos);
    pos = nl + 1;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const std::vector<std::string> w = split(line);
    if (w.empty() || w[0] == "comment" || w[0] == "obj_info") continue;
    if (w[0] == "end_header") break;
    if (w[0] == "format") {
      if (have_format) fail_file(path, "PLY header has two format lines");
      if (w.size() != 3) fail_file(path, "malformed PLY format line '{}'", printable(line));
      if (w[1] == "ascii") h.ascii = true;
      else if (w[1] != "binary_little_endian")
        fail_file(path, "unsupported PLY format '{}' (binary_little_endian or ascii)", printable(w[1]));
      if (w[2] != "1.0") fail_file(path, "unsupported PLY version '{}' (1.0)", printable(w[2]));
      have_format = true;
    } else if (w[0] == "element") {
      Element e;
      if (w.size() == 3) {
        e.name = w[1];
        const char* end = w[2].data() + w[2].size();
        const auto res = std::from_chars(w[2].data(), end, e.count);
        if (res.ec != std::errc() || res.ptr != end)
          fail_file(path, "malformed PLY element line '{}'", printable(line));
      } else {
        fail_file(path, "malformed PLY element line '{}'", printable(line));
      }
      if (h.find(e.name)) fail_file(path, "PLY header declares element '{}' twice", printable(e.name));
      h.elements.push_back(std::move(e));
    } else if (w[0] == "property") {
      if (h.elements.empty()) fail_file(path, "PLY property before any element: '{}'", printable(line));
      Element& e = h.elements.back();
      Property p;
      if (w.size() == 5 && w[1] == "list") {
        p.is_list = true;
        p.name = w[4];
        const auto ct = parse_type(w[2]), it = parse_type(w[3]);
        if (!ct) fail_file(path, "unknown PLY property type '{}'", printable(w[2]));
        if (!it) fail_file(path, "unknown PLY property type '{}'", printable(w[3]));
        if (*ct == Type::F32 || *ct == Type::F64)
          fail_file(path, "PLY list property '{}' has a non-integer count type {}", printable(p.name), w[2]);
        p.count_type = *ct;
        p.type = *it;
        p.type_name = w[3];
      } else if (w.size() == 3 && w[1] != "list") {
        const auto t = parse_type(w[1]);
        if (!t) fail_file(path, "unknown PLY property type '{}'", printable(w[1]));
        p.type = *t;
        p.type_name = w[1];
        p.name = w[2];
      } else {
        fail_file(path, "malformed PLY property line '{}'", printable(line));
      }
      if (e.index(p.name) >= 0)
        fail_file(path, "{} element declares property '{}' twice", printable(e.name), printable(p.name));
      e.props.push_back(std::move(p));
    } else {
      fail_file(path, "unexpected PLY header line '{}'", printable(line));
    }
  }
  if (!have_format) fail_file(path, "PLY header has no format line");
  h.body_offset = pos;
  return h;
}

// Walks a binary body: records where each fixed-row element starts and checks that every
// element fits in the file before anything is allocated.
void walk_binary(PlyHeader& h, const std::vector<uint8_t>& bytes, const fs::path& path) {
  ByteReader r(bytes.data(), bytes.size(), path);
  r.seek(h.body_offset, "PLY body");
  for (Element& e : h.elements) {
    e.offset = r.position();
    if (!e.has_list()) {
      const size_t row = e.row_size();
      if (row == 0) continue;  // no properties: the rows hold no bytes
      if (e.count > r.remaining() / row)
        fail_file(path, "truncated PLY body: {} {} rows of {} bytes do not fit in the {} bytes left", e.count, e.name,
                  row, r.remaining());
      r.skip(e.count * row, "rows");
      continue;
    }
    // Rows of variable size (faces and the like): every row holds at least one count byte,
    // so this loop ends at the end of the file at the latest.
    for (uint64_t i = 0; i < e.count; ++i) {
      for (const Property& p : e.props) {
        if (!p.is_list) {
          r.skip(type_size(p.type), "property value");
          continue;
        }
        r.require(type_size(p.count_type), "list length");
        const double n = load(r.current(), p.count_type);
        r.skip(type_size(p.count_type), "list length");
        if (n < 0) fail_file(path, "negative list length {} in {} row {}", n, e.name, i);
        const uint64_t items = static_cast<uint64_t>(n);
        if (items > r.remaining() / type_size(p.type))
          fail_file(path, "truncated PLY body: list of {} items in {} row {} does not fit in the {} bytes left", items,
                    e.name, i, r.remaining());
        r.skip(items * type_size(p.type), "list items");
      }
    }
  }
}

// Splits the ASCII body into numbers on the fly, keeping the values of the named element.
class AsciiBody {
 public:
  AsciiBody(std::string_view text, const fs::path& path) : s_(text), path_(path) {}

  void read(Element& e, bool keep) {
    if (e.props.empty()) return;
    if (keep && e.has_list())
      fail_file(path_, "list properties are not supported in the {} element", e.name);
    // Every value needs at least one character and one separator: refuse a count the rest
    // of the file cannot hold before allocating for it.
    const uint64_t bytes_left = s_.size() - pos_;
    const uint64_t per_row = e.props.size();
    if (e.count > (bytes_left + 1) / 2 / per_row)
      fail_file(path_, "truncated ASCII PLY body: {} {} rows of {} values do not fit in the {} bytes left", e.count,
                e.name, per_row, bytes_left);
    if (keep) e.values.resize(e.count * per_row);
    for (uint64_t i = 0; i < e.count; ++i) {
      for (size_t k = 0; k < e.props.size(); ++k) {
        const Property& p = e.props[k];
        const double v = next(e, i);
        if (p.is_list) {
          if (v < 0 || v != std::floor(v) || v > static_cast<double>(s_.size()))
            fail_file(path_, "bad list length {} in ASCII PLY body ({} row {})", v, e.name, i);
          for (uint64_t j = 0; j < static_cast<uint64_t>(v); ++j) next(e, i);
        } else if (keep) {
          e.values[i * per_row + k] = static_cast<float>(v);
        }
      }
    }
  }

 private:
  double next(const Element& e, uint64_t row) {
    while (pos_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[pos_]))) ++pos_;
    if (pos_ == s_.size())
      fail_file(path_, "truncated ASCII PLY body: {} row {} of {} has too few values", e.name, row, e.count);
    size_t end = pos_;
    while (end < s_.size() && !std::isspace(static_cast<unsigned char>(s_[end]))) ++end;
    std::string_view tok = s_.substr(pos_, end - pos_);
    pos_ = end;
    std::string_view digits = tok;
    if (!digits.empty() && digits[0] == '+') digits.remove_prefix(1);  // from_chars refuses '+'
    double v = 0;
    const auto res = std::from_chars(digits.data(), digits.data() + digits.size(), v);
    if (res.ec != std::errc() || res.ptr != digits.data() + digits.size())
      fail_file(path_, "malformed number '{}' in ASCII PLY body ({} row {})", printable(tok), e.name, row);
    return v;
  }

  std::string_view s_;
  size_t pos_ = 0;
  const fs::path& path_;
};

// Random access to the scalar properties of one element, binary or ASCII.
class Table {
 public:
  Table(const Element& e, const std::vector<uint8_t>& bytes, bool ascii) : e_(e), bytes_(bytes), ascii_(ascii) {
    size_t off = 0;
    for (const auto& p : e.props) {
      offsets_.push_back(off);
      off += type_size(p.type);
    }
    row_ = off;
  }
  float get(size_t row, int prop) const {
    if (ascii_) return e_.values[row * e_.props.size() + static_cast<size_t>(prop)];
    return static_cast<float>(load(bytes_.data() + e_.offset + row * row_ + offsets_[prop], e_.props[prop].type));
  }
  uint32_t get_u32(size_t row, int prop) const {  // binary uint32 properties only
    uint32_t v;
    std::memcpy(&v, bytes_.data() + e_.offset + row * row_ + offsets_[prop], 4);
    return v;
  }

 private:
  const Element& e_;
  const std::vector<uint8_t>& bytes_;
  bool ascii_;
  std::vector<size_t> offsets_;
  size_t row_ = 0;
};

// Indices of `names` in `e`; fails naming every missing one.
std::vector<int> require(const Element& e, const std::vector<std::string>& names, const char* what,
                         const fs::path& path) {
  std::vector<int> idx;
  std::vector<std::string> missing;
  for (const auto& n : names) {
    idx.push_back(e.index(n));
    if (idx.back() < 0) missing.push_back(n);
  }
  if (!missing.empty())
    fail_file(path, "{} element lacks required {} {} ({})", e.name, missing.size() == 1 ? "property" : "properties",
              fmt::join(missing, ", "), what);
  return idx;
}

// Decoding runs in double, as PlayCanvas does in JavaScript, and rounds to float only when
// storing, so decoded values match its output.
double unorm(uint32_t v, int bits) {
  const uint32_t mask = (1u << bits) - 1;
  return static_cast<double>(v & mask) / mask;
}

double lerp(float a, float b, double t) { return static_cast<double>(a) * (1.0 - t) + static_cast<double>(b) * t; }


SplatCloud read_compressed(const PlyHeader& h, const Element& vertex, const std::vector<uint8_t>& bytes,
                           const fs::path& path) {
  const size_t n = vertex.count;
  const std::vector<int> packed = require(vertex, {"packed_position", "packed_rotation", "packed_scale", "packed_color"},
                                          "compressed PLY", path);
  for (int k : packed)
    if (vertex.props[k].type != Type::U32)
      fail_file(path, "compressed PLY property '{}' must be uint32, not {}", vertex.props[k].name,
                vertex.props[k].type_name);
  const Element* chunk = nullptr;
  const Element* sh = nullptr;
  for (const Element& e : h.elements) {
    if (e.name == "chunk") chunk = &e;
    if (e.name == "sh") sh = &e;
  }
  if (!chunk) fail_file(path, "compressed PLY (packed_* vertex properties) has no chunk element");
  if (chunk->has_list()) fail_file(path, "list properties are not supported in the chunk element");
  const uint64_t chunks_needed = (n + 255) / 256;
  if (chunk->count < chunks_needed)
    fail_file(path, "compressed PLY has {} chunks for {} splats (256 splats per chunk: needs {})", chunk->count, n,
              chunks_needed);
  const std::vector<int> range = require(*chunk,
                                         {"min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "min_scale_x",
                                          "min_scale_y", "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z"},
                                         "compressed PLY", path);
  // Older files store the colour directly as 8 bits; newer ones also give a per-chunk range.
  const bool colour_range = chunk->index("min_r") >= 0 || chunk->index("max_r") >= 0;
  std::vector<int> colour;
  if (colour_range)
    colour = require(*chunk, {"min_r", "min_g", "min_b", "max_r", "max_g", "max_b"}, "compressed PLY colour range",
                     path);

  const Table vt(vertex, bytes, false), ct(*chunk, bytes, false);
  SplatCloud c;
  c.means.resize(n * 3);
  c.normals.assign(n * 3, 0.f);
  c.sh_dc.resize(n * 3);
  c.opacity_logit.resize(n);
  c.log_scales.resize(n * 3);
  c.rotations.resize(n * 4);
  const double norm = 1.0 / (std::sqrt(2.0) * 0.5);  // maps [0, 1] back to [-1/sqrt2, 1/sqrt2]
  for (size_t ci = 0; ci < chunks_needed; ++ci) {
    float lo[9], hi[9];  // position, log scale, colour
    for (int a = 0; a < 3; ++a) {
      lo[a] = ct.get(ci, range[a]);
      hi[a] = ct.get(ci, range[3 + a]);
      lo[3 + a] = ct.get(ci, range[6 + a]);
      hi[3 + a] = ct.get(ci, range[9 + a]);
      lo[6 + a] = colour_range ? ct.get(ci, colour[a]) : 0.f;
      hi[6 + a] = colour_range ? ct.get(ci, colour[3 + a]) : 1.f;
    }
    const size_t end = std::min(n, (ci + 1) * 256);
    for (size_t i = ci * 256; i < end; ++i) {
      // Position and log scale: 11/10/11 bits of x/y/z, from the top bit down.
      const uint32_t pp = vt.get_u32(i, packed[0]), ps = vt.get_u32(i, packed[2]);
      const double tp[3] = {unorm(pp >> 21, 11), unorm(pp >> 11, 10), unorm(pp, 11)};
      const double ts[3] = {unorm(ps >> 21, 11), unorm(ps >> 11, 10), unorm(ps, 11)};
      for (int a = 0; a < 3; ++a) {
        c.means[i * 3 + a] = static_cast<float>(lerp(lo[a], hi[a], tp[a]));
        c.log_scales[i * 3 + a] = static_cast<float>(lerp(lo[3 + a], hi[3 + a], ts[a]));
      }
      // Rotation: the top 2 bits say which of rot_0..rot_3 (w, x, y, z) is largest in
      // magnitude; the other three follow in rot order, 10 bits each, mapped from
      // [-1/sqrt2, 1/sqrt2]; the writer normalised and flipped the sign so that the dropped
      // one is positive, so it is recovered from the unit norm.
      const uint32_t pr = vt.get_u32(i, packed[1]);
      const double others[3] = {(unorm(pr >> 20, 10) - 0.5) * norm, (unorm(pr >> 10, 10) - 0.5) * norm,
                                (unorm(pr, 10) - 0.5) * norm};
      const double m = std::sqrt(std::max(0.0, 1.0 - (others[0] * others[0] + others[1] * others[1] + others[2] * others[2])));
      const uint32_t largest = pr >> 30;
      for (uint32_t k = 0, o = 0; k < 4; ++k) c.rotations[i * 4 + k] = static_cast<float>(k == largest ? m : others[o++]);
      // Colour: 8 bits per channel (r, g, b from the top byte) within the chunk's range of
      // 0.5 + SH_C0 * f_dc; the low byte is the activated opacity.
      const uint32_t pc = vt.get_u32(i, packed[3]);
      const double tc[3] = {unorm(pc >> 24, 8), unorm(pc >> 16, 8), unorm(pc >> 8, 8)};
      for (int a = 0; a < 3; ++a)
        c.sh_dc[i * 3 + a] = static_cast<float>(dc_of_colour(lerp(lo[6 + a], hi[6 + a], tc[a])));
      c.opacity_logit[i] = splat_quantize::opacity_logit_of_byte(static_cast<uint8_t>(pc & 0xff));
    }
  }

  if (sh) {
    if (sh->count != n) fail_file(path, "sh element has {} rows for {} splats", sh->count, n);
    if (sh->has_list()) fail_file(path, "list properties are not supported in the sh element");
    const size_t k = sh->props.size();
    if (k != 9 && k != 24 && k != 45)
      fail_file(path, "sh element has {} properties; expected 9, 24 or 45 (SH degree 1 to 3)", k);
    std::vector<std::string> names;
    for (size_t j = 0; j < k; ++j) names.push_back(fmt::format("f_rest_{}", j));
    const std::vector<int> idx = require(*sh, names, "compressed PLY", path);
    for (int j : idx)
      if (sh->props[j].type != Type::U8)
        fail_file(path, "sh property '{}' must be uchar, not {}", sh->props[j].name, sh->props[j].type_name);
    const Table st(*sh, bytes, false);
    c.sh_rest_per_channel = static_cast<int>(k / 3);
    c.sh_rest.resize(n * k);
    for (size_t i = 0; i < n; ++i) {
      for (size_t j = 0; j < k; ++j) {
        // The writer stores trunc((v / 8 + 0.5) * 256) clamped to [0, 255]: decode to the
        // centre of that bin, with the clamped ends at the range limits (as splat-transform).
        const float b = st.get(i, idx[j]);
        const float t = b == 0.f ? 0.f : b == 255.f ? 1.f : (b + 0.5f) / 256.f;
        c.sh_rest[i * k + j] = (t - 0.5f) * 8.f;
      }
    }
  }
  return c;
}

SplatCloud read_standard(const Element& vertex, const std::vector<uint8_t>& bytes, bool ascii, const fs::path& path) {
  if (vertex.has_list()) fail_file(path, "list properties are not supported in the vertex element");
  const std::vector<int> idx =
      require(vertex,
              {"x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2", "rot_0",
               "rot_1", "rot_2", "rot_3"},
              "a 3D Gaussian splat PLY needs x y z f_dc_0..2 opacity scale_0..2 rot_0..3", path);
  // f_rest_* must be numbered 0..R-1, R = 3K.
  size_t rest = 0;
  for (const Property& p : vertex.props) {
    if (p.name.rfind("f_rest_", 0) != 0) continue;
    const std::string_view num = std::string_view(p.name).substr(7);
    size_t j = 0;
    const auto res = std::from_chars(num.data(), num.data() + num.size(), j);
    if (res.ec != std::errc() || res.ptr != num.data() + num.size()) continue;  // not ours: ignore
    ++rest;
  }
  std::vector<int> rest_idx;
  for (size_t j = 0; j < rest; ++j) {
    rest_idx.push_back(vertex.index(fmt::format("f_rest_{}", j)));
    if (rest_idx.back() < 0)
      fail_file(path, "vertex element has {} f_rest properties but no f_rest_{}", rest, j);
  }
  if (rest != 0 && rest != 9 && rest != 24 && rest != 45)
    fail_file(path, "vertex element has {} f_rest properties; expected 0, 9, 24 or 45 (SH degree 0 to 3)", rest);

  const size_t n = vertex.count;
  const Table t(vertex, bytes, ascii);
  SplatCloud c;
  c.means.resize(n * 3);
  c.normals.assign(n * 3, 0.f);
  c.sh_dc.resize(n * 3);
  c.opacity_logit.resize(n);
  c.log_scales.resize(n * 3);
  c.rotations.resize(n * 4);
  c.sh_rest_per_channel = static_cast<int>(rest / 3);
  c.sh_rest.resize(n * rest);
  int normal_idx[3];
  for (int a = 0; a < 3; ++a) normal_idx[a] = vertex.index(std::string("n") + "xyz"[a]);
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      c.means[i * 3 + a] = t.get(i, idx[a]);
      c.sh_dc[i * 3 + a] = t.get(i, idx[3 + a]);
      c.log_scales[i * 3 + a] = t.get(i, idx[7 + a]);
      if (normal_idx[a] >= 0) c.normals[i * 3 + a] = t.get(i, normal_idx[a]);
    }
    c.opacity_logit[i] = t.get(i, idx[6]);
    for (int a = 0; a < 4; ++a) c.rotations[i * 4 + a] = t.get(i, idx[10 + a]);
    for (size_t j = 0; j < rest; ++j) c.sh_rest[i * rest + j] = t.get(i, rest_idx[j]);
  }
  return c;
}

}  // namespace

SplatCloud read_splat_ply(const fs::path& path) {
  const std::vector<uint8_t> bytes = read_file_bytes(path);
  PlyHeader h = parse_header(bytes, path);
  Element* vertex = h.find("vertex");
  if (!vertex) fail_file(path, "PLY file has no vertex element");
  const bool compressed = vertex->index("packed_position") >= 0 || vertex->index("packed_rotation") >= 0 ||
                          vertex->index("packed_scale") >= 0 || vertex->index("packed_color") >= 0;
  if (compressed && h.ascii) fail_file(path, "compressed PLY must be binary, not ascii");
  if (h.ascii) {
    AsciiBody body(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()).substr(h.body_offset),
                   path);
    for (Element& e : h.elements) body.read(e, &e == vertex);
  } else {
    walk_binary(h, bytes, path);
  }
  return compressed ? read_compressed(h, *vertex, bytes, path) : read_standard(*vertex, bytes, h.ascii, path);
}

void check_splat_cloud(const SplatCloud& c, const fs::path& path) {
  const size_t n = c.size();
  if (c.sh_rest_per_channel < 0) fail_file(path, "splat cloud has a negative SH coefficient count");
  const size_t rest = static_cast<size_t>(c.sh_rest_per_channel) * 3;
  auto check = [&](const std::vector<float>& v, size_t per, const char* name) {
    if (v.size() != n * per)
      fail_file(path, "splat cloud {} has {} values, expected {} ({} per splat for {} splats)", name, v.size(), n * per,
                per, n);
  };
  check(c.means, 3, "means");
  if (!c.normals.empty()) check(c.normals, 3, "normals");
  check(c.sh_dc, 3, "sh_dc");
  check(c.sh_rest, rest, "sh_rest");
  check(c.log_scales, 3, "log_scales");
  check(c.rotations, 4, "rotations");
}

void write_splat_ply(const fs::path& path, const SplatCloud& c) {
  check_splat_cloud(c, path);
  const size_t n = c.size();
  const size_t rest = static_cast<size_t>(c.sh_rest_per_channel) * 3;

  // No comment line: some splat viewers refuse headers with comments.
  std::string header = fmt::format("ply\nformat binary_little_endian 1.0\nelement vertex {}\n", n);
  std::vector<std::string> props = {"x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"};
  for (size_t j = 0; j < rest; ++j) props.push_back(fmt::format("f_rest_{}", j));
  for (const char* p : {"opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"}) props.push_back(p);
  for (const auto& p : props) header += "property float " + p + "\n";
  header += "end_header\n";

  const size_t row = props.size();
  write_file_atomic(path, [&](const fs::path& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) fail_file(tmp, "cannot open for writing: {}", std::strerror(errno));
    out.write(header.data(), static_cast<std::streamsize>(header.size()));
    // Rows are assembled in blocks so large clouds are not copied whole.
    constexpr size_t kBlock = 4096;
    std::vector<float> values(kBlock * row);
    for (size_t start = 0; start < n; start += kBlock) {
      const size_t count = std::min(kBlock, n - start);
      for (size_t b = 0; b < count; ++b) {
        const size_t i = start + b;
        float* v = &values[b * row];
        for (int a = 0; a < 3; ++a) {
          v[a] = c.means[i * 3 + a];
          v[3 + a] = c.normals.empty() ? 0.f : c.normals[i * 3 + a];
          v[6 + a] = c.sh_dc[i * 3 + a];
        }
        for (size_t j = 0; j < rest; ++j) v[9 + j] = c.sh_rest[i * rest + j];
        v[9 + rest] = c.opacity_logit[i];
        for (int a = 0; a < 3; ++a) v[10 + rest + a] = c.log_scales[i * 3 + a];
        for (int a = 0; a < 4; ++a) v[13 + rest + a] = c.rotations[i * 4 + a];
      }
      out.write(reinterpret_cast<const char*>(values.data()), static_cast<std::streamsize>(count * row * sizeof(float)));
    }
    out.flush();
    if (!out) fail_file(path, "write error (disk full?)");
  });
}

}  // namespace ii

namespace ii {

std::vector<size_t> morton_order(const std::vector<float>& means) {
  const size_t n = means.size() / 3;
  float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], means[i * 3 + a]);
      hi[a] = std::max(hi[a], means[i * 3 + a]);
    }
  // 10 bits per axis, interleaved: neighbours in space end up near in the order.
  auto spread = [](uint32_t v) {
    v = (v | (v << 16)) & 0x030000ff;
    v = (v | (v << 8)) & 0x0300f00f;
    v = (v | (v << 4)) & 0x030c30c3;
    return (v | (v << 2)) & 0x09249249;
  };
  std::vector<uint32_t> code(n);
  parallel_range(static_cast<int64_t>(n), 1 << 15, thread_plan().cores, [&](int64_t begin, int64_t end) {
    for (auto i = static_cast<size_t>(begin); i < static_cast<size_t>(end); ++i) {
      uint32_t c = 0;
      for (int a = 0; a < 3; ++a) {
        const double t = hi[a] > lo[a] ? (means[i * 3 + a] - lo[a]) / (static_cast<double>(hi[a]) - lo[a]) : 0.0;
        c |= spread(static_cast<uint32_t>(std::clamp(t, 0.0, 1.0) * 1023)) << a;
      }
      code[i] = c;
    }
  });
  // A stable sort by the 30-bit codes: three counting passes of 10 bits (least significant
  // first), the order std::stable_sort gives, in a fraction of its time for millions. Each
  // thread counts and places a contiguous slice; slices keep their order, so ties do.
  constexpr size_t kBuckets = 1024;
  const size_t slices = std::clamp<size_t>(n / 65536, 1, static_cast<size_t>(thread_plan().cores));
  auto slice_begin = [&](size_t t) { return n * t / slices; };
  std::vector<size_t> order(n), next(n);
  for (size_t i = 0; i < n; ++i) order[i] = i;
  std::vector<std::vector<size_t>> at(slices, std::vector<size_t>(kBuckets));
  for (int shift = 0; shift < 30; shift += 10) {
    auto digit = [&](size_t i) { return (code[i] >> shift) & (kBuckets - 1); };
    parallel_dynamic(static_cast<int64_t>(slices), static_cast<int>(slices), [&](int64_t t) {
      std::vector<size_t>& count = at[static_cast<size_t>(t)];
      std::fill(count.begin(), count.end(), 0);
      for (size_t s = slice_begin(static_cast<size_t>(t)); s < slice_begin(static_cast<size_t>(t) + 1); ++s)
        ++count[digit(order[s])];
    });
    size_t position = 0;  // bucket by bucket, slice by slice: each slice's first place in a bucket
    for (size_t b = 0; b < kBuckets; ++b)
      for (size_t t = 0; t < slices; ++t) {
        const size_t count = at[t][b];
        at[t][b] = position;
        position += count;
      }
    parallel_dynamic(static_cast<int64_t>(slices), static_cast<int>(slices), [&](int64_t t) {
      std::vector<size_t>& place = at[static_cast<size_t>(t)];
      for (size_t s = slice_begin(static_cast<size_t>(t)); s < slice_begin(static_cast<size_t>(t) + 1); ++s)
        next[place[digit(order[s])]++] = order[s];
    });
    order.swap(next);
  }
  return order;
}

void write_compressed_splat_ply(const fs::path& path, const SplatCloud& c) {
  const std::string bytes = encode_compressed_splat_ply(c, path);
  write_file_atomic(path, bytes);
}

std::string encode_compressed_splat_ply(const SplatCloud& c, const fs::path& path) {
  check_splat_cloud(c, path);
  const int k = c.sh_rest_per_channel;
  if (c.sh_degree() < 0)
    fail_file(path, "{} SH coefficients per channel are no SH degree (3, 8 or 15 expected)", k);
  const size_t n = c.size();
  const size_t chunks = (n + 255) / 256;
  std::string header = fmt::format("ply\nformat binary_little_endian 1.0\nelement chunk {}\n", chunks);
  for (const char* bound : {"min", "max"})
    for (const char* a : {"x", "y", "z"}) header += fmt::format("property float {}_{}\n", bound, a);
  for (const char* bound : {"min", "max"})
    for (const char* a : {"x", "y", "z"}) header += fmt::format("property float {}_scale_{}\n", bound, a);
  for (const char* bound : {"min", "max"})
    for (const char* a : {"r", "g", "b"}) header += fmt::format("property float {}_{}\n", bound, a);
  header += fmt::format("element vertex {}\n", n);
  for (const char* p : {"packed_position", "packed_rotation", "packed_scale", "packed_color"})
    header += fmt::format("property uint {}\n", p);
  if (k > 0) {
    header += fmt::format("element sh {}\n", n);
    for (int j = 0; j < 3 * k; ++j) header += fmt::format("property uchar f_rest_{}\n", j);
  }
  header += "end_header\n";

  const std::vector<size_t> order = morton_order(c.means);
  std::vector<float> chunk_table(chunks * 18);
  std::vector<uint32_t> packed(n * 4);
  std::vector<uint8_t> sh(n * 3 * static_cast<size_t>(k));
  // t in [0, 1] of [lo, hi] to `bits` bits (PlayCanvas rounds the same way).
  auto pack = [](double v, float lo, float hi, int bits) {
    const uint32_t mask = (1u << bits) - 1;
    const double t = hi > lo ? (v - lo) / (static_cast<double>(hi) - lo) : 0.0;
    return static_cast<uint32_t>(std::lround(std::clamp(t, 0.0, 1.0) * mask));
  };
  // Chunks are independent: packed side by side.
  parallel_range(static_cast<int64_t>(chunks), 64, thread_plan().cores, [&](int64_t first, int64_t last) {
    for (auto ci = static_cast<size_t>(first); ci < static_cast<size_t>(last); ++ci) {
      const size_t begin = ci * 256, end = std::min(n, begin + 256);
      float lo[9], hi[9];  // position, log scale (clamped to ±20, as SuperSplat), colour
      std::fill(lo, lo + 9, INFINITY);
      std::fill(hi, hi + 9, -INFINITY);
      auto colour = [&](size_t i, int a) { return static_cast<float>(colour_of_dc(c.sh_dc[i * 3 + a])); };
      auto log_scale = [&](size_t i, int a) { return std::clamp(c.log_scales[i * 3 + a], -20.f, 20.f); };
      for (size_t s = begin; s < end; ++s) {
        const size_t i = order[s];
        for (int a = 0; a < 3; ++a) {
          const float v[3] = {c.means[i * 3 + a], log_scale(i, a), colour(i, a)};
          for (int g = 0; g < 3; ++g) {
            lo[g * 3 + a] = std::min(lo[g * 3 + a], v[g]);
            hi[g * 3 + a] = std::max(hi[g * 3 + a], v[g]);
          }
        }
      }
      float* row = &chunk_table[ci * 18];
      for (int g = 0; g < 3; ++g)
        for (int a = 0; a < 3; ++a) {
          row[g * 6 + a] = lo[g * 3 + a];
          row[g * 6 + 3 + a] = hi[g * 3 + a];
        }
      for (size_t s = begin; s < end; ++s) {
        const size_t i = order[s];
        uint32_t* p = &packed[s * 4];
        const float* m = &c.means[i * 3];
        p[0] = pack(m[0], lo[0], hi[0], 11) << 21 | pack(m[1], lo[1], hi[1], 10) << 11 | pack(m[2], lo[2], hi[2], 11);
        // Rotation (w, x, y, z): the three smallest, 10 bits each over [-1/√2, 1/√2].
        const splat_quantize::SmallestThree q = splat_quantize::smallest_three(&c.rotations[i * 4]);
        uint32_t r = static_cast<uint32_t>(q.largest);
        for (int a = 0; a < 4; ++a)
          if (a != q.largest)
            r = r << 10 | static_cast<uint32_t>(std::lround(std::clamp(q.q[a] / std::sqrt(2.0) + 0.5, 0.0, 1.0) * 1023));
        p[1] = r;
        p[2] = pack(log_scale(i, 0), lo[3], hi[3], 11) << 21 | pack(log_scale(i, 1), lo[4], hi[4], 10) << 11 |
               pack(log_scale(i, 2), lo[5], hi[5], 11);
        const double alpha = 1 / (1 + std::exp(-static_cast<double>(c.opacity_logit[i])));
        p[3] = pack(colour(i, 0), lo[6], hi[6], 8) << 24 | pack(colour(i, 1), lo[7], hi[7], 8) << 16 |
               pack(colour(i, 2), lo[8], hi[8], 8) << 8 | pack(alpha, 0, 1, 8);
        for (int j = 0; j < 3 * k; ++j) {
          const double t = c.sh_rest[i * 3 * k + j] / 8.0 + 0.5;
          sh[s * 3 * k + j] = static_cast<uint8_t>(std::clamp(std::trunc(t * 256), 0.0, 255.0));
        }
      }
    }
  });
  std::string bytes = header;
  auto append = [&](const void* data, size_t size) { bytes.append(static_cast<const char*>(data), size); };
  bytes.reserve(header.size() + chunk_table.size() * 4 + packed.size() * 4 + sh.size());
  append(chunk_table.data(), chunk_table.size() * 4);
  append(packed.data(), packed.size() * 4);
  append(sh.data(), sh.size());
  return bytes;
}

}  // namespace ii
