#include "io/sog.h"

#include <webp/decode.h>
#include <webp/encode.h>
#include <zip.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <memory>
#include <numeric>
#include <random>
#include <string>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "common/error.h"
#include "common/files.h"
#include "common/parallel.h"
#include "io/splat_quantize.h"
#include "io/zip_archive.h"

namespace ii {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr int64_t kMaxSplats = int64_t{1} << 24;  // splats: 16.7 M (a 4 x 904 x 512 prediction has 1.85 M)
constexpr int kPaletteColumns = 64;  // SH palette entries per row of shN_centroids
constexpr int kMaxPalette = 4096;    // what the writer fits (the format allows 65536)

struct Texture {
  int width = 0, height = 0;
  std::vector<uint8_t> rgba;
  const uint8_t* texel(size_t i) const { return rgba.data() + i * 4; }
};

// At most `max_texels` (checked before decoding: a small lossless WebP can claim a huge image).
Texture decode_webp(const std::vector<uint8_t>& bytes, const std::string& entry, int64_t max_texels,
                    const fs::path& path) {
  int w = 0, h = 0;
  if (!WebPGetInfo(bytes.data(), bytes.size(), &w, &h))
    fail_file(path, "SOG image {} is not a WebP image", entry);
  if (w <= 0 || h <= 0 || int64_t{w} * h > max_texels)
    fail_file(path, "SOG image {} is {}x{}: more than the {} texels it can need", entry, w, h, max_texels);
  Texture t;
  t.width = w;
  t.height = h;
  t.rgba.resize(size_t(w) * h * 4);
  if (!WebPDecodeRGBAInto(bytes.data(), bytes.size(), t.rgba.data(), t.rgba.size(), w * 4))
    fail_file(path, "SOG image {} could not be decoded (corrupt WebP data)", entry);
  return t;
}

// The files of a bundle or of a folder with meta.json: only plain names, nothing outside.
class SogFiles {
 public:
  explicit SogFiles(const fs::path& path) : path_(path) {
    if (path.filename() != "meta.json") zip_ = std::make_unique<ZipArchive>(path);
  }
  std::vector<uint8_t> read(const std::string& name) const {
    if (name.empty() || name.find('/') != std::string::npos || name.find('\\') != std::string::npos ||
        name == "." || name == "..")
      fail_file(path_, "SOG file name '{}' is not a plain file name", name);
    if (zip_) {
      if (!zip_->has(name)) fail_file(path_, "SOG bundle has no {}", name);
      return zip_->read(name);
    }
    const fs::path file = path_.parent_path() / name;
    if (!fs::is_regular_file(file)) fail_file(path_, "SOG file {} is missing beside meta.json", name);
    return read_file_bytes(file);
  }

 private:
  fs::path path_;
  std::unique_ptr<ZipArchive> zip_;
};

const json& member(const json& j, const char* key, const std::string& where, const fs::path& path) {
  if (!j.is_object() || !j.contains(key)) fail_file(path, "SOG meta.json has no {}{}", where, key);
  return j.at(key);
}

std::vector<float> floats(const json& j, size_t count, const std::string& what, const fs::path& path) {
  if (!j.is_array() || j.size() != count) fail_file(path, "SOG meta.json {} must be {} numbers", what, count);
  std::vector<float> v;
  for (const json& x : j) {
    if (!x.is_number()) fail_file(path, "SOG meta.json {} must be {} numbers", what, count);
    const double d = x.get<double>();
    if (!std::isfinite(d) || std::abs(d) > 1e30) fail_file(path, "SOG meta.json {} holds a value that is not finite", what);
    v.push_back(static_cast<float>(d));
  }
  return v;
}

std::vector<std::string> file_names(const json& group, const char* name, size_t count, const fs::path& path) {
  const json& files = member(group, "files", std::string(name) + ".", path);
  if (!files.is_array() || files.size() != count)
    fail_file(path, "SOG meta.json {}.files must name {} file{}", name, count, count == 1 ? "" : "s");
  std::vector<std::string> names;
  for (const json& f : files) {
    if (!f.is_string()) fail_file(path, "SOG meta.json {}.files must be strings", name);
    names.push_back(f.get<std::string>());
  }
  return names;
}

// One texel per splat: about square, so at most twice the count (and a few rows) is needed.
Texture texture(const SogFiles& files, const std::string& name, size_t count, const fs::path& path) {
  Texture t = decode_webp(files.read(name), name, 2 * static_cast<int64_t>(count) + 65536, path);
  if (size_t(t.width) * t.height < count)
    fail_file(path, "SOG image {} has {}x{} texels for {} splats", name, t.width, t.height, count);
  return t;
}

double inverse_log(double v) { return v < 0 ? -(std::exp(-v) - 1) : std::exp(v) - 1; }
double log_transform(double v) { return v < 0 ? -std::log1p(-v) : std::log1p(v); }

}  // namespace

SplatCloud read_sog(const fs::path& path) {
  const SogFiles files(path);
  json meta;
  try {
    const std::vector<uint8_t> text = files.read("meta.json");
    meta = json::parse(text.begin(), text.end());
  } catch (const json::exception& e) {
    fail_file(path, "SOG meta.json is not valid JSON ({})", e.what());
  }
  if (!meta.is_object()) fail_file(path, "SOG meta.json is not a JSON object");
  if (!meta.contains("version"))
    fail_file(path, "SOG version 1 (no version in meta.json) is not supported: convert it with splat-transform");
  if (!meta["version"].is_number_integer() || meta["version"].get<int64_t>() != 2)
    fail_file(path, "SOG version {} is not supported (2)", meta["version"].dump());
  const json& count_json = member(meta, "count", "", path);
  if (!count_json.is_number_integer() || count_json.get<int64_t>() < 0 || count_json.get<int64_t>() > kMaxSplats)
    fail_file(path, "SOG splat count {} is not a count of at most {}", count_json.dump(), kMaxSplats);
  const size_t n = count_json.get<size_t>();

  const json& means = member(meta, "means", "", path);
  const std::vector<float> lo = floats(member(means, "mins", "means.", path), 3, "means.mins", path);
  const std::vector<float> hi = floats(member(means, "maxs", "means.", path), 3, "means.maxs", path);
  const std::vector<std::string> mean_files = file_names(means, "means", 2, path);
  const json& scales = member(meta, "scales", "", path);
  const std::vector<float> scale_book = floats(member(scales, "codebook", "scales.", path), 256, "scales.codebook", path);
  const json& sh0 = member(meta, "sh0", "", path);
  const std::vector<float> colour_book = floats(member(sh0, "codebook", "sh0.", path), 256, "sh0.codebook", path);

  const Texture means_l = texture(files, mean_files[0], n, path), means_u = texture(files, mean_files[1], n, path);
  const Texture quats = texture(files, file_names(member(meta, "quats", "", path), "quats", 1, path)[0], n, path);
  const Texture scale_labels = texture(files, file_names(scales, "scales", 1, path)[0], n, path);
  const Texture colours = texture(files, file_names(sh0, "sh0", 1, path)[0], n, path);

  SplatCloud c;
  c.resize(n, 0);
  for (size_t i = 0; i < n; ++i) {
    const uint8_t *l = means_l.texel(i), *u = means_u.texel(i), *q = quats.texel(i), *s = scale_labels.texel(i),
                  *k = colours.texel(i);
    for (int a = 0; a < 3; ++a) {
      const double t = (l[a] | (u[a] << 8)) / 65535.0;
      c.means[i * 3 + a] = static_cast<float>(inverse_log(lo[a] + (static_cast<double>(hi[a]) - lo[a]) * t));
      c.log_scales[i * 3 + a] = scale_book[s[a]];
      c.sh_dc[i * 3 + a] = colour_book[k[a]];
    }
    c.opacity_logit[i] = splat_quantize::opacity_logit_of_byte(k[3]);
    if (q[3] < 252) fail_file(path, "SOG splat {} has no rotation (quats alpha {}, expected 252-255)", i, q[3]);
    const int largest = q[3] - 252;
    double sum = 0;
    float* rot = &c.rotations[i * 4];
    for (int a = 0, o = 0; a < 4; ++a) {
      if (a == largest) continue;
      rot[a] = static_cast<float>((q[o++] / 255.0 * 2 - 1) / std::sqrt(2.0));
      sum += double(rot[a]) * rot[a];
    }
    rot[largest] = static_cast<float>(std::sqrt(std::max(0.0, 1 - sum)));
  }

  if (meta.contains("shN")) {
    const json& sh = meta["shN"];
    const json& bands = member(sh, "bands", "shN.", path);
    if (!bands.is_number_integer() || bands.get<int64_t>() < 1 || bands.get<int64_t>() > 3)
      fail_file(path, "SOG shN.bands {} is not 1, 2 or 3", bands.dump());
    const int coefficients = (bands.get<int>() + 1) * (bands.get<int>() + 1) - 1;
    const json& palette_json = member(sh, "count", "shN.", path);
    if (!palette_json.is_number_integer() || palette_json.get<int64_t>() < 1 || palette_json.get<int64_t>() > 65536)
      fail_file(path, "SOG shN.count {} is not a palette size of 1 to 65536", palette_json.dump());
    const size_t palette = palette_json.get<size_t>();
    const std::vector<float> book = floats(member(sh, "codebook", "shN.", path), 256, "shN.codebook", path);
    const std::vector<std::string> sh_files = file_names(sh, "shN", 2, path);
    const Texture centroids = decode_webp(files.read(sh_files[0]), sh_files[0],
                                          int64_t{kPaletteColumns} * coefficients * (65536 / kPaletteColumns), path);
    const Texture labels = texture(files, sh_files[1], n, path);
    if (centroids.width != kPaletteColumns * coefficients ||
        size_t(centroids.height) * kPaletteColumns < palette)
      fail_file(path, "SOG image {} is {}x{}: {} palette entries of {} coefficients need {} columns and {} rows",
                sh_files[0], centroids.width, centroids.height, palette, coefficients, kPaletteColumns * coefficients,
                (palette + kPaletteColumns - 1) / kPaletteColumns);
    c.resize(n, coefficients);
    for (size_t i = 0; i < n; ++i) {
      const uint8_t* t = labels.texel(i);
      const size_t label = t[0] | (t[1] << 8);
      if (label >= palette) fail_file(path, "SOG splat {} has SH label {}, beyond the palette of {}", i, label, palette);
      const size_t row = label / kPaletteColumns, column = (label % kPaletteColumns) * coefficients;
      for (int j = 0; j < coefficients; ++j) {
        const uint8_t* e = centroids.texel(row * centroids.width + column + j);
        for (int ch = 0; ch < 3; ++ch) c.sh_rest[i * 3 * coefficients + ch * coefficients + j] = book[e[ch]];
      }
    }
  }
  return c;
}

namespace {

// A 256-entry codebook for `values` by 1D k-means (Lloyd's, from quantiles, on a sorted
// sample), and each value's index into it.
std::pair<std::vector<float>, std::vector<uint8_t>> codebook(const std::vector<float>& values) {
  std::vector<float> sample;
  const size_t step = std::max<size_t>(1, values.size() / 500000);
  for (size_t i = 0; i < values.size(); i += step) sample.push_back(values[i]);
  std::sort(sample.begin(), sample.end());
  std::vector<float> centres(256, 0.f);
  if (!sample.empty()) {
    std::vector<double> prefix(sample.size() + 1, 0.0);
    for (size_t i = 0; i < sample.size(); ++i) prefix[i + 1] = prefix[i] + sample[i];
    for (int k = 0; k < 256; ++k) centres[k] = sample[std::min(sample.size() - 1, (2 * k + 1) * sample.size() / 512)];
    for (int iteration = 0; iteration < 30; ++iteration) {
      std::sort(centres.begin(), centres.end());
      // Each centre takes the values closer to it than to its neighbours: a run of the sorted sample.
      size_t begin = 0;
      for (int k = 0; k < 256; ++k) {
        const size_t end = k == 255 ? sample.size()
                                    : static_cast<size_t>(std::upper_bound(sample.begin(), sample.end(),
                                                                           0.5f * (centres[k] + centres[k + 1])) -
                                                          sample.begin());
        if (end > begin) centres[k] = static_cast<float>((prefix[end] - prefix[begin]) / double(end - begin));
        begin = std::max(begin, end);
      }
    }
    std::sort(centres.begin(), centres.end());
  }
  std::vector<uint8_t> labels(values.size());
  for (size_t i = 0; i < values.size(); ++i) {
    const auto it = std::lower_bound(centres.begin(), centres.end(), values[i]);
    size_t k = static_cast<size_t>(it - centres.begin());
    if (k == 256 || (k > 0 && values[i] - centres[k - 1] < centres[k] - values[i])) --k;
    labels[i] = static_cast<uint8_t>(k);
  }
  return {centres, labels};
}

using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Each row of `points`' nearest row of `centres` (squared distance), as ||c||^2 - 2 x.c: one
// matrix product per block of rows (Eigen's), the blocks over the cores. The brute-force loop it
// replaced made the SH palette of a 90k-splat capture in 14 s.
std::vector<uint16_t> nearest_centres(const Eigen::Ref<const RowMatrix>& points, const RowMatrix& centres) {
  const Eigen::VectorXf norms = centres.rowwise().squaredNorm();
  std::vector<uint16_t> out(static_cast<size_t>(points.rows()));
  constexpr int64_t kBlock = 128;
  const int64_t blocks = (points.rows() + kBlock - 1) / kBlock;
  parallel_range(blocks, 1, thread_plan().cores, [&](int64_t b0, int64_t b1) {
    Eigen::MatrixXf dots;
    for (int64_t b = b0; b < b1; ++b) {
      const int64_t r0 = b * kBlock, rows = std::min(kBlock, points.rows() - r0);
      dots.noalias() = centres * points.middleRows(r0, rows).transpose();  // entries x rows
      for (int64_t r = 0; r < rows; ++r) {
        Eigen::Index best = 0;
        (norms - 2 * dots.col(r)).minCoeff(&best);
        out[static_cast<size_t>(r0 + r)] = static_cast<uint16_t>(best);
      }
    }
  });
  return out;
}

// The SH palette: k-means (squared distance) fitted on a seeded sample, then every splat's
// nearest entry.
std::pair<std::vector<float>, std::vector<uint16_t>> sh_palette(const std::vector<float>& rest, size_t n, int dims,
                                                                size_t entries) {
  std::mt19937 rng(1);
  std::vector<size_t> sample(n);
  std::iota(sample.begin(), sample.end(), 0);
  std::shuffle(sample.begin(), sample.end(), rng);
  sample.resize(std::min<size_t>(n, 8 * entries));
  const Eigen::Map<const RowMatrix> all(rest.data(), static_cast<Eigen::Index>(n), dims);
  RowMatrix sampled(static_cast<Eigen::Index>(sample.size()), dims);
  for (size_t s = 0; s < sample.size(); ++s) sampled.row(static_cast<Eigen::Index>(s)) = all.row(static_cast<Eigen::Index>(sample[s]));
  RowMatrix centres(static_cast<Eigen::Index>(entries), dims);
  for (size_t k = 0; k < entries; ++k) centres.row(static_cast<Eigen::Index>(k)) = sampled.row(static_cast<Eigen::Index>(k % sample.size()));
  for (int iteration = 0; iteration < 5; ++iteration) {
    const std::vector<uint16_t> nearest = nearest_centres(sampled, centres);
    Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(entries), dims);
    std::vector<size_t> members(entries, 0);
    for (size_t s = 0; s < sample.size(); ++s) {
      ++members[nearest[s]];
      sum.row(nearest[s]) += sampled.row(static_cast<Eigen::Index>(s)).cast<double>();
    }
    for (size_t k = 0; k < entries; ++k)
      if (members[k] > 0)
        centres.row(static_cast<Eigen::Index>(k)) = (sum.row(static_cast<Eigen::Index>(k)) / double(members[k])).cast<float>();
  }
  std::vector<float> flat(centres.data(), centres.data() + centres.size());
  return {flat, nearest_centres(all, centres)};
}

std::vector<uint8_t> encode_webp(const std::vector<uint8_t>& rgba, int width, int height, const fs::path& path) {
  uint8_t* out = nullptr;
  const size_t size = WebPEncodeLosslessRGBA(rgba.data(), width, height, width * 4, &out);
  if (size == 0 || !out) fail_file(path, "WebP encoding failed ({}x{})", width, height);
  std::vector<uint8_t> bytes(out, out + size);
  WebPFree(out);
  return bytes;
}

}  // namespace

void write_sog(const fs::path& path, const SplatCloud& c) {
  check_splat_cloud(c, path);
  const size_t n = c.size();
  const int coefficients = c.sh_rest_per_channel;
  if (c.sh_degree() < 0)
    fail_file(path, "{} SH coefficients per channel are no SH degree (3, 8 or 15 expected)", coefficients);
  if (static_cast<int64_t>(n) > kMaxSplats) fail_file(path, "{} splats are more than a SOG file holds here", n);
  for (float v : c.means)
    if (!std::isfinite(v)) fail_file(path, "a splat position is not finite: SOG cannot store it");
  // Texture size as splat-transform makes it: about square, multiples of 4.
  const int width = std::max(4, static_cast<int>(std::ceil(std::sqrt(double(n)) / 4)) * 4);
  const int height = std::max(4, static_cast<int>(std::ceil(double(n) / width / 4)) * 4);
  const size_t texels = size_t(width) * height;
  const std::vector<size_t> order = morton_order(c.means);

  std::vector<std::pair<std::string, std::vector<uint8_t>>> entries;
  json meta = {{"version", 2}, {"asset", {{"generator", "instainpaint"}}}, {"count", n}};

  // Positions, 16 bits per axis on the log-transformed range.
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], log_transform(c.means[i * 3 + a]));
      hi[a] = std::max(hi[a], log_transform(c.means[i * 3 + a]));
    }
  if (n == 0) {
    std::fill(lo, lo + 3, 0.0);
    std::fill(hi, hi + 3, 0.0);
  }
  std::vector<uint8_t> means_l(texels * 4, 255), means_u(texels * 4, 255), quats(texels * 4, 255);
  for (size_t s = 0; s < n; ++s) {
    const size_t i = order[s];
    for (int a = 0; a < 3; ++a) {
      const double t = hi[a] > lo[a] ? (log_transform(c.means[i * 3 + a]) - lo[a]) / (hi[a] - lo[a]) : 0.0;
      const uint32_t v = static_cast<uint32_t>(std::lround(std::clamp(t, 0.0, 1.0) * 65535));
      means_l[s * 4 + a] = v & 0xff;
      means_u[s * 4 + a] = v >> 8;
    }
    // Rotation (w, x, y, z): the three smallest × √2, 8 bits each, and 252 + the largest's index.
    const splat_quantize::SmallestThree q = splat_quantize::smallest_three(&c.rotations[i * 4]);
    for (int a = 0, o = 0; a < 4; ++a)
      if (a != q.largest)
        quats[s * 4 + o++] =
            static_cast<uint8_t>(std::lround(std::clamp(q.q[a] * std::sqrt(2.0) * 0.5 + 0.5, 0.0, 1.0) * 255));
    quats[s * 4 + 3] = static_cast<uint8_t>(252 + q.largest);
  }
  meta["means"] = {{"mins", {lo[0], lo[1], lo[2]}}, {"maxs", {hi[0], hi[1], hi[2]}},
                   {"files", {"means_l.webp", "means_u.webp"}}};
  entries.push_back({"means_l.webp", encode_webp(means_l, width, height, path)});
  entries.push_back({"means_u.webp", encode_webp(means_u, width, height, path)});
  meta["quats"] = {{"files", {"quats.webp"}}};
  entries.push_back({"quats.webp", encode_webp(quats, width, height, path)});

  // Log scales and SH DC terms: one codebook each over all three axes / channels.
  for (const auto& [name, values] : {std::pair<std::string, const std::vector<float>*>{"scales", &c.log_scales},
                                     {"sh0", &c.sh_dc}}) {
    const auto [book, labels] = codebook(*values);
    std::vector<uint8_t> rgba(texels * 4, 255);
    for (size_t s = 0; s < n; ++s)
      for (int a = 0; a < 3; ++a) rgba[s * 4 + a] = labels[order[s] * 3 + a];
    if (name == "sh0")
      for (size_t s = 0; s < n; ++s)
        rgba[s * 4 + 3] = static_cast<uint8_t>(
            std::lround(255 / (1 + std::exp(-static_cast<double>(c.opacity_logit[order[s]])))));
    meta[name] = {{"codebook", book}, {"files", {name + ".webp"}}};
    entries.push_back({name + ".webp", encode_webp(rgba, width, height, path)});
  }

  if (coefficients > 0 && n > 0) {
    const int dims = 3 * coefficients;  // per splat: the channels' coefficients, PLY order
    const size_t palette = std::min<size_t>(n, kMaxPalette);
    const auto [centres, labels] = sh_palette(c.sh_rest, n, dims, palette);
    const auto [book, indices] = codebook(centres);
    const int rows = static_cast<int>((palette + kPaletteColumns - 1) / kPaletteColumns);
    std::vector<uint8_t> centroid_rgba(size_t(kPaletteColumns) * coefficients * rows * 4, 255);
    for (size_t k = 0; k < palette; ++k)
      for (int j = 0; j < coefficients; ++j)
        for (int ch = 0; ch < 3; ++ch)
          centroid_rgba[((k / kPaletteColumns) * kPaletteColumns * coefficients + (k % kPaletteColumns) * coefficients + j) * 4 +
                        ch] = indices[k * dims + ch * coefficients + j];
    std::vector<uint8_t> label_rgba(texels * 4, 0);
    for (size_t s = 0; s < n; ++s) {
      label_rgba[s * 4] = labels[order[s]] & 0xff;
      label_rgba[s * 4 + 1] = labels[order[s]] >> 8;
      label_rgba[s * 4 + 3] = 255;
    }
    meta["shN"] = {{"count", palette},
                   {"bands", c.sh_degree()},
                   {"codebook", book},
                   {"files", {"shN_centroids.webp", "shN_labels.webp"}}};
    entries.push_back(
        {"shN_centroids.webp", encode_webp(centroid_rgba, kPaletteColumns * coefficients, rows, path)});
    entries.push_back({"shN_labels.webp", encode_webp(label_rgba, width, height, path)});
  }
  const std::string meta_text = meta.dump();
  entries.push_back({"meta.json", std::vector<uint8_t>(meta_text.begin(), meta_text.end())});

  write_file_atomic(path, [&](const fs::path& tmp) {
    int err = 0;
    zip_t* z = zip_open(tmp.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &err);
    if (!z) fail_file(tmp, "cannot create the SOG bundle (libzip error {})", err);
    for (const auto& [name, bytes] : entries) {
      zip_source_t* source = zip_source_buffer(z, bytes.data(), bytes.size(), 0);
      // WebP is compressed already: stored; meta.json deflated.
      if (!source || zip_file_add(z, name.c_str(), source, ZIP_FL_ENC_UTF_8) < 0) {
        if (source) zip_source_free(source);
        const std::string why = zip_strerror(z);
        zip_discard(z);
        fail_file(path, "cannot add {} to the SOG bundle ({})", name, why);
      }
      zip_set_file_compression(z, zip_name_locate(z, name.c_str(), 0), name == "meta.json" ? ZIP_CM_DEFLATE : ZIP_CM_STORE,
                               0);
    }
    if (zip_close(z) != 0) {
      const std::string why = zip_strerror(z);
      zip_discard(z);
      fail_file(path, "cannot write the SOG bundle ({})", why);
    }
  });
}

}  // namespace ii
