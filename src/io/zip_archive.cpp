#include "io/zip_archive.h"

#include <zip.h>

#include "common/error.h"

namespace ii {

namespace fs = std::filesystem;

namespace {
// Deflate cannot shrink data more than about 1032:1, so a larger claimed size is a lie
// (and allocating it could exhaust memory).
constexpr uint64_t kMaxDeflateRatio = 1100;
}  // namespace

ZipArchive::ZipArchive(const fs::path& path) : path_(path) {
  int err = 0;
  zip_ = zip_open(path.c_str(), ZIP_RDONLY | ZIP_CHECKCONS, &err);
  if (!zip_) {
    zip_error_t ze;
    zip_error_init_with_code(&ze, err);
    const std::string why = zip_error_strerror(&ze);
    zip_error_fini(&ze);
    fail_file(path, "not a readable zip archive (libzip: {})", why);
  }
  std::error_code ec;
  file_size_ = fs::file_size(path, ec);
  if (ec) file_size_ = 0;
}

ZipArchive::~ZipArchive() { zip_discard(zip_); }

std::vector<std::string> ZipArchive::names() const {
  std::vector<std::string> out;
  const zip_int64_t n = zip_get_num_entries(zip_, 0);
  for (zip_int64_t i = 0; i < n; ++i)
    if (const char* name = zip_get_name(zip_, static_cast<zip_uint64_t>(i), 0)) out.emplace_back(name);
  return out;
}

bool ZipArchive::has(const std::string& name) const { return zip_name_locate(zip_, name.c_str(), 0) >= 0; }

uint64_t ZipArchive::size(const std::string& name) const {
  zip_stat_t st;
  zip_stat_init(&st);
  if (zip_stat(zip_, name.c_str(), 0, &st) != 0) fail_file(path_, "archive has no entry {}", name);
  if (!(st.valid & ZIP_STAT_SIZE) || !(st.valid & ZIP_STAT_COMP_SIZE))
    fail_file(path_, "archive entry {} has no recorded size", name);
  const bool stored = (st.valid & ZIP_STAT_COMP_METHOD) && st.comp_method == ZIP_CM_STORE;
  if ((file_size_ && st.comp_size > file_size_) || (stored && st.size != st.comp_size) ||
      st.size / kMaxDeflateRatio > st.comp_size)
    fail_file(path_, "archive entry {} claims {} bytes from {} stored bytes: corrupt archive", name, st.size,
              st.comp_size);
  return st.size;
}

std::vector<uint8_t> ZipArchive::read(const std::string& name) const {
  const uint64_t n = size(name);
  zip_file_t* f = zip_fopen(zip_, name.c_str(), 0);
  if (!f) fail_file(path_, "cannot open archive entry {} (libzip: {})", name, zip_strerror(zip_));
  std::vector<uint8_t> data(n);
  uint64_t done = 0;
  while (done < n) {
    const zip_int64_t got = zip_fread(f, data.data() + done, n - done);
    if (got <= 0) break;
    done += static_cast<uint64_t>(got);
  }
  // Reading on to the end lets libzip verify the entry's CRC.
  uint8_t extra;
  const zip_int64_t tail = done == n ? zip_fread(f, &extra, 1) : -1;
  const std::string why = zip_file_strerror(f);
  zip_fclose(f);
  if (done != n || tail != 0) fail_file(path_, "archive entry {} is truncated or corrupt (libzip: {})", name, why);
  return data;
}

}  // namespace ii
