#pragma once
// The folder of fetched networks and what is known of each file in it. A file is used only
// when its record (written when it was downloaded or imported and checked) still describes it:
// the same size and modification time. `verify` hashes it again.
#include <filesystem>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "io/file_hash.h"
#include "models/catalogue.h"

namespace ii {

// $INSTAINPAINT_MODELS_DIR, else $XDG_CACHE_HOME/instainpaint/models, else
// ~/.cache/instainpaint/models (not created here).
std::filesystem::path models_dir();

// What the cache holds of one entry.
struct CachedModel {
  std::string name;
  std::filesystem::path file;
  std::string sha256, md5;
  uintmax_t size = 0;
  bool pinned = false;     // matched a published checksum (else recorded at the first get)
  std::string origin;      // the URL it came from, or "imported from <path>"
  std::string checked_at;  // UTC, ISO 8601
};

enum class CacheState { Absent, Unchecked, Verified };
struct CacheStatus {
  CacheState state = CacheState::Absent;
  std::optional<CachedModel> model;  // with Verified
  std::string why;                   // with Unchecked: what differs from the record
};

// The cache's file of an entry and its record (beside it, "<file>.record.json").
std::filesystem::path cached_file(const ModelEntry& entry);
std::filesystem::path record_file(const ModelEntry& entry);

CacheStatus cache_status(const ModelEntry& entry);
// The entry's file when its record still describes it, else nullopt.
std::optional<CachedModel> cached_model(const ModelEntry& entry);
// The first usable cached file of a role, in catalogue order (MobileSAM before the larger SAMs).
std::optional<CachedModel> cached_model_for(ModelRole role);

// A file's digests and whether they matched a published checksum.
struct FileCheck {
  FileDigests digests;
  bool pinned = false;
};

// "" when `digests` match a checksum the entry's catalogue publishes (or it publishes none), else
// what differs: "its MD5 is ... and its SHA-256 ..., but IOPaint (...) publishes MD5 ...".
std::string published_mismatch(const ModelEntry& entry, const FileDigests& digests);

// Hashes `file` and checks it against the entry's published checksums, or when none is
// published against `recorded_sha256` (when given). Throws an Error naming the entry, the file,
// what was expected and both checksums found; leaves the file alone. An archive entry's file is
// its member, held to the recorded SHA-256; `the_archive`: the file is the archive itself, held
// to the published checksums.
FileCheck check_file(const ModelEntry& entry, const std::filesystem::path& file,
                     const std::string& recorded_sha256 = "", bool the_archive = false);

// Hashes the cached file again; an Error (the file left in place) when it differs.
CachedModel verify_cached(const ModelEntry& entry);
// The models' folder, made when it is not there; an Error naming it when it cannot be.
std::filesystem::path make_models_dir();
// Copies `source` into the cache as the entry's file after checking it as a download is.
CachedModel import_model(const ModelEntry& entry, const std::filesystem::path& source);
// The name the entry is published under: its file, or for an archive entry the archive's (the
// last part of its first URL): what a mirror holds.
std::string published_name(const ModelEntry& entry);
// Takes the entry's member out of `archive` (checked as published: `archive_check`) into the
// cache under the entry's file name, and records it.
CachedModel install_archive_member(const ModelEntry& entry, const std::filesystem::path& archive,
                                   const FileCheck& archive_check, const std::string& origin);
// Removes the entry's file, its record and any partial download; whether anything was there.
bool remove_cached(const ModelEntry& entry);

// Moves a checked file into place under the entry's name and writes its record.
CachedModel install_checked(const ModelEntry& entry, const std::filesystem::path& checked_file,
                            const FileCheck& check, const std::string& origin);

// The cache's verified record of `file` when it is an entry's file in the cache, else nullopt.
std::optional<CachedModel> cached_model_of_file(const std::filesystem::path& file);

// How a model file used by a command is named in run.json, masks.json, fill.json:
// {"file", "sha256", "from": "the cache" | "a path"} (and "catalogue_name" for the cache's).
nlohmann::json model_file_description(const std::filesystem::path& file);

// The verified file of the catalogue's `name`; an Error saying how to bring or mend it.
std::filesystem::path verified_model_path(const std::string& name);

// "absent", "present, not checked", "verified" or "present (SHA-256 recorded)" (not pinned).
std::string cache_state_text(const CacheStatus& status);
// `models list --json` and Python's models.list(): {"folder", "networks": [each entry with its
// state, path, checksums], "auto": {role: the name auto picks, or null}}.
nlohmann::json catalogue_state();

// Where a role's flag value leads: "auto" (the cache's file, else the built-in path), a
// catalogue name (its cached file, else an Error giving the command that brings it), the
// built-in path's own words, or a file. `builtin_words`: e.g. {"none"} for --segmenter.
struct ModelChoice {
  std::optional<std::filesystem::path> file;  // nullopt: the built-in path
  std::optional<CachedModel> cached;          // when it came from the cache
};
ModelChoice choose_model(ModelRole role, const std::string& value);

}  // namespace ii
