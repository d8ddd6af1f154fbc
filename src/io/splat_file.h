#pragma once
// Splat files by name: what `infer`, `render`, `serve` and `convert` read and write.
//   x.ply             standard 3DGS PLY (float; read: also compressed PLY, detected by content)
//   x.compressed.ply  SuperSplat's compressed PLY
//   x.spz             Niantic's SPZ
//   x.sog             PlayCanvas's SOG bundle (read: also a meta.json with its images beside it)
#include <filesystem>
#include <string>

#include "io/ply.h"

namespace ii {

enum class SplatFormat { Ply, CompressedPly, Spz, Sog };

// From the file name; an Error naming the file and the formats otherwise.
SplatFormat splat_format_of(const std::filesystem::path& path);
std::string splat_format_name(SplatFormat format);  // "PLY", "compressed PLY", "SPZ", "SOG"
// Whether the name is one of a splat file (for commands that take several kinds of file).
bool is_splat_file_name(const std::filesystem::path& path);

SplatCloud read_splats(const std::filesystem::path& path);
// Atomic, in the format of the name.
void write_splats(const std::filesystem::path& path, const SplatCloud& cloud);

}  // namespace ii
