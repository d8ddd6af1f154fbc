#pragma once
// Niantic's SPZ splat files (github.com/nianticlabs/spz): a header and the splats attribute
// by attribute: 24-bit fixed-point positions, 8-bit opacities, colours (the SH DC term),
// log scales and SH coefficients, and rotations (version 2: x, y, z as 8 bits; version 3 and
// later: the three smallest quaternion components, 10 bits each). Versions 1-3 are one gzip
// stream; version 4 has a plain 32-byte header and one zstd stream per attribute.
//
// Coordinates are kept as they are (no axis flips), as Niantic's ply_to_spz and Spark do, so a
// PLY and the SPZ made from it show the same scene the same way up. SH degree 4 (SPZ allows
// it) is read without its fourth band: the renderer goes to degree 3.
#include <cstdint>
#include <filesystem>
#include <vector>

#include "io/ply.h"

namespace ii {

// Versions 1-4. Errors name the file and the problem (not SPZ, truncated, inconsistent counts).
SplatCloud read_spz(const std::filesystem::path& path);
SplatCloud decode_spz(const uint8_t* data, size_t size, const std::filesystem::path& name);

// Version 3 (gzip, what viewers read), 12 fractional bits for positions unless the cloud's
// extent needs fewer; SH with all 8 bits (Niantic's library keeps 5 and 4 by default: on a
// refined statue with SH 3 that costs 18 dB of render PSNR for 23 % fewer bytes,
// docs/benchmarks.md, "Splat file formats"). Atomic.
std::vector<uint8_t> encode_spz(const SplatCloud& cloud, const std::filesystem::path& name);
void write_spz(const std::filesystem::path& path, const SplatCloud& cloud);

}  // namespace ii
