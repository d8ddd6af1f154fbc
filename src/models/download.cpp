#include "models/download.h"

#include <curl/curl.h>
#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cmath>
#include <memory>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "common/error.h"
#include "common/stopwatch.h"

namespace ii {

namespace fs = std::filesystem;

std::string get_command(const std::string& name) { return "instainpaint models get " + name; }

namespace {

void init_curl_once() {
  static const bool done = [] { return curl_global_init(CURL_GLOBAL_DEFAULT) == CURLE_OK; }();
  if (!done) fail("libcurl could not be initialised");
}

// One download of a file at a time: an advisory lock on "<file>.lock", released when the
// process ends however it ends. A second process waits (and says so).
class DownloadLock {
 public:
  DownloadLock(const fs::path& lock_file, const std::string& name, bool say) {
    fd_ = ::open(lock_file.c_str(), O_CREAT | O_RDWR | O_CLOEXEC, 0644);
    if (fd_ < 0) fail_file(lock_file.parent_path(), "cannot be written: {}", std::strerror(errno));
    if (::flock(fd_, LOCK_EX | LOCK_NB) == 0) return;
    if (say) std::fprintf(stderr, "%s: another download of it is under way; waiting for it\n", name.c_str());
    while (::flock(fd_, LOCK_EX) != 0)
      if (errno != EINTR) fail_file(lock_file, "cannot be locked: {}", std::strerror(errno));
  }
  ~DownloadLock() { ::close(fd_); }  // closing releases the lock
  DownloadLock(const DownloadLock&) = delete;
  DownloadLock& operator=(const DownloadLock&) = delete;

 private:
  int fd_ = -1;
};

std::string megabytes(double bytes) {
  return bytes < 1e5 ? fmt::format("{:.0f} kB", bytes / 1e3) : fmt::format("{:.1f} MB", bytes / 1e6);
}

std::string duration(double seconds) {
  const long s = std::lround(std::max(0.0, seconds));
  return s >= 3600 ? fmt::format("{}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60) : fmt::format("{}:{:02}", s / 60, s % 60);
}

// The state of one transfer, shared with libcurl's callbacks.
struct Transfer {
  CURL* curl = nullptr;
  std::FILE* out = nullptr;
  std::string name;
  curl_off_t resumed_from = 0;  // bytes already in the partial file when asked to resume
  bool restarted = false;       // the server sent the whole file: the partial file was emptied
  bool checked_answer = false;
  bool bar = false;             // a progress bar on a terminal
  Stopwatch watch;
  double last_draw_ms = -1e9;
  // A transfer with no new byte for stall_ms is abandoned (libcurl's own low-speed check
  // averages over seconds and let a server that stalled after its first bytes hang on).
  double stall_ms = 30000;
  curl_off_t last_bytes = -1;
  double last_byte_ms = 0;
  bool stalled = false;
};

size_t write_body(char* data, size_t size, size_t count, void* user) {
  Transfer& t = *static_cast<Transfer*>(user);
  if (!t.checked_answer) {
    t.checked_answer = true;
    long code = 0;
    curl_easy_getinfo(t.curl, CURLINFO_RESPONSE_CODE, &code);
    if (t.resumed_from > 0 && code == 200) {  // the whole file again: start the partial one afresh
      if (std::fflush(t.out) != 0 || ::ftruncate(::fileno(t.out), 0) != 0 || std::fseek(t.out, 0, SEEK_SET) != 0)
        return 0;
      t.restarted = true;
      t.resumed_from = 0;
    }
  }
  return std::fwrite(data, size, count, t.out) * size;
}

int on_progress(void* user, curl_off_t total, curl_off_t now, curl_off_t, curl_off_t) {
  Transfer& t = *static_cast<Transfer*>(user);
  if (now != t.last_bytes) {
    t.last_bytes = now;
    t.last_byte_ms = t.watch.ms();
  } else if (t.watch.ms() - t.last_byte_ms > t.stall_ms) {
    t.stalled = true;
    return 1;  // abandons the transfer
  }
  if (!t.bar || t.watch.ms() - t.last_draw_ms < 100) return 0;
  t.last_draw_ms = t.watch.ms();
  const double seconds = t.watch.ms() / 1000, rate = seconds > 0 ? now / seconds : 0;
  const double done = static_cast<double>(t.resumed_from + now), all = static_cast<double>(t.resumed_from + total);
  std::string line = fmt::format("\r{}  {}", t.name, megabytes(done));
  if (total > 0) {
    const int width = 24, filled = static_cast<int>(width * done / all);
    line += fmt::format(" / {}  [{}{}] {:3.0f}%", megabytes(all), std::string(filled, '#'), std::string(width - filled, ' '),
                        100 * done / all);
    if (rate > 0) line += fmt::format("  {}/s  {} left", megabytes(rate), duration((total - now) / rate));
  } else if (rate > 0) {
    line += fmt::format("  {}/s", megabytes(rate));
  }
  std::fprintf(stderr, "%s\033[K", line.c_str());
  return 0;
}

// A base URL and a file name: the name percent-encoded ('+' in InstaInpaint's checkpoint).
std::string mirror_url(std::string base, const std::string& file_name) {
  while (!base.empty() && base.back() == '/') base.pop_back();
  std::string name;
  for (const char c : file_name)
    name += std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-' ? std::string(1, c)
                                                                                           : fmt::format("%{:02X}", c);
  return base + "/" + name;
}

uintmax_t size_or_zero(const fs::path& file) {
  std::error_code ec;
  const uintmax_t size = fs::file_size(file, ec);
  return ec ? 0 : size;
}

// One transfer of `url` into `part`, resumed where it holds bytes already. An empty string
// when the whole file arrived, else what went wrong.
std::string transfer(const std::string& url, const fs::path& part, const ModelEntry& entry,
                     const DownloadOptions& options) {
  Transfer t;
  t.name = entry.name;
  t.bar = options.progress && ::isatty(::fileno(stderr));
  t.resumed_from = static_cast<curl_off_t>(size_or_zero(part));
  t.out = std::fopen(part.c_str(), "ab");
  if (!t.out) fail_file(part, "cannot be written: {}", std::strerror(errno));
  std::unique_ptr<CURL, decltype(&curl_easy_cleanup)> curl(curl_easy_init(), curl_easy_cleanup);
  if (!curl) fail("libcurl could not start a transfer");
  t.curl = curl.get();
  char error[CURL_ERROR_SIZE] = "";
  const long timeout_s = std::max(1L, std::lround(options.timeout_s));
  t.stall_ms = 1000.0 * timeout_s;
  CURL* c = curl.get();
  curl_easy_setopt(c, CURLOPT_URL, url.c_str());
  curl_easy_setopt(c, CURLOPT_PROTOCOLS_STR, "http,https");
  curl_easy_setopt(c, CURLOPT_REDIR_PROTOCOLS_STR, "http,https");
  curl_easy_setopt(c, CURLOPT_FOLLOWLOCATION, 1L);
  curl_easy_setopt(c, CURLOPT_MAXREDIRS, 10L);
  curl_easy_setopt(c, CURLOPT_FAILONERROR, 1L);
  curl_easy_setopt(c, CURLOPT_NOSIGNAL, 1L);
  curl_easy_setopt(c, CURLOPT_CONNECTTIMEOUT, timeout_s);
  curl_easy_setopt(c, CURLOPT_USERAGENT, "instainpaint");
  curl_easy_setopt(c, CURLOPT_ERRORBUFFER, error);
  curl_easy_setopt(c, CURLOPT_WRITEFUNCTION, write_body);
  curl_easy_setopt(c, CURLOPT_WRITEDATA, &t);
  curl_easy_setopt(c, CURLOPT_NOPROGRESS, 0L);
  curl_easy_setopt(c, CURLOPT_XFERINFOFUNCTION, on_progress);
  curl_easy_setopt(c, CURLOPT_XFERINFODATA, &t);
  if (t.resumed_from > 0) curl_easy_setopt(c, CURLOPT_RESUME_FROM_LARGE, t.resumed_from);
  const CURLcode result = curl_easy_perform(c);
  const bool closed = std::fclose(t.out) == 0;
  if (t.bar) std::fprintf(stderr, "\r\033[K");
  long code = 0;
  curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &code);
  if (result == CURLE_OK) return closed ? "" : fmt::format("{}: write error", part.string());
  const uintmax_t bytes = size_or_zero(part);
  const std::string got = bytes ? " (" + megabytes(static_cast<double>(bytes)) + " received)" : "";
  // Nothing left to send after the partial file: it is whole already (the check decides).
  if (result == CURLE_HTTP_RETURNED_ERROR && code == 416 && t.resumed_from > 0) return "";
  if (result == CURLE_HTTP_RETURNED_ERROR) return fmt::format("{}: HTTP {}", url, code);
  if (result == CURLE_OPERATION_TIMEDOUT || t.stalled)
    return fmt::format("{}: nothing arrived for {} s{}", url, timeout_s, got);
  if (result == CURLE_WRITE_ERROR) return fmt::format("{}: cannot be written ({})", part.string(), std::strerror(errno));
  return fmt::format("{}: {}{}", url, *error ? error : curl_easy_strerror(result), got);
}

}  // namespace

CachedModel download_model(const ModelEntry& entry, const DownloadOptions& options) {
  init_curl_once();
  const fs::path dir = make_models_dir();
  std::error_code ec;
  const DownloadLock lock(dir / (entry.file_name + ".lock"), entry.name, options.progress);
  if (const auto done = cached_model(entry)) return *done;  // there already, or fetched while we waited

  std::string mirror = options.mirror;
  if (const char* env = std::getenv("INSTAINPAINT_MODELS_MIRROR"); mirror.empty() && env) mirror = env;
  const std::vector<std::string> urls =
      mirror.empty() ? entry.urls : std::vector{mirror_url(mirror, published_name(entry))};
  const fs::path part = dir / (entry.file_name + ".part");
  std::vector<std::string> failures;
  for (const std::string& url : urls) {
    Stopwatch watch;
    const uintmax_t resumed = size_or_zero(part);
    if (const std::string why = transfer(url, part, entry, options); !why.empty()) {
      failures.push_back(why);
      if (size_or_zero(part) == 0) fs::remove(part, ec);
      continue;
    }
    FileCheck check;
    check.digests = digests_of_file(part);
    check.pinned = entry.pinned();
    if (const std::string why = published_mismatch(entry, check.digests); !why.empty()) {
      fs::remove(part, ec);  // not the published file: never kept, never resumed
      failures.push_back(fmt::format("{}: not the published file: {}; deleted", url, why));
      continue;
    }
    CachedModel m;
    if (entry.archive_member.empty()) {
      m = install_checked(entry, part, check, url);
    } else {  // the member kept, the archive not
      try {
        m = install_archive_member(entry, part, check, url);
      } catch (const Error& e) {
        fs::remove(part, ec);
        failures.push_back(fmt::format("{}: {}; deleted", url, e.what()));
        continue;
      }
      fs::remove(part, ec);
    }
    if (options.progress) {
      const double seconds = watch.ms() / 1000;
      std::fprintf(stderr, "%s: %s%s in %.1f s (%s/s), %s\n", entry.name.c_str(), megabytes(m.size).c_str(),
                   resumed > 0 ? fmt::format(" (resumed at {})", megabytes(resumed)).c_str() : "", seconds,
                   megabytes((m.size - resumed) / std::max(seconds, 1e-3)).c_str(),
                   check.pinned ? ("matches the checksum " + entry.checksum_publisher() + " publishes").c_str()
                                : "not pinned: its SHA-256 recorded");
    }
    return m;
  }
  std::string message = fmt::format("{}: the download failed: ", entry.name);
  for (size_t i = 0; i < failures.size(); ++i) message += (i ? "; " : "") + failures[i];
  if (size_or_zero(part) > 0)
    message += fmt::format(". {} of it is kept; the same command resumes it", megabytes(size_or_zero(part)));
  throw Error(message);
}

}  // namespace ii
