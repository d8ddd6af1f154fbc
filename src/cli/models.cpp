// `instainpaint models`: the networks the commands use when they are in the cache, brought and
// checked by one command (list, get, verify, path, import, remove).
#include <fmt/core.h>

#include <algorithm>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "common/error.h"
#include "models/download.h"

namespace ii::cli {

namespace {

using json = nlohmann::json;

std::string size_text(uintmax_t bytes) {
  if (bytes == 0) return "?";
  return bytes >= 1000000000 ? fmt::format("{:.2f} GB", bytes / 1e9) : fmt::format("{:.0f} MB", bytes / 1e6);
}

void list(bool as_json) {
  if (as_json) {
    fmt::print("{}\n", catalogue_state().dump(2));
    return;
  }
  size_t w = 4;  // the names' column
  for (const ModelEntry& e : model_catalogue()) w = std::max(w, e.name.size());
  fmt::print("networks in {}\n\n", models_dir().string());
  fmt::print("{:<{}} {:<12} {:>8}  {:<11} {:<26} {}\n", "name", w, "for", "size", "licence", "state", "checksum");
  for (const ModelEntry& e : model_catalogue()) {
    const CacheStatus s = cache_status(e);
    fmt::print("{:<{}} {:<12} {:>8}  {:<11} {:<26} {}\n", e.name, w, role_flag(e.role), size_text(e.size), e.licence,
               cache_state_text(s), e.pinned() ? "pinned (" + e.checksum_publisher() + ")" : "not pinned: none is published");
  }
  fmt::print("\n");
  for (const ModelEntry& e : model_catalogue()) fmt::print("{:<{}} {}\n{:<{}} from {}\n", e.name, w, e.purpose, "", w, e.urls[0]);
  fmt::print("\nwhat the commands use by default (auto):\n");
  const char* builtin[] = {"the built-in model", "colour growth (no network)", "Navier-Stokes (no network)"};
  int i = 0;
  for (const ModelRole r : {ModelRole::Checkpoint, ModelRole::Segmenter, ModelRole::Inpainter}) {
    const auto m = cached_model_for(r);
    fmt::print("  {:<13} {}\n", role_flag(r), m ? m->name + " (" + m->file.string() + ")" : builtin[i]);
    ++i;
  }
}

void get(const std::vector<std::string>& names, const DownloadOptions& options) {
  std::vector<const ModelEntry*> entries;  // every name checked before anything is fetched
  for (const std::string& n : names) entries.push_back(&catalogue_entry(n));
  for (const ModelEntry* e : entries) {
    if (const auto m = cached_model(*e)) {
      fmt::print("{}: already in the cache, {}\n", e->name, m->file.string());
      continue;
    }
    const CachedModel m = download_model(*e, options);
    fmt::print("{}: {}\n", e->name, m.file.string());
  }
}

void verify(std::vector<std::string> names) {
  if (names.empty())
    for (const ModelEntry& e : model_catalogue())
      if (cache_status(e).state != CacheState::Absent) names.push_back(e.name);
  if (names.empty()) {
    fmt::print("no network in {}; bring one with: {}\n", models_dir().string(), get_command("NAME"));
    return;
  }
  std::vector<std::string> failures;
  for (const std::string& n : names) {
    const ModelEntry& e = catalogue_entry(n);
    try {
      const CachedModel m = verify_cached(e);
      fmt::print("{}: {} ({}; SHA-256 {})\n", e.name, m.pinned ? "verified" : "unchanged since its first get",
                 m.pinned ? "matches " + e.checksum_publisher() : "no checksum is published", m.sha256);
    } catch (const Error& err) {
      failures.push_back(err.what());
    }
  }
  if (failures.size() == 1) throw Error(failures[0]);
  if (!failures.empty()) {
    std::string all;
    for (const auto& f : failures) all += "\n  " + f;
    throw Error(fmt::format("{} networks failed their check:{}", failures.size(), all));
  }
}

}  // namespace

void add_models_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("models", "Bring, check and list the learned networks the commands use (SAM, LaMa, InstaInpaint)");
  cmd->require_subcommand(1);
  cmd->footer(
      "The commands use a verified network of the cache by default (--checkpoint, --segmenter and --inpainter\n"
      "are 'auto'); without one they take the built-in path. Nothing is downloaded but by 'models get'.\n"
      "The cache: $INSTAINPAINT_MODELS_DIR, else $XDG_CACHE_HOME/instainpaint/models, else ~/.cache/instainpaint/models.\n"
      "Examples:\n"
      "  instainpaint models list\n"
      "  instainpaint models get mobile-sam big-lama\n"
      "  instainpaint models get instainpaint --mirror https://models.example.org/instainpaint\n"
      "  instainpaint models import ~/Downloads/mobile_sam.pt --as mobile-sam\n"
      "  instainpaint models verify");

  auto json_flag = std::make_shared<bool>(false);
  auto* list_cmd = cmd->add_subcommand("list", "Each network: what it is for, size, licence, where it comes from, its state");
  list_cmd->add_flag("--json", *json_flag, "Print JSON instead of text");
  list_cmd->callback([json_flag] { list(*json_flag); });

  auto names = std::make_shared<std::vector<std::string>>();
  auto options = std::make_shared<DownloadOptions>();
  auto* get_cmd = cmd->add_subcommand("get", "Download networks into the cache and check their checksums");
  get_cmd->add_option("names", *names, "Catalogue names (models list)")->required();
  get_cmd->add_option("--mirror", options->mirror,
                      "A base URL holding the same file names (default $INSTAINPAINT_MODELS_MIRROR, else where the "
                      "authors publish each)");
  get_cmd->add_option("--timeout", options->timeout_s, "Seconds to connect, and without a byte before giving up")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 3600.0));
  get_cmd->add_flag("--quiet{false}", options->progress, "No progress");
  get_cmd->callback([names, options] { get(*names, *options); });

  auto verify_names = std::make_shared<std::vector<std::string>>();
  auto* verify_cmd = cmd->add_subcommand("verify", "Hash the cached files again and check them (default: every one present)");
  verify_cmd->add_option("names", *verify_names, "Catalogue names");
  verify_cmd->callback([verify_names] { verify(*verify_names); });

  auto path_name = std::make_shared<std::string>();
  auto* path_cmd = cmd->add_subcommand("path", "Print a verified network's file (for scripts)");
  path_cmd->add_option("name", *path_name, "Catalogue name")->required();
  path_cmd->callback([path_name] { fmt::print("{}\n", verified_model_path(*path_name).string()); });

  auto import_file = std::make_shared<std::string>();
  auto import_name = std::make_shared<std::string>();
  auto* import_cmd = cmd->add_subcommand("import", "Check a file downloaded by hand and copy it into the cache");
  import_cmd->add_option("file", *import_file, "The file")->required();
  import_cmd->add_option("--as", *import_name, "Its catalogue name")->required();
  import_cmd->callback([import_file, import_name] {
    const ModelEntry& e = catalogue_entry(*import_name);
    const CachedModel m = import_model(e, *import_file);
    fmt::print("{}: {} ({})\n", e.name, m.file.string(),
               m.pinned ? "matches " + e.checksum_publisher() : "no checksum is published: its SHA-256 recorded");
  });

  auto remove_name = std::make_shared<std::string>();
  auto* remove_cmd = cmd->add_subcommand("remove", "Delete a network from the cache");
  remove_cmd->add_option("name", *remove_name, "Catalogue name")->required();
  remove_cmd->callback([remove_name] {
    const ModelEntry& e = catalogue_entry(*remove_name);
    fmt::print("{}: {}\n", e.name, remove_cached(e) ? "removed" : "was not in the cache");
  });
}

}  // namespace ii::cli
