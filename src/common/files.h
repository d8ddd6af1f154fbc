#pragma once
// Whole-file reads and atomic writes. Atomic = write to a temporary file in the same
// folder, flush to disk, then rename over the target: a crash or kill mid-write leaves
// either the old file or the new one, never a truncated mix.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace ii {

std::vector<uint8_t> read_file_bytes(const std::filesystem::path& path);
std::string read_file_text(const std::filesystem::path& path);

// Calls `write(stream_path)` to fill a temporary file, then renames it to `path`.
// If `write` throws, the temporary is removed and `path` is untouched.
void write_file_atomic(const std::filesystem::path& path,
                       const std::function<void(const std::filesystem::path& tmp)>& write);
void write_file_atomic(const std::filesystem::path& path, std::string_view bytes);
// Whether `file` is the temporary of a write_file_atomic that a killed process left behind.
bool is_atomic_write_leftover(const std::filesystem::path& file);

}  // namespace ii
