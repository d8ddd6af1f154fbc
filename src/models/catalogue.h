#pragma once
// The networks instainpaint can fetch for its users (`instainpaint models`): what each is for,
// where its authors publish it, its licence and the checksum its authors or a well-kept
// downstream (IOPaint) publish. Torch-free: the cache and the download need no network code.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace ii {

// Which flag of the commands a network serves: --checkpoint, --segmenter or --inpainter.
enum class ModelRole { Checkpoint, Segmenter, Inpainter };
const char* role_name(ModelRole role);  // "checkpoint", "segmenter", "inpainter"
const char* role_flag(ModelRole role);  // "--checkpoint", ...

struct ModelEntry {
  std::string name;       // what `models get` takes: "mobile-sam"
  ModelRole role = ModelRole::Segmenter;
  std::string purpose;    // one line for `models list`
  std::string file_name;  // the published file name, also its name in the cache
  std::vector<std::string> urls;  // where its authors (then downstream) publish it, tried in order
  std::string licence;
  uint64_t size = 0;      // bytes, as published (0: not known before the download)
  // Published checksums (lower-case hex; empty: none). A file matching neither is refused.
  std::string md5, sha256;
  std::string checksum_source;  // who publishes the checksum, e.g. "IOPaint (iopaint/model/lama.py)"
  // When the published file is a zip archive: the cache keeps its member whose path ends so
  // (big-lama.zip's "models/best.ckpt"); the checksums are the archive's.
  std::string archive_member;
  bool pinned() const { return !md5.empty() || !sha256.empty(); }
  // Who publishes the checksum, for messages: checksum_source, else "the catalogue".
  std::string checksum_publisher() const { return checksum_source.empty() ? "the catalogue" : checksum_source; }
};

// The built-in entries, then those of $INSTAINPAINT_MODELS_CATALOGUE (a JSON file: an
// organisation's own approved files, the tests' seeded ones), which replace built-in entries
// of the same name.
const std::vector<ModelEntry>& model_catalogue();
// The entry named `name`; an Error listing every name when there is none.
const ModelEntry& catalogue_entry(const std::string& name);
// Whether `name` is an entry of the catalogue.
bool in_catalogue(const std::string& name);

// A catalogue file's entries (a JSON array of objects with the fields above: name, role,
// file, urls, and optionally purpose, licence, size, md5, sha256, checksum_source, archive_member); an Error
// naming `source` and the problem for anything else.
std::vector<ModelEntry> parse_model_catalogue(const std::string& text, const std::string& source);

}  // namespace ii
