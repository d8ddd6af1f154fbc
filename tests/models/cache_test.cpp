// The catalogue, the cache's records and the choice a command's "auto" makes (the downloads
// themselves: download_test.py, against a server on the loopback address).
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>

#include "common/error.h"
#include "io/file_hash.h"
#include "models/cache.h"
#include "models/download.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;
using test::error_message;

// Sets an environment variable for one test and puts back what was there.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::string& value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    ::setenv(name, value.c_str(), 1);
  }
  ~ScopedEnv() {
    if (old_)
      ::setenv(name_, old_->c_str(), 1);
    else
      ::unsetenv(name_);
  }

 private:
  const char* name_;
  std::optional<std::string> old_;
};

TEST(ModelCatalogue, NamesEveryNetworkWithItsPublishedLocationAndChecksum) {
  std::vector<std::string> names;
  for (const ModelEntry& e : model_catalogue()) {
    names.push_back(e.name);
    ASSERT_FALSE(e.urls.empty()) << e.name;
    for (const std::string& u : e.urls) EXPECT_EQ(u.rfind("https://", 0), 0u) << u;
    EXPECT_FALSE(e.licence.empty()) << e.name;
    if (e.pinned()) EXPECT_EQ(e.md5.size(), 32u) << e.name;
  }
  EXPECT_EQ(names, (std::vector<std::string>{"instainpaint", "mobile-sam", "sam-vit-b", "sam-vit-l", "sam-vit-h", "big-lama",
                                     "big-lama-authors"}));
  // SAM's file names end in the first digits of the MD5 IOPaint pins.
  for (const char* name : {"sam-vit-b", "sam-vit-l", "sam-vit-h"}) {
    const ModelEntry& e = catalogue_entry(name);
    EXPECT_NE(e.file_name.find(e.md5.substr(0, 6)), std::string::npos) << name;
  }
  EXPECT_FALSE(catalogue_entry("instainpaint").pinned());  // its authors publish no checksum
  EXPECT_FALSE(catalogue_entry("big-lama-authors").pinned());
  EXPECT_EQ(published_name(catalogue_entry("big-lama-authors")), "big-lama.zip");
  EXPECT_EQ(published_name(catalogue_entry("big-lama")), "big-lama.pt");
  EXPECT_EQ(error_message([] { catalogue_entry("sam3"); }),
            "'sam3' is not a network of the catalogue: instainpaint, mobile-sam, sam-vit-b, sam-vit-l, sam-vit-h, big-lama, "
            "big-lama-authors");
}

TEST(ModelCatalogue, AFileOfEntriesIsCheckedField) {
  const auto parse_error = [](const std::string& text) {
    return error_message([&] { parse_model_catalogue(text, "cat.json"); });
  };
  EXPECT_EQ(parse_error("{"), "cat.json: not JSON");
  EXPECT_EQ(parse_error("{}"), "cat.json: expected a JSON list of networks");
  EXPECT_EQ(parse_error(R"([{"role":"segmenter","file":"a.pt","urls":["https://x/a.pt"]}])"),
            "cat.json: network 1: 'name' is missing");
  EXPECT_EQ(parse_error(R"([{"name":"a","role":"segmenter","file":"../a.pt","urls":["https://x/a.pt"]}])"),
            "cat.json: network 1: file '../a.pt' may hold only letters, digits, '.', '_', '-', '+'");
  EXPECT_EQ(parse_error(R"([{"name":"a","role":"painter","file":"a.pt","urls":["https://x/a.pt"]}])"),
            "cat.json: network 1: role 'painter' is not one of checkpoint, segmenter, inpainter");
  EXPECT_EQ(parse_error(R"([{"name":"a","role":"segmenter","file":"a.pt","urls":["file:///etc/passwd"]}])"),
            "cat.json: network 1: URL 'file:///etc/passwd' is neither https:// nor http://");
  EXPECT_EQ(parse_error(R"([{"name":"a","role":"segmenter","file":"a.pt","urls":["https://x/a.pt"],"md5":"XYZ"}])"),
            "cat.json: network 1: md5 must be 32 lower-case hex digits");
  EXPECT_EQ(parse_error(R"([{"name":"a","role":"segmenter","file":"a.pt","urls":["https://x"]},
                           {"name":"a","role":"inpainter","file":"b.pt","urls":["https://x"]}])"),
            "cat.json: network 2 has the name or file of network 1");
  const auto entries = parse_model_catalogue(
      R"([{"name":"a","role":"inpainter","file":"a.pt","urls":["http://127.0.0.1/a.pt"],"size":12}])", "cat.json");
  ASSERT_EQ(entries.size(), 1u);
  EXPECT_EQ(entries[0].role, ModelRole::Inpainter);
  EXPECT_EQ(entries[0].size, 12u);
  EXPECT_FALSE(entries[0].pinned());
}

TEST(ModelCache, FolderFromTheEnvironmentInOrder) {
  const ScopedEnv home("HOME", "/home/someone");
  {
    const ScopedEnv dir("INSTAINPAINT_MODELS_DIR", "");
    const ScopedEnv xdg("XDG_CACHE_HOME", "");
    EXPECT_EQ(models_dir(), fs::path("/home/someone/.cache/instainpaint/models"));
    const ScopedEnv xdg2("XDG_CACHE_HOME", "/var/cache/me");
    EXPECT_EQ(models_dir(), fs::path("/var/cache/me/instainpaint/models"));
    const ScopedEnv dir2("INSTAINPAINT_MODELS_DIR", "/srv/models");
    EXPECT_EQ(models_dir(), fs::path("/srv/models"));
  }
}

// A seeded file and an entry pinned to its MD5 (or not pinned).
struct SeededModel {
  fs::path file;
  ModelEntry entry;
};
SeededModel seeded_model(const fs::path& dir, bool pinned) {
  SeededModel s;
  s.file = dir / "weights.bin";
  std::string bytes(5000, '\0');
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<char>((i * 7919) % 251);
  test::write_bytes(s.file, bytes);
  s.entry.name = "seeded";
  s.entry.role = ModelRole::Segmenter;
  s.entry.file_name = "seeded.pt";
  s.entry.urls = {"http://127.0.0.1:9/seeded.pt"};
  s.entry.checksum_source = "the test";
  if (pinned) s.entry.md5 = digests_of_file(s.file).md5;
  return s;
}

TEST(ModelCache, ImportChecksRecordsAndNoticesAChange) {
  const fs::path dir = test::temp_dir("models-import");
  const ScopedEnv env("INSTAINPAINT_MODELS_DIR", (dir / "cache").string());
  const SeededModel s = seeded_model(dir, true);
  EXPECT_EQ(cache_status(s.entry).state, CacheState::Absent);
  const CachedModel m = import_model(s.entry, s.file);
  EXPECT_TRUE(m.pinned);
  EXPECT_EQ(m.sha256, sha256_of_file(s.file));
  EXPECT_EQ(m.file, dir / "cache" / "seeded.pt");
  ASSERT_EQ(cache_status(s.entry).state, CacheState::Verified);
  EXPECT_EQ(model_file_description(s.file)["from"], "a path");
  // Checked against another catalogue's checksum: not this one's file.
  ModelEntry other = s.entry;
  other.md5 = std::string(32, '0');
  EXPECT_EQ(cache_status(other).state, CacheState::Unchecked);
  EXPECT_EQ(cache_status(other).why,
            "its recorded checksums are not the published ones (run instainpaint models verify seeded)");
  // A record that is not what the cache writes: the file is not used until it is verified again.
  const std::string record = test::file_bytes(record_file(s.entry));
  test::write_bytes(record_file(s.entry), R"({"sha256": "x", "size": 5000, "modified_ns": 1, "md5": 7})");
  EXPECT_EQ(cache_status(s.entry).why, "no record of its check (run instainpaint models verify seeded)");
  test::write_bytes(record_file(s.entry), record);
  ASSERT_EQ(cache_status(s.entry).state, CacheState::Verified);
  // One byte changed: no longer used, and verify says what it found and what is published.
  {
    std::fstream f(m.file, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(10);
    f.put('x');
  }
  const CacheStatus changed = cache_status(s.entry);
  EXPECT_EQ(changed.state, CacheState::Unchecked);
  EXPECT_FALSE(changed.model);
  const std::string why = error_message([&] { verify_cached(s.entry); });
  EXPECT_NE(why.find("is not the published file: its MD5 is " + digests_of_file(m.file).md5), std::string::npos) << why;
  EXPECT_NE(why.find("the test publishes MD5 " + s.entry.md5), std::string::npos) << why;
  EXPECT_TRUE(remove_cached(s.entry));
  EXPECT_EQ(cache_status(s.entry).state, CacheState::Absent);
  EXPECT_FALSE(remove_cached(s.entry));
}

TEST(ModelCache, AnUnpinnedFileIsHeldToTheSha256RecordedFirst) {
  const fs::path dir = test::temp_dir("models-unpinned");
  const ScopedEnv env("INSTAINPAINT_MODELS_DIR", (dir / "cache").string());
  const SeededModel s = seeded_model(dir, false);
  const CachedModel m = import_model(s.entry, s.file);
  EXPECT_FALSE(m.pinned);
  EXPECT_EQ(verify_cached(s.entry).sha256, m.sha256);
  test::write_bytes(m.file, "another file");
  EXPECT_EQ(error_message([&] { verify_cached(s.entry); }),
            fmt::format("seeded: {} has changed: its SHA-256 is {}, but {} was recorded when it was first fetched",
                        m.file.string(), sha256_of_file(m.file), m.sha256));
}

TEST(ModelCache, WithoutAFolderToNameAutoTakesTheBuiltInPath) {
  const ScopedEnv dir("INSTAINPAINT_MODELS_DIR", ""), xdg("XDG_CACHE_HOME", ""), home("HOME", "");
  EXPECT_EQ(test::error_message([] { models_dir(); }),
            "the models' folder: neither INSTAINPAINT_MODELS_DIR, XDG_CACHE_HOME nor HOME is set");
  EXPECT_FALSE(choose_model(ModelRole::Checkpoint, "auto").file);
  const fs::path file = test::temp_dir("models-no-folder") / "weights.bin";
  test::write_bytes(file, "weights");
  EXPECT_EQ(model_file_description(file).value("from", ""), "a path");
}

TEST(ModelCache, AutoTakesTheBuiltInPathWithAnEmptyCacheAndANameItsCachedFile) {
  const fs::path dir = test::temp_dir("models-auto");
  const ScopedEnv env("INSTAINPAINT_MODELS_DIR", (dir / "empty").string());
  EXPECT_FALSE(choose_model(ModelRole::Segmenter, "auto").file);
  EXPECT_FALSE(cached_model_for(ModelRole::Inpainter));
  EXPECT_EQ(*choose_model(ModelRole::Segmenter, "my_sam.pth").file, fs::path("my_sam.pth"));
  EXPECT_EQ(error_message([] { choose_model(ModelRole::Segmenter, "mobile-sam"); }),
            fmt::format("--segmenter mobile-sam: not in the cache ({}); bring it with: instainpaint models get mobile-sam",
                        (dir / "empty").string()));
  EXPECT_EQ(error_message([] { choose_model(ModelRole::Inpainter, "mobile-sam"); }),
            "--inpainter mobile-sam: mobile-sam is for --segmenter");
}

}  // namespace
}  // namespace ii
