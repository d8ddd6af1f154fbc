#include "models/catalogue.h"

#include <algorithm>
#include <cstdlib>
#include <mutex>

#include "common/error.h"
#include "common/files.h"

namespace ii {

using json = nlohmann::json;

const char* role_name(ModelRole role) {
  switch (role) {
    case ModelRole::Checkpoint: return "checkpoint";
    case ModelRole::Segmenter: return "segmenter";
    case ModelRole::Inpainter: return "inpainter";
  }
  return "?";
}

const char* role_flag(ModelRole role) {
  switch (role) {
    case ModelRole::Checkpoint: return "--checkpoint";
    case ModelRole::Segmenter: return "--segmenter";
    case ModelRole::Inpainter: return "--inpainter";
  }
  return "?";
}

namespace {

// Where each comes from and who publishes its checksum (docs/models.md). The authors publish
// none; IOPaint (github.com/Sanster/IOPaint) pins the MD5 of the files it downloads. SAM's file
// names end in the first hex digits of that MD5.
std::vector<ModelEntry> builtin_entries() {
  const std::string iopaint_sam = "IOPaint (iopaint/plugins/interactive_seg.py)";
  const std::string sam_base = "https://dl.fbaipublicfiles.com/segment_anything/";
  const std::string sanster = "https://github.com/Sanster/models/releases/download/";
  std::vector<ModelEntry> e;
  e.push_back({"instainpaint", ModelRole::Checkpoint,
               "InstaInpaint's released checkpoint (the paper's network; ~11 s an edit on a 2-core CPU)",
               "exp_ins+random+3d_121_multimask.pth",
               {"https://huggingface.co/dhmbb/instainpaint/resolve/main/exp_ins%2Brandom%2B3d_121_multimask.pth"},
               "MIT", 0, "", "", ""});
  e.push_back({"mobile-sam", ModelRole::Segmenter, "MobileSAM: one click outlines the object (fast, 1 s a photo on 2 cores)",
               "mobile_sam.pt",
               {"https://github.com/ChaoningZhang/MobileSAM/raw/master/weights/mobile_sam.pt",
                sanster + "MobileSAM/mobile_sam.pt"},
               "Apache-2.0", 40728226, "f3c0d8cda613564d499310dab6c812cd", "", iopaint_sam});
  e.push_back({"sam-vit-b", ModelRole::Segmenter, "Segment Anything ViT-B: one click outlines the object",
               "sam_vit_b_01ec64.pth", {sam_base + "sam_vit_b_01ec64.pth"}, "Apache-2.0", 375042383,
               "01ec64d29a2fca3f0661936605ae66f8", "", iopaint_sam});
  e.push_back({"sam-vit-l", ModelRole::Segmenter, "Segment Anything ViT-L: one click outlines the object",
               "sam_vit_l_0b3195.pth", {sam_base + "sam_vit_l_0b3195.pth"}, "Apache-2.0", 1249524607,
               "0b3195507c641ddb6910d2bb5adee89c", "", iopaint_sam});
  e.push_back({"sam-vit-h", ModelRole::Segmenter, "Segment Anything ViT-H: one click outlines the object (largest)",
               "sam_vit_h_4b8939.pth", {sam_base + "sam_vit_h_4b8939.pth"}, "Apache-2.0", 2564550879,
               "4b8939a88964f0f4ff5f5b2642c598a6", "", iopaint_sam});
  e.push_back({"big-lama", ModelRole::Inpainter, "LaMa (big-lama): paints the removed object's hole in the reference photo",
               "big-lama.pt", {sanster + "add_big_lama/big-lama.pt"}, "Apache-2.0", 205669692,
               "e3aa4aaa15225a33ec84f9f4bc47e500", "", "IOPaint (iopaint/model/lama.py)"});
  // The same network as its authors publish it (github.com/advimman/lama's README): an archive
  // with no published checksum, of which the cache keeps models/best.ckpt.
  e.push_back({"big-lama-authors", ModelRole::Inpainter,
               "LaMa (big-lama) from its authors' archive (big-lama.zip's models/best.ckpt)", "big-lama-best.ckpt",
               {"https://huggingface.co/smartywu/big-lama/resolve/main/big-lama.zip"}, "Apache-2.0", 0, "", "", "",
               "models/best.ckpt"});
  return e;
}

bool is_hex(const std::string& s, size_t length) {
  return s.size() == length &&
         std::all_of(s.begin(), s.end(), [](char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); });
}

ModelRole parse_role(const std::string& name, const std::string& where) {
  for (const ModelRole r : {ModelRole::Checkpoint, ModelRole::Segmenter, ModelRole::Inpainter})
    if (name == role_name(r)) return r;
  fail("{}: role '{}' is not one of checkpoint, segmenter, inpainter", where, name);
}

// A name or file name that cannot leave the cache folder nor hide: letters, digits, . _ - +.
bool plain_name(const std::string& s) {
  return !s.empty() && s.size() <= 200 && s[0] != '.' &&
         std::all_of(s.begin(), s.end(), [](char c) {
           return std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-' || c == '+';
         });
}

ModelEntry parse_entry(const json& j, const std::string& where) {
  if (!j.is_object()) fail("{}: expected an object", where);
  const auto text = [&](const char* key, bool required) -> std::string {
    if (!j.contains(key)) {
      if (required) fail("{}: '{}' is missing", where, key);
      return "";
    }
    if (!j[key].is_string()) fail("{}: '{}' must be a string", where, key);
    return j[key].get<std::string>();
  };
  ModelEntry e;
  e.name = text("name", true);
  if (!plain_name(e.name)) fail("{}: name '{}' may hold only letters, digits, '.', '_', '-', '+'", where, e.name);
  e.role = parse_role(text("role", true), where);
  e.file_name = text("file", true);
  if (!plain_name(e.file_name))
    fail("{}: file '{}' may hold only letters, digits, '.', '_', '-', '+'", where, e.file_name);
  if (!j.contains("urls") || !j["urls"].is_array() || j["urls"].empty())
    fail("{}: 'urls' must be a list of at least one URL", where);
  for (const json& u : j["urls"]) {
    if (!u.is_string()) fail("{}: every URL must be a string", where);
    const std::string url = u.get<std::string>();
    if (url.rfind("https://", 0) != 0 && url.rfind("http://", 0) != 0)
      fail("{}: URL '{}' is neither https:// nor http://", where, url);
    e.urls.push_back(url);
  }
  e.purpose = text("purpose", false);
  e.licence = text("licence", false);
  e.checksum_source = text("checksum_source", false);
  e.archive_member = text("archive_member", false);
  e.md5 = text("md5", false);
  e.sha256 = text("sha256", false);
  if (!e.md5.empty() && !is_hex(e.md5, 32)) fail("{}: md5 must be 32 lower-case hex digits", where);
  if (!e.sha256.empty() && !is_hex(e.sha256, 64)) fail("{}: sha256 must be 64 lower-case hex digits", where);
  if (j.contains("size")) {
    if (!j["size"].is_number_unsigned()) fail("{}: 'size' must be a number of bytes", where);
    e.size = j["size"].get<uint64_t>();
  }
  return e;
}

std::vector<ModelEntry> load_catalogue() {
  std::vector<ModelEntry> entries = builtin_entries();
  const char* extra = std::getenv("INSTAINPAINT_MODELS_CATALOGUE");
  if (!extra || !*extra) return entries;
  for (ModelEntry& e : parse_model_catalogue(read_file_text(extra), extra)) {
    const auto same = std::find_if(entries.begin(), entries.end(), [&](const ModelEntry& b) { return b.name == e.name; });
    if (same != entries.end())
      *same = std::move(e);
    else
      entries.push_back(std::move(e));
  }
  return entries;
}

}  // namespace

std::vector<ModelEntry> parse_model_catalogue(const std::string& text, const std::string& source) {
  const json j = json::parse(text, nullptr, false);
  if (j.is_discarded()) fail("{}: not JSON", source);
  if (!j.is_array()) fail("{}: expected a JSON list of networks", source);
  std::vector<ModelEntry> entries;
  for (size_t i = 0; i < j.size(); ++i) {
    entries.push_back(parse_entry(j[i], fmt::format("{}: network {}", source, i + 1)));
    for (size_t k = 0; k + 1 < entries.size(); ++k)
      if (entries[k].name == entries.back().name || entries[k].file_name == entries.back().file_name)
        fail("{}: network {} has the name or file of network {}", source, i + 1, k + 1);
  }
  return entries;
}

const std::vector<ModelEntry>& model_catalogue() {
  // Read once: a command reads its environment at start.
  static const std::vector<ModelEntry> entries = load_catalogue();
  return entries;
}

bool in_catalogue(const std::string& name) {
  const auto& entries = model_catalogue();
  return std::any_of(entries.begin(), entries.end(), [&](const ModelEntry& e) { return e.name == name; });
}

const ModelEntry& catalogue_entry(const std::string& name) {
  std::string names;
  for (const ModelEntry& e : model_catalogue()) {
    if (e.name == name) return e;
    names += (names.empty() ? "" : ", ") + e.name;
  }
  fail("'{}' is not a network of the catalogue: {}", name, names);
}

}  // namespace ii
