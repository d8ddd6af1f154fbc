#pragma once
// PlayCanvas's SOG (version 2; github.com/playcanvas/splat-transform): the splats as lossless
// WebP images, one texel per splat, and a meta.json, bundled in a zip (`x.sog`) or as files
// beside `meta.json`:
//   means_l/means_u  16-bit positions (low/high bytes) on sign(v)·log(1 + |v|), within the
//                    meta's per-axis range;
//   quats            the three smallest components of the unit quaternion (w, x, y, z) × √2,
//                    8 bits each, and 252 + the index of the largest;
//   scales           indices into a 256-entry codebook of log scales;
//   sh0              indices into a 256-entry codebook of SH DC terms, and the opacity;
//   shN_labels/_centroids  a palette of SH coefficient sets (16-bit labels), each coefficient
//                    an index into a 256-entry codebook.
// The writer fits the codebooks with 1D k-means over all values, the SH palette with k-means
// on a sample (up to 4096 entries), and stores the splats in Morton order (morton_order).
#include <cstdint>
#include <filesystem>
#include <vector>

#include "io/ply.h"

namespace ii {

// `x.sog` (a zip) or a `meta.json` with its images beside it. Errors name the file and the problem.
SplatCloud read_sog(const std::filesystem::path& path);

// A `.sog` bundle. Atomic.
void write_sog(const std::filesystem::path& path, const SplatCloud& cloud);

}  // namespace ii
