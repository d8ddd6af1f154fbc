#pragma once
// 3D Gaussian splat PLY files: the standard layout of the reference 3DGS code and viewers
// (read and write) and the SuperSplat/PlayCanvas "compressed PLY" layout (read).
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

namespace ii {

// The degree-0 spherical harmonic Y_0^0: a splat's colour from its DC term is 0.5 + kSh0 * dc.
constexpr double kSh0 = 0.28209479177387814;
// A channel's colour from its DC term, and back.
constexpr double colour_of_dc(double dc) { return 0.5 + kSh0 * dc; }
constexpr double dc_of_colour(double colour) { return (colour - 0.5) / kSh0; }

// Pre-activation values, as the reference 3DGS code stores them.
struct SplatCloud {
  std::vector<float> means;          // N*3
  std::vector<float> normals;        // N*3 (usually zero; kept for round trips; may be empty on write)
  std::vector<float> sh_dc;          // N*3, f_dc_0..2; colour = 0.5 + kSh0 * dc
  std::vector<float> sh_rest;        // N*3*K as in the file: per splat, all R coefficients, then G, then B
  int sh_rest_per_channel = 0;       // K = 0, 3, 8 or 15
  std::vector<float> opacity_logit;  // N
  std::vector<float> log_scales;     // N*3
  std::vector<float> rotations;      // N*4, (w, x, y, z) = rot_0..3, not necessarily normalised

  size_t size() const { return opacity_logit.size(); }
  // Room for n splats with `rest` SH coefficients per channel (normals left empty).
  void resize(size_t n, int rest) {
    means.resize(n * 3);
    sh_dc.resize(n * 3);
    sh_rest_per_channel = rest;
    sh_rest.resize(n * 3 * static_cast<size_t>(rest));
    opacity_logit.resize(n);
    log_scales.resize(n * 3);
    rotations.resize(n * 4);
  }
  // 0-3 from sh_rest_per_channel (0, 3, 8, 15); -1 for any other count.
  int sh_degree() const {
    for (int d = 0; d <= 3; ++d)
      if ((d + 1) * (d + 1) - 1 == sh_rest_per_channel) return d;
    return -1;
  }
};

// Reads a binary little-endian or ASCII standard PLY (properties in any order and of any
// scalar type, unknown properties and elements ignored), or a compressed PLY (detected from
// its packed_* vertex properties). Compressed data is decoded as PlayCanvas does: positions
// and log-scales lerped within their chunk's range, rotations from "largest component
// dropped" 2+10+10+10 bits, colours to f_dc, 8-bit opacity to a logit (0 and 255 map to
// -40 and +40), 8-bit SH to the centre of their quantisation bin.
SplatCloud read_splat_ply(const std::filesystem::path& path);
// Errors naming `path` when the cloud's arrays do not hold the same number of splats.
void check_splat_cloud(const SplatCloud& cloud, const std::filesystem::path& path);
// Binary little-endian standard layout: x y z nx ny nz f_dc_0..2 f_rest_* opacity
// scale_0..2 rot_0..3, all float. Atomic.
void write_splat_ply(const std::filesystem::path& path, const SplatCloud& cloud);
// SuperSplat's compressed PLY (what read_splat_ply reads back): the splats in Morton order of
// their positions (morton_order), in chunks of 256 with per-chunk ranges; 11/10/11-bit
// positions and log scales, 2+3x10-bit rotations, 8-bit colours and opacity, 8-bit SH. Atomic.
void write_compressed_splat_ply(const std::filesystem::path& path, const SplatCloud& cloud);
// The file's bytes in memory (a server sends them before they are on disk); `name` only names
// the splats in error messages.
std::string encode_compressed_splat_ply(const SplatCloud& cloud, const std::filesystem::path& name);
// The order write_compressed_splat_ply stores splats in: by the Morton code of their position
// (10 bits per axis within the bounding box), ties in index order.
std::vector<size_t> morton_order(const std::vector<float>& means);

}  // namespace ii
