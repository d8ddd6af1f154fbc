#pragma once
// A file's SHA-256 (OpenSSL), as `sha256sum` prints it: what run.json records of a model file
// so that a result names the exact weights that made it.
#include <filesystem>
#include <string>

namespace ii {

// 64 lower-case hex digits; an Error naming the file when it cannot be read.
std::string sha256_of_file(const std::filesystem::path& path);

}  // namespace ii
