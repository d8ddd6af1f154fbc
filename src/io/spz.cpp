#include "io/spz.h"

#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <functional>
#include <string>

#include "common/error.h"
#include "common/files.h"
#include "io/byte_reader.h"
#include "io/splat_quantize.h"
#include "io/half.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

constexpr uint32_t kMagic = 0x5053474e;  // "NGSP"
constexpr uint32_t kLatestVersion = 4, kWrittenVersion = 3;
constexpr double kColourScale = 0.15;  // SPZ's colour byte = dc * 0.15 * 255 + 127.5
constexpr int kMaxDegree = 4;
constexpr double kSqrtHalf = 0.70710678118654752;
// Bits kept of each 8-bit SH coefficient: degree 1, and degrees 2-3 (the rest rounded to the
// centre of its bucket, which gzip then compresses well).
constexpr int kSh1Bits = 8, kShRestBits = 8;

int sh_coefficients(int degree) { return (degree + 1) * (degree + 1) - 1; }  // per channel, DC excluded

// Byte counts of each attribute stream for n splats, in file order: positions, alphas,
// colours, scales, rotations, SH.
std::array<uint64_t, 6> stream_sizes(uint64_t n, uint32_t version, int degree) {
  return {n * 3 * (version == 1 ? 2 : 3), n, n * 3, n * 3, n * (version >= 3 ? 4 : 3),
          n * 3 * static_cast<uint64_t>(sh_coefficients(degree))};
}

// gzip-inflates at most `limit` bytes (what the header says the splats need; anything after
// them, SPZ's extensions, is not needed). `limit_of` is asked once the first `header` bytes are out.
std::vector<uint8_t> gunzip(const uint8_t* data, size_t size, size_t header,
                            const std::function<size_t(const std::vector<uint8_t>&)>& limit_of, const fs::path& name) {
  struct Inflater {
    z_stream s{};
    ~Inflater() { inflateEnd(&s); }
  } z;
  z_stream& s = z.s;
  if (inflateInit2(&s, 16 + MAX_WBITS) != Z_OK) fail_file(name, "cannot start gzip decompression");
  std::vector<uint8_t> out;
  size_t limit = header;
  bool limited = false;
  s.next_in = const_cast<Bytef*>(data);
  s.avail_in = static_cast<uInt>(std::min<size_t>(size, UINT32_MAX));
  while (out.size() < limit) {
    const size_t have = out.size();
    // Grow with the data, not with what the header claims: a lying header costs nothing.
    out.resize(std::min(limit, std::max<size_t>(have * 2, 1 << 16)));
    s.next_out = out.data() + have;
    s.avail_out = static_cast<uInt>(std::min<size_t>(out.size() - have, UINT32_MAX));
    const int status = inflate(&s, Z_NO_FLUSH);
    out.resize(out.size() - s.avail_out);
    if (status != Z_OK && status != Z_STREAM_END && status != Z_BUF_ERROR)
      fail_file(name, "not a valid gzip stream ({})", s.msg ? s.msg : "corrupt data");
    if (!limited && out.size() >= header) {
      limit = limit_of(out);
      limited = true;
    }
    if (status == Z_STREAM_END || (status == Z_BUF_ERROR && s.avail_in == 0)) break;
  }
  return out;
}

// zstd-decompresses one stream that must hold `expected` bytes, the buffer growing with the
// data (a lying size costs nothing).
std::vector<uint8_t> unzstd(const uint8_t* data, size_t size, uint64_t expected, const fs::path& name,
                            const char* what) {
  struct Stream {
    ZSTD_DStream* s = ZSTD_createDStream();
    ~Stream() { ZSTD_freeDStream(s); }
  } z;
  if (!z.s) fail_file(name, "cannot start zstd decompression");
  std::vector<uint8_t> out;
  if (expected == 0) return out;  // no splats: nothing to check the stream against
  ZSTD_inBuffer in{data, size, 0};
  size_t status = 1;
  while (out.size() < expected) {
    const size_t have = out.size();
    out.resize(static_cast<size_t>(std::min<uint64_t>(expected, std::max<size_t>(have * 2, 1 << 16))));
    ZSTD_outBuffer o{out.data() + have, out.size() - have, 0};
    status = ZSTD_decompressStream(z.s, &o, &in);
    out.resize(have + o.pos);
    if (ZSTD_isError(status))
      fail_file(name, "SPZ {} stream is not valid zstd data ({})", what, ZSTD_getErrorName(status));
    if (o.pos == 0 && in.pos == in.size) break;  // no more input, no more output
  }
  if (out.size() < expected)
    fail_file(name, "SPZ {} stream ends after {} of its {} bytes", what, out.size(), expected);
  if (status != 0) fail_file(name, "SPZ {} stream holds more than the {} bytes its table of contents says", what, expected);
  return out;
}

struct SpzHeader {
  uint32_t version = 0, points = 0;
  int degree = 0, fractional_bits = 0;
};

SpzHeader check_header(uint32_t magic, uint32_t version, uint32_t points, uint8_t degree, uint8_t fractional_bits,
                    const fs::path& name) {
  if (magic != kMagic) fail_file(name, "not an SPZ file (magic 0x{:08x}, expected 0x{:08x})", magic, kMagic);
  if (version < 1 || version > kLatestVersion)
    fail_file(name, "SPZ version {} is not supported (1 to {})", version, kLatestVersion);
  if (degree > kMaxDegree) fail_file(name, "SPZ SH degree {} is not supported (0 to {})", degree, kMaxDegree);
  if (fractional_bits > 23) fail_file(name, "SPZ fractional bits {} do not fit 24-bit positions", fractional_bits);
  return {version, points, degree, fractional_bits};
}

// The splats from the six attribute streams.
SplatCloud unpack(const SpzHeader& h, const std::array<const uint8_t*, 6>& streams, const fs::path& name) {
  const size_t n = h.points;
  const auto [positions, alphas, colours, scales, rotations, sh] = streams;
  const int file_coefficients = sh_coefficients(h.degree);
  const int kept = std::min(file_coefficients, sh_coefficients(3));
  SplatCloud c;
  c.resize(n, kept);

  const float unit = std::ldexp(1.f, -h.fractional_bits);
  for (size_t i = 0; i < n * 3; ++i) {
    if (h.version == 1) {
      uint16_t half;
      std::memcpy(&half, positions + i * 2, 2);
      c.means[i] = half_to_float(half);
      if (!std::isfinite(c.means[i])) fail_file(name, "SPZ splat {} has a position that is not finite", i / 3);
    } else {
      const uint8_t* p = positions + i * 3;
      int32_t fixed = p[0] | (p[1] << 8) | (p[2] << 16);
      if (fixed & 0x800000) fixed -= 1 << 24;  // sign of the 24-bit value
      c.means[i] = static_cast<float>(fixed) * unit;
    }
    c.sh_dc[i] = static_cast<float>((colours[i] / 255.0 - 0.5) / kColourScale);
    c.log_scales[i] = scales[i] / 16.f - 10.f;
  }
  for (size_t i = 0; i < n; ++i) {
    c.opacity_logit[i] = splat_quantize::opacity_logit_of_byte(alphas[i]);
    float q[4];  // x, y, z, w
    if (h.version >= 3) {
      const uint8_t* r = rotations + i * 4;
      uint32_t packed = r[0] | (r[1] << 8) | (r[2] << 16) | (static_cast<uint32_t>(r[3]) << 24);
      const int largest = static_cast<int>(packed >> 30);
      double sum = 0;
      for (int k = 3; k >= 0; --k) {
        if (k == largest) continue;
        const double magnitude = kSqrtHalf * (packed & 511u) / 511.0;
        q[k] = static_cast<float>((packed >> 9) & 1u ? -magnitude : magnitude);
        sum += q[k] * q[k];
        packed >>= 10;
      }
      q[largest] = static_cast<float>(std::sqrt(std::max(0.0, 1 - sum)));
    } else {
      const uint8_t* r = rotations + i * 3;
      double sum = 0;
      for (int k = 0; k < 3; ++k) {
        q[k] = static_cast<float>(r[k] / 127.5 - 1);
        sum += q[k] * q[k];
      }
      q[3] = static_cast<float>(std::sqrt(std::max(0.0, 1 - sum)));
    }
    float* rot = &c.rotations[i * 4];  // PLY order: w, x, y, z
    rot[0] = q[3];
    rot[1] = q[0];
    rot[2] = q[1];
    rot[3] = q[2];
    // SPZ: coefficient-major, colour inner; PLY: per channel, all its coefficients.
    for (int j = 0; j < kept; ++j)
      for (int ch = 0; ch < 3; ++ch)
        c.sh_rest[i * 3 * kept + ch * kept + j] = (sh[(i * file_coefficients + j) * 3 + ch] - 128.f) / 128.f;
  }
  return c;
}

SplatCloud decode_gzip(const uint8_t* data, size_t size, const fs::path& name) {
  constexpr size_t kHeaderBytes = 16;
  SpzHeader h;
  const std::vector<uint8_t> body = gunzip(
      data, size, kHeaderBytes,
      [&](const std::vector<uint8_t>& head) {
        ByteReader r(head.data(), head.size(), name);
        const uint32_t magic = r.read<uint32_t>("magic"), version = r.read<uint32_t>("version"),
                       points = r.read<uint32_t>("splat count");
        const uint8_t degree = r.read<uint8_t>("SH degree"), bits = r.read<uint8_t>("fractional bits");
        h = check_header(magic, version, points, degree, bits, name);
        if (version == 4) fail_file(name, "SPZ version 4 must not be gzip-compressed");
        uint64_t total = kHeaderBytes;
        for (uint64_t s : stream_sizes(h.points, h.version, h.degree)) total += s;
        return static_cast<size_t>(total);
      },
      name);
  if (body.size() < kHeaderBytes) fail_file(name, "truncated SPZ file: {} bytes, shorter than its header", body.size());
  std::array<const uint8_t*, 6> streams;
  size_t at = kHeaderBytes;
  const auto sizes = stream_sizes(h.points, h.version, h.degree);
  static constexpr const char* kNames[6] = {"positions", "opacities", "colours", "scales", "rotations", "SH"};
  for (int k = 0; k < 6; ++k) {
    if (body.size() - at < sizes[k])
      fail_file(name, "truncated SPZ file: its {} splats need {} bytes of {}, {} are left", h.points, sizes[k],
                kNames[k], body.size() - at);
    streams[k] = body.data() + at;
    at += sizes[k];
  }
  return unpack(h, streams, name);
}

SplatCloud decode_zstd(const uint8_t* data, size_t size, const fs::path& name) {
  ByteReader r(data, size, name);
  const uint32_t magic = r.read<uint32_t>("magic"), version = r.read<uint32_t>("version"),
                 points = r.read<uint32_t>("splat count");
  const uint8_t degree = r.read<uint8_t>("SH degree"), bits = r.read<uint8_t>("fractional bits");
  r.skip(1, "flags");
  const uint8_t stream_count = r.read<uint8_t>("stream count");
  const uint32_t toc = r.read<uint32_t>("table of contents offset");
  const SpzHeader h = check_header(magic, version, points, degree, bits, name);
  if (version < 4) fail_file(name, "SPZ version {} must be gzip-compressed, not a plain header", version);
  if (stream_count < 5 || stream_count > 6)
    fail_file(name, "SPZ file has {} attribute streams, expected 6 (5 without SH)", stream_count);
  if (toc < 32) fail_file(name, "SPZ table of contents at byte {} overlaps the 32-byte header", toc);
  r.seek(toc, "the table of contents");
  std::array<uint64_t, 6> compressed{}, plain{};
  for (int k = 0; k < stream_count; ++k) {
    compressed[k] = r.read<uint64_t>("a compressed stream size");
    plain[k] = r.read<uint64_t>("a stream size");
  }
  const auto sizes = stream_sizes(h.points, h.version, h.degree);
  static constexpr const char* kNames[6] = {"positions", "opacities", "colours", "scales", "rotations", "SH"};
  std::array<std::vector<uint8_t>, 6> decoded;
  std::array<const uint8_t*, 6> streams;
  for (int k = 0; k < 6; ++k) {
    if (k >= stream_count) {
      if (sizes[k] != 0) fail_file(name, "SPZ file has no {} stream", kNames[k]);
      streams[k] = nullptr;
      continue;
    }
    if (plain[k] != sizes[k])
      fail_file(name, "SPZ {} stream holds {} bytes; {} splats need {}", kNames[k], plain[k], h.points, sizes[k]);
    r.require(compressed[k], kNames[k]);
    decoded[k] = unzstd(r.current(), compressed[k], plain[k], name, kNames[k]);
    r.skip(compressed[k], kNames[k]);
    streams[k] = decoded[k].data();
  }
  return unpack(h, streams, name);
}

uint8_t to_byte(double x) { return static_cast<uint8_t>(std::clamp(std::round(x), 0.0, 255.0)); }

std::vector<uint8_t> gzip(const std::vector<uint8_t>& plain, const fs::path& name) {
  z_stream s{};
  if (deflateInit2(&s, Z_DEFAULT_COMPRESSION, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY) != Z_OK)
    fail_file(name, "cannot start gzip compression");
  std::vector<uint8_t> out(deflateBound(&s, static_cast<uLong>(plain.size())));
  s.next_in = const_cast<Bytef*>(plain.data());
  s.avail_in = static_cast<uInt>(plain.size());
  s.next_out = out.data();
  s.avail_out = static_cast<uInt>(out.size());
  const int status = deflate(&s, Z_FINISH);
  out.resize(out.size() - s.avail_out);
  deflateEnd(&s);
  if (status != Z_STREAM_END) fail_file(name, "gzip compression failed");
  return out;
}

}  // namespace

SplatCloud decode_spz(const uint8_t* data, size_t size, const fs::path& name) {
  if (size >= 2 && data[0] == 0x1f && data[1] == 0x8b) return decode_gzip(data, size, name);
  if (size >= 4 && std::memcmp(data, "NGSP", 4) == 0) return decode_zstd(data, size, name);
  fail_file(name, "not an SPZ file: neither gzip-compressed (versions 1-3) nor starting with NGSP (version 4)");
}

SplatCloud read_spz(const fs::path& path) {
  const MappedFile file(path);
  return decode_spz(file.data(), file.size(), path);
}

std::vector<uint8_t> encode_spz(const SplatCloud& c, const fs::path& name) {
  check_splat_cloud(c, name);
  const size_t n = c.size();
  if (n > UINT32_MAX) fail_file(name, "{} splats are more than SPZ can hold", n);
  const int degree = c.sh_degree();
  if (degree < 0)
    fail_file(name, "{} SH coefficients per channel are no SH degree (3, 8 or 15 expected)", c.sh_rest_per_channel);
  // Fixed point: as many fractional bits as the extent allows, at most SPZ's usual 12.
  double largest = 0;
  for (float v : c.means) {
    if (!std::isfinite(v)) fail_file(name, "a splat position is not finite: SPZ cannot store it");
    largest = std::max(largest, std::abs(static_cast<double>(v)));
  }
  int bits = 12;
  while (bits > 0 && std::round(largest * std::ldexp(1.0, bits)) > (1 << 23) - 1) --bits;
  if (std::round(largest * std::ldexp(1.0, bits)) > (1 << 23) - 1)
    fail_file(name, "a splat position ({}) is too far from the origin for SPZ's 24-bit positions", largest);

  const auto sizes = stream_sizes(n, kWrittenVersion, degree);
  std::vector<uint8_t> plain(16);
  const uint32_t head[3] = {kMagic, kWrittenVersion, static_cast<uint32_t>(n)};
  std::memcpy(plain.data(), head, sizeof head);
  plain[12] = static_cast<uint8_t>(degree);
  plain[13] = static_cast<uint8_t>(bits);
  size_t at = plain.size();
  std::array<uint8_t*, 6> stream;
  size_t total = 0;
  for (uint64_t s : sizes) total += s;
  plain.resize(plain.size() + total);
  for (int k = 0; k < 6; ++k) {
    stream[k] = plain.data() + at;
    at += sizes[k];
  }
  const int coefficients = c.sh_rest_per_channel;
  const double unit = std::ldexp(1.0, bits);
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      const int32_t fixed = static_cast<int32_t>(std::round(c.means[i * 3 + a] * unit));
      uint8_t* p = stream[0] + (i * 3 + a) * 3;
      p[0] = fixed & 0xff;
      p[1] = (fixed >> 8) & 0xff;
      p[2] = (fixed >> 16) & 0xff;
      stream[2][i * 3 + a] = to_byte(c.sh_dc[i * 3 + a] * kColourScale * 255 + 127.5);
      stream[3][i * 3 + a] = to_byte((c.log_scales[i * 3 + a] + 10) * 16);
    }
    stream[1][i] = to_byte(255 / (1 + std::exp(-static_cast<double>(c.opacity_logit[i]))));
    // PLY's (w, x, y, z) to SPZ's (x, y, z, w); the largest component left out, the others as
    // sign + 9 bits of |q| / √½.
    const splat_quantize::SmallestThree q = splat_quantize::smallest_three(&c.rotations[i * 4]);
    const int largest = (q.largest + 3) % 4;  // in x, y, z, w
    uint32_t packed = static_cast<uint32_t>(largest);
    for (int k = 0; k < 4; ++k) {
      if (k == largest) continue;
      const double v = q.q[(k + 1) % 4];
      const uint32_t magnitude = std::min<uint32_t>(511, static_cast<uint32_t>(511 * std::abs(v) / kSqrtHalf + 0.5));
      packed = (packed << 10) | (v < 0 ? 1u << 9 : 0u) | magnitude;
    }
    std::memcpy(stream[4] + i * 4, &packed, 4);
    // SH: 8 bits centred at 128 (x 128), rounded to buckets of the bits kept.
    for (int j = 0; j < coefficients; ++j)
      for (int ch = 0; ch < 3; ++ch) {
        const int bucket = 1 << (8 - (j < 3 ? kSh1Bits : kShRestBits));
        int v = static_cast<int>(std::round(c.sh_rest[i * 3 * coefficients + ch * coefficients + j] * 128.0) + 128);
        v = (v + bucket / 2) / bucket * bucket;
        stream[5][(i * coefficients + j) * 3 + ch] = static_cast<uint8_t>(std::clamp(v, 0, 255));
      }
  }
  return gzip(plain, name);
}

void write_spz(const fs::path& path, const SplatCloud& cloud) {
  const std::vector<uint8_t> bytes = encode_spz(cloud, path);
  write_file_atomic(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

}  // namespace ii
