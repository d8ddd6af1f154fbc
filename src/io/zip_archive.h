#pragma once
// Read-only zip archives (libzip) whose entries are checked before they are read: sizes
// against what deflate can produce, CRCs at the end, so a corrupt or lying archive is an Error
// naming the file and the entry. PyTorch checkpoints (.pth) and SOG bundles are zips.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

struct zip;

namespace ii {

class ZipArchive {
 public:
  explicit ZipArchive(const std::filesystem::path& path);
  ~ZipArchive();
  ZipArchive(const ZipArchive&) = delete;
  ZipArchive& operator=(const ZipArchive&) = delete;

  std::vector<std::string> names() const;
  bool has(const std::string& name) const;
  // The entry's uncompressed size, checked against what its compressed size makes possible.
  uint64_t size(const std::string& name) const;
  std::vector<uint8_t> read(const std::string& name) const;

 private:
  std::filesystem::path path_;
  struct zip* zip_ = nullptr;
  uint64_t file_size_ = 0;
};

}  // namespace ii
