#include "models/cache.h"

#include <chrono>
#include <cstdlib>
#include <ctime>

#include "common/error.h"
#include "common/files.h"
#include "io/zip_archive.h"
#include "models/download.h"

namespace ii {

namespace fs = std::filesystem;
using json = nlohmann::json;

fs::path models_dir() {
  if (const char* dir = std::getenv("INSTAINPAINT_MODELS_DIR"); dir && *dir) return dir;
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg) return fs::path(xdg) / "instainpaint" / "models";
  if (const char* home = std::getenv("HOME"); home && *home) return fs::path(home) / ".cache" / "instainpaint" / "models";
  fail("the models' folder: neither INSTAINPAINT_MODELS_DIR, XDG_CACHE_HOME nor HOME is set");
}

fs::path cached_file(const ModelEntry& entry) { return models_dir() / entry.file_name; }
fs::path record_file(const ModelEntry& entry) { return models_dir() / (entry.file_name + ".record.json"); }

namespace {

int64_t modified_ns(const fs::path& file) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(fs::last_write_time(file).time_since_epoch()).count();
}

std::string utc_now() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return text;
}

// The record of the entry's file: nullopt when there is none or it cannot be read (the file
// is then "not checked", which `verify` mends).
std::optional<json> read_record(const ModelEntry& entry) {
  std::error_code ec;
  if (!fs::exists(record_file(entry), ec)) return std::nullopt;
  try {
    json j = json::parse(read_file_text(record_file(entry)), nullptr, false);
    if (!j.is_object() || !j.contains("sha256") || !j["sha256"].is_string() || !j.contains("size") ||
        !j["size"].is_number_unsigned() || !j.contains("modified_ns") || !j["modified_ns"].is_number_integer())
      return std::nullopt;
    for (const char* text : {"md5", "origin", "checked_at"})
      if (j.contains(text) && !j[text].is_string()) return std::nullopt;
    if (j.contains("pinned") && !j["pinned"].is_boolean()) return std::nullopt;
    return j;
  } catch (const Error&) {
    return std::nullopt;
  }
}

CachedModel from_record(const ModelEntry& entry, const json& r) {
  CachedModel m;
  m.name = entry.name;
  m.file = cached_file(entry);
  m.sha256 = r.value("sha256", "");
  m.md5 = r.value("md5", "");
  m.size = r.value("size", uintmax_t{0});
  m.pinned = r.value("pinned", false);
  m.origin = r.value("origin", "");
  m.checked_at = r.value("checked_at", "");
  return m;
}

CachedModel write_record(const ModelEntry& entry, const FileCheck& check, const std::string& origin) {
  const fs::path file = cached_file(entry);
  const json r = {{"name", entry.name},          {"file", entry.file_name},      {"sha256", check.digests.sha256},
                  {"md5", check.digests.md5},     {"size", check.digests.size},   {"modified_ns", modified_ns(file)},
                  {"pinned", check.pinned},       {"origin", origin},             {"checked_at", utc_now()}};
  write_file_atomic(record_file(entry), r.dump(2) + "\n");
  return from_record(entry, r);
}

std::string published(const ModelEntry& entry) {
  std::string out;
  if (!entry.md5.empty()) out += "MD5 " + entry.md5;
  if (!entry.sha256.empty()) out += (out.empty() ? "SHA-256 " : " or SHA-256 ") + entry.sha256;
  return out;
}

}  // namespace

CacheStatus cache_status(const ModelEntry& entry) {
  CacheStatus s;
  const fs::path file = cached_file(entry);
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) return s;
  s.state = CacheState::Unchecked;
  const std::optional<json> r = read_record(entry);
  if (!r) {
    s.why = "no record of its check (run instainpaint models verify " + entry.name + ")";
    return s;
  }
  const uintmax_t size = fs::file_size(file, ec);
  if (ec || size != (*r)["size"].get<uintmax_t>() || modified_ns(file) != (*r)["modified_ns"].get<int64_t>()) {
    s.why = "changed since it was checked (run instainpaint models verify " + entry.name + ")";
    return s;
  }
  // A file checked against another catalogue's checksums (an organisation's, the tests') is not
  // this one's.
  FileDigests recorded;
  recorded.sha256 = (*r)["sha256"].get<std::string>();
  recorded.md5 = r->value("md5", "");
  if (entry.archive_member.empty() && !published_mismatch(entry, recorded).empty()) {
    s.why = "its recorded checksums are not the published ones (run instainpaint models verify " + entry.name + ")";
    return s;
  }
  s.state = CacheState::Verified;
  s.model = from_record(entry, *r);
  return s;
}

std::optional<CachedModel> cached_model(const ModelEntry& entry) { return cache_status(entry).model; }

namespace {

// The models' folder, or nullopt where none can be named (no HOME): no cache, the built-in path.
std::optional<fs::path> known_models_dir() {
  try {
    return models_dir();
  } catch (const Error&) {
    return std::nullopt;
  }
}

}  // namespace

std::optional<CachedModel> cached_model_for(ModelRole role) {
  std::error_code ec;
  const std::optional<fs::path> dir = known_models_dir();
  if (!dir || !fs::is_directory(*dir, ec)) return std::nullopt;
  for (const ModelEntry& e : model_catalogue())
    if (e.role == role)
      if (auto m = cached_model(e)) return m;
  return std::nullopt;
}

std::string published_mismatch(const ModelEntry& entry, const FileDigests& digests) {
  if (!entry.pinned() || (!entry.md5.empty() && digests.md5 == entry.md5) ||
      (!entry.sha256.empty() && digests.sha256 == entry.sha256))
    return "";
  return fmt::format("its MD5 is {} and its SHA-256 {}, but {} publishes {}", digests.md5, digests.sha256,
                     entry.checksum_publisher(), published(entry));
}

FileCheck check_file(const ModelEntry& entry, const fs::path& file, const std::string& recorded_sha256,
                     bool the_archive) {
  FileCheck c;
  c.digests = digests_of_file(file);
  // An archive's member is held to the SHA-256 recorded when it was taken out (the published
  // checksums are the archive's).
  const bool by_publisher = entry.pinned() && (entry.archive_member.empty() || the_archive);
  c.pinned = entry.pinned();
  if (const std::string why = by_publisher ? published_mismatch(entry, c.digests) : ""; !why.empty()) {
    fail("{}: {} is not the published file: {}", entry.name, file.string(), why);
  } else if (!by_publisher && !recorded_sha256.empty() && c.digests.sha256 != recorded_sha256) {
    fail("{}: {} has changed: its SHA-256 is {}, but {} was recorded when it was first fetched", entry.name,
         file.string(), c.digests.sha256, recorded_sha256);
  }
  return c;
}

CachedModel install_checked(const ModelEntry& entry, const fs::path& checked, const FileCheck& check,
                            const std::string& origin) {
  std::error_code ec;
  fs::rename(checked, cached_file(entry), ec);
  if (ec) fail_file(cached_file(entry), "cannot move the checked file into place: {}", ec.message());
  return write_record(entry, check, origin);
}

CachedModel verify_cached(const ModelEntry& entry) {
  const fs::path file = cached_file(entry);
  std::error_code ec;
  if (!fs::is_regular_file(file, ec))
    fail("{}: not in the cache ({}); bring it with: {}", entry.name, models_dir().string(), get_command(entry.name));
  const std::optional<json> r = read_record(entry);
  const FileCheck check = check_file(entry, file, r ? (*r)["sha256"].get<std::string>() : "");
  return write_record(entry, check, r ? r->value("origin", "") : "found in the cache");
}

std::string published_name(const ModelEntry& entry) {
  if (entry.archive_member.empty() || entry.urls.empty()) return entry.file_name;
  std::string url = entry.urls[0].substr(0, entry.urls[0].find_first_of("?#"));
  return url.substr(url.rfind('/') + 1);
}

namespace {

// The archive's entry that ends in the entry's member path, or "" when it holds none.
std::string member_of(const ZipArchive& zip, const std::string& member) {
  for (const std::string& name : zip.names())
    if (name == member || (name.size() > member.size() && name.compare(name.size() - member.size(), member.size(), member) == 0 &&
                           name[name.size() - member.size() - 1] == '/'))
      return name;
  return "";
}

bool holds_member(const fs::path& file, const std::string& member) {
  try {
    return !member_of(ZipArchive(file), member).empty();
  } catch (const Error&) {
    return false;  // not a zip archive
  }
}

}  // namespace

CachedModel install_archive_member(const ModelEntry& entry, const fs::path& archive, const FileCheck& archive_check,
                                   const std::string& origin) {
  const ZipArchive zip(archive);
  const std::string member = member_of(zip, entry.archive_member);
  if (member.empty()) fail("{}: {} holds no {}", entry.name, archive.string(), entry.archive_member);
  const fs::path taken = models_dir() / (entry.file_name + ".extract");
  const std::vector<uint8_t> bytes = zip.read(member);
  write_file_atomic(taken, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
  FileCheck check;
  check.digests = digests_of_file(taken);
  check.pinned = archive_check.pinned;
  return install_checked(entry, taken, check, origin + " (its " + member + ")");
}

fs::path make_models_dir() {
  const fs::path dir = models_dir();
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir, ec))
    fail_file(dir, "the models' folder cannot be made: {} (set INSTAINPAINT_MODELS_DIR to a folder you can write)",
              ec ? ec.message() : "not a folder");
  return dir;
}

CachedModel import_model(const ModelEntry& entry, const fs::path& source) {
  std::error_code ec;
  if (!fs::is_regular_file(source, ec)) fail_file(source, "no such file");
  const std::string origin = "imported from " + fs::absolute(source).string();
  // An archive entry takes the archive (checked as published, its member kept) or the member itself.
  if (!entry.archive_member.empty() && holds_member(source, entry.archive_member)) {
    const FileCheck check = check_file(entry, source, "", /*the_archive=*/true);
    make_models_dir();
    return install_archive_member(entry, source, check, origin);
  }
  const FileCheck check = check_file(entry, source, "");
  const fs::path tmp = make_models_dir() / (entry.file_name + ".import");
  fs::copy_file(source, tmp, fs::copy_options::overwrite_existing, ec);
  if (ec) {
    fs::remove(tmp, ec);
    fail_file(tmp.parent_path(), "cannot write {}: {}", tmp.filename().string(), ec.message());
  }
  return install_checked(entry, tmp, check, origin);
}

bool remove_cached(const ModelEntry& entry) {
  bool any = false;
  std::error_code ec;
  for (const fs::path& p : {cached_file(entry), record_file(entry), models_dir() / (entry.file_name + ".part")})
    any = fs::remove(p, ec) || any;
  return any;
}

std::optional<CachedModel> cached_model_of_file(const fs::path& file) {
  std::error_code ec;
  if (!known_models_dir()) return std::nullopt;
  for (const ModelEntry& e : model_catalogue())
    if (fs::equivalent(file, cached_file(e), ec)) return cached_model(e);
  return std::nullopt;
}

json model_file_description(const fs::path& file) {
  if (const auto m = cached_model_of_file(file))
    return {{"file", file.string()}, {"sha256", m->sha256}, {"from", "the cache"}, {"catalogue_name", m->name}};
  return {{"file", file.string()}, {"sha256", sha256_of_file(file)}, {"from", "a path"}};
}

fs::path verified_model_path(const std::string& name) {
  const ModelEntry& e = catalogue_entry(name);
  const CacheStatus s = cache_status(e);
  if (!s.model)
    fail("{}: {}", e.name, s.state == CacheState::Absent ? "not in the cache; bring it with: " + get_command(e.name) : s.why);
  return s.model->file;
}

std::string cache_state_text(const CacheStatus& s) {
  switch (s.state) {
    case CacheState::Absent: return "absent";
    case CacheState::Unchecked: return "present, not checked";
    case CacheState::Verified: return s.model->pinned ? "verified" : "present (SHA-256 recorded)";
  }
  return "?";
}

json catalogue_state() {
  json out = {{"folder", models_dir().string()}, {"networks", json::array()}, {"auto", json::object()}};
  for (const ModelEntry& e : model_catalogue()) {
    const CacheStatus s = cache_status(e);
    json j = {{"name", e.name},       {"role", role_name(e.role)}, {"purpose", e.purpose},
              {"file", e.file_name},  {"urls", e.urls},            {"licence", e.licence},
              {"size", e.size},       {"pinned", e.pinned()},      {"state", cache_state_text(s)},
              {"path", cached_file(e).string()}};
    if (!e.md5.empty()) j["md5"] = e.md5;
    if (!e.sha256.empty()) j["published_sha256"] = e.sha256;
    if (s.model) j["sha256"] = s.model->sha256, j["origin"] = s.model->origin, j["checked_at"] = s.model->checked_at;
    if (!s.why.empty()) j["why"] = s.why;
    out["networks"].push_back(j);
  }
  for (const ModelRole r : {ModelRole::Checkpoint, ModelRole::Segmenter, ModelRole::Inpainter}) {
    const auto m = cached_model_for(r);
    out["auto"][role_name(r)] = m ? json(m->name) : json(nullptr);
  }
  return out;
}

ModelChoice choose_model(ModelRole role, const std::string& value) {
  ModelChoice c;
  if (value == "auto") {
    c.cached = cached_model_for(role);
    if (c.cached) c.file = c.cached->file;
    return c;
  }
  if (in_catalogue(value)) {
    const ModelEntry& e = catalogue_entry(value);
    if (e.role != role) fail("{} {}: {} is for {}", role_flag(role), value, value, role_flag(e.role));
    const CacheStatus s = cache_status(e);
    if (s.state == CacheState::Absent)
      fail("{} {}: not in the cache ({}); bring it with: {}", role_flag(role), value, models_dir().string(),
           get_command(value));
    if (!s.model) fail("{} {}: the cache's file is {}", role_flag(role), value, s.why);
    c.cached = s.model;
    c.file = s.model->file;
    return c;
  }
  c.file = fs::path(value);
  return c;
}

}  // namespace ii
