#pragma once
// A file's SHA-256 and MD5 (OpenSSL), as `sha256sum` / `md5sum` print them: what run.json records
// of a model file so that a result names the exact weights that made it, and what a downloaded
// network is checked against (its authors or IOPaint publish one or the other).
#include <filesystem>
#include <string>

namespace ii {

// 64 lower-case hex digits; an Error naming the file when it cannot be read.
std::string sha256_of_file(const std::filesystem::path& path);

struct FileDigests {
  std::string sha256, md5;  // lower-case hex
  uintmax_t size = 0;
};
// Both digests in one pass over the file.
FileDigests digests_of_file(const std::filesystem::path& path);

}  // namespace ii
