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

// A whole file's bytes, mapped read-only: large files (checkpoints) are read from the page
// cache without a copy into fresh memory. Files that cannot be mapped (pipes) are read
// instead. The same errors as read_file_bytes.
class MappedFile {
 public:
  // `populate`: the kernel reads the whole file in at once (MAP_POPULATE), for a reader that
  // goes through all of it: one call instead of a page fault every 4 kB.
  explicit MappedFile(const std::filesystem::path& path, bool populate = false);
  ~MappedFile();
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  const uint8_t* data() const { return data_; }
  size_t size() const { return size_; }

 private:
  const uint8_t* data_ = nullptr;
  size_t size_ = 0;
  bool mapped_ = false;
  std::vector<uint8_t> read_;  // when not mapped
};

// Calls `write(stream_path)` to fill a temporary file, then renames it to `path`.
// If `write` throws, the temporary is removed and `path` is untouched.
void write_file_atomic(const std::filesystem::path& path,
                       const std::function<void(const std::filesystem::path& tmp)>& write);
void write_file_atomic(const std::filesystem::path& path, std::string_view bytes);
// Whether `file` is the temporary of a write_file_atomic that a killed process left behind.
bool is_atomic_write_leftover(const std::filesystem::path& file);

// A fresh folder of its own in the system's temporary folder ($TMPDIR), removed with all it
// holds when the object goes.
class TemporaryFolder {
 public:
  explicit TemporaryFolder(const std::string& prefix);
  ~TemporaryFolder();
  TemporaryFolder(const TemporaryFolder&) = delete;
  TemporaryFolder& operator=(const TemporaryFolder&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

}  // namespace ii
