#include "io/pth.h"

#include <cctype>
#include <fstream>
#include <set>

#include "common/error.h"
#include "common/files.h"
#include "io/byte_reader.h"
#include "io/zip_archive.h"

namespace ii {

namespace fs = std::filesystem;
using Kind = PickleValue::Kind;

namespace {

// `('storage', storage_class, key, location, numel[, view])`: the persistent id torch.save
// writes for each storage. Returns the dtype, key and element count.
struct StorageRef {
  std::string dtype, key;
  int64_t numel = 0;
};

StorageRef storage_ref(const fs::path& path, const std::string& where, const PickleValue& pid, size_t arity) {
  if (pid.kind != Kind::Tuple || pid.items->empty())
    fail_file(path, "{}: a persistent id that is a {}, not a storage reference", where, pid.kind_name());
  const auto& a = *pid.items;
  if (a[0].kind == Kind::String && a[0].text == "module")
    fail_file(path, "refusing to load: the checkpoint stores a whole nn.Module (Python source), not a state dict");
  if (a.size() != arity || a[0].kind != Kind::String || a[0].text != "storage")
    fail_file(path, "{}: a persistent id that is not ('storage', type, key, location, size)", where);
  if (a[1].kind != Kind::Global || pth_storage_dtype(a[1].text).empty())
    fail_file(path, "{}: unknown storage type {}", where, a[1].kind == Kind::Global ? a[1].text : a[1].kind_name());
  if (a[2].kind != Kind::String || a[2].text.empty() || a[2].text.size() > 1024)
    fail_file(path, "{}: a storage reference without a valid key", where);
  if (a[4].kind != Kind::Int || a[4].integer < 0)
    fail_file(path, "{}: storage {} has an invalid element count", where, a[2].text);
  return {pth_storage_dtype(a[1].text), a[2].text, a[4].integer};
}

// numel * item for messages, where a lying count may not fit 64 bits.
std::string byte_count_text(int64_t numel, uint64_t item) {
  const unsigned __int128 n = static_cast<unsigned __int128>(static_cast<uint64_t>(numel)) * item;
  return n > UINT64_MAX ? "more than 2^64" : std::to_string(static_cast<uint64_t>(n));
}

PickleValue storage_value(const StorageRef& ref, std::shared_ptr<const std::vector<uint8_t>> data) {
  PickleValue s;
  s.kind = Kind::Storage;
  s.text = ref.dtype;
  s.tensor = std::make_shared<PthTensor>();
  s.tensor->dtype = ref.dtype;
  s.tensor->shape = {ref.numel};
  s.tensor->stride = {1};
  s.tensor->storage = std::move(data);
  return s;
}

PickleValue read_zip(const fs::path& path, const PickleOptions& options) {
  const ZipArchive zip(path);
  // torch names every entry `<archive name>/...`; the archive name is free (the file stem
  // when saved), so find it from data.pkl.
  std::string pkl;
  for (const std::string& name : zip.names()) {
    const size_t slash = name.find('/');
    if (slash != std::string::npos && slash > 0 && name.compare(slash, std::string::npos, "/data.pkl") == 0) {
      pkl = name;
      break;
    }
  }
  if (pkl.empty()) fail_file(path, "zip archive has no <name>/data.pkl: not a PyTorch checkpoint");
  const std::string prefix = pkl.substr(0, pkl.size() - 8);  // "<name>/"
  // Written since torch 1.10; older archives are little-endian by definition.
  if (zip.has(prefix + "byteorder")) {
    if (zip.size(prefix + "byteorder") > 16) fail_file(path, "{}byteorder is not 'little' or 'big'", prefix);
    const auto bytes = zip.read(prefix + "byteorder");
    std::string order(bytes.begin(), bytes.end());
    while (!order.empty() && std::isspace(static_cast<unsigned char>(order.back()))) order.pop_back();
    if (order != "little")
      fail_file(path, "stores {} data (byteorder '{}'); only little-endian checkpoints are supported",
                order == "big" ? "big-endian" : "unknown-endian", order);
  }

  std::map<std::string, std::shared_ptr<const std::vector<uint8_t>>> storages;
  const PersistentLoad load = [&](const PickleValue& pid) {
    const StorageRef ref = storage_ref(path, pkl, pid, 5);
    auto it = storages.find(ref.key);
    const std::string entry = prefix + "data/" + ref.key;
    if (it == storages.end()) {
      if (!zip.has(entry)) fail_file(path, "storage {} is missing from the archive (no entry {})", ref.key, entry);
      it = storages.emplace(ref.key, std::make_shared<const std::vector<uint8_t>>(zip.read(entry))).first;
    }
    // Compared before anything else uses the data: the element count is what tensors are checked against.
    const uint64_t bytes = it->second->size(), item = pth_dtype_size(ref.dtype);
    if (bytes % item != 0 || bytes / item != static_cast<uint64_t>(ref.numel))
      fail_file(path, "storage {} holds {} bytes, but {} elements of {} need {}", ref.key, bytes, ref.numel, ref.dtype,
                byte_count_text(ref.numel, item));
    return storage_value(ref, it->second);
  };
  const std::vector<uint8_t> bytes = zip.read(pkl);
  ByteReader reader(bytes.data(), bytes.size(), path);
  return unpickle(reader, pkl, load, options);
}

// torch.save before 1.6 (or with _use_new_zipfile_serialization=False).
PickleValue read_legacy(const fs::path& path, const PickleOptions& options) {
  const std::vector<uint8_t> file = read_file_bytes(path);
  ByteReader r(file.data(), file.size(), path);
  const PickleValue magic = unpickle(r, "magic number pickle");
  // 0x1950a86a20f9469cfc6c as Python pickles it: ten little-endian bytes.
  static const std::string kMagic("\x6c\xfc\x9c\x46\xf9\x20\x6a\xa8\x50\x19", 10);
  if (magic.kind != Kind::BigInt || magic.text != kMagic)
    fail_file(path, "not a PyTorch checkpoint: a pickle without torch.save's magic number");
  const PickleValue version = unpickle(r, "protocol version pickle");
  if (version.kind != Kind::Int || version.integer != 1001)
    fail_file(path, "legacy checkpoint protocol {} is not the supported 1001",
              version.kind == Kind::Int ? std::to_string(version.integer) : version.kind_name());
  const PickleValue sys_info = unpickle(r, "system info pickle");
  if (const PickleValue* le = sys_info.get("little_endian"); le && le->kind == Kind::Bool && !le->boolean)
    fail_file(path, "stores big-endian data; only little-endian checkpoints are supported");

  struct Pending {
    StorageRef ref;
    std::shared_ptr<std::vector<uint8_t>> data;  // filled after the main pickle
    bool read = false;
  };
  std::map<std::string, Pending> storages;
  const PersistentLoad load = [&](const PickleValue& pid) {
    const StorageRef ref = storage_ref(path, "main pickle", pid, 6);
    if (pid.items->back().kind != Kind::None)
      fail_file(path, "storage {} is a view of another storage (pre-1.0 checkpoints): not supported", ref.key);
    auto it = storages.find(ref.key);
    if (it == storages.end()) {
      it = storages.emplace(ref.key, Pending{ref, std::make_shared<std::vector<uint8_t>>()}).first;
    } else if (it->second.ref.numel * pth_dtype_size(it->second.ref.dtype) != ref.numel * pth_dtype_size(ref.dtype)) {
      fail_file(path, "storage {} is declared with two different sizes", ref.key);
    }
    return storage_value(ref, it->second.data);
  };
  const PickleValue result = unpickle(r, "main pickle", load, options);
  const PickleValue keys = unpickle(r, "storage key pickle");
  if (keys.kind != Kind::List) fail_file(path, "the storage key pickle is a {}, not a list", keys.kind_name());
  for (const PickleValue& key : *keys.items) {
    if (key.kind != Kind::String) fail_file(path, "the storage key list holds a {}", key.kind_name());
    auto it = storages.find(key.text);
    if (it == storages.end()) fail_file(path, "storage {} has data but no tensor refers to it", key.text);
    Pending& s = it->second;
    if (s.read) fail_file(path, "storage {} is listed twice", key.text);
    s.read = true;
    const size_t at = r.position();
    const int64_t count = r.read<int64_t>("storage element count");
    if (count != s.ref.numel)
      fail_file(path, "storage {} at byte {} holds {} elements, its tensors expect {}", key.text, at, count, s.ref.numel);
    const uint64_t item = pth_dtype_size(s.ref.dtype);
    if (static_cast<uint64_t>(count) > r.remaining() / item)
      fail_file(path, "truncated file: storage {} needs {} bytes at byte {}, only {} left", key.text,
                byte_count_text(count, item), r.position(), r.remaining());
    s.data->resize(static_cast<size_t>(count) * item);
    r.read_bytes(s.data->data(), s.data->size(), "storage data");
  }
  for (const auto& [key, s] : storages)
    if (!s.read) fail_file(path, "storage {} has no data in the file", key);
  return result;
}

}  // namespace

PickleValue read_pth(const fs::path& path, const PickleOptions& options) {
  std::error_code ec;
  if (!fs::exists(path, ec)) fail_file(path, "file not found");
  if (fs::is_directory(path, ec)) fail_file(path, "is a directory, expected a .pth file");
  char head[2] = {0, 0};
  {
    std::ifstream in(path, std::ios::binary);
    if (!in) fail_file(path, "cannot open for reading");
    in.read(head, 2);
  }
  if (head[0] == 'P' && head[1] == 'K') return read_zip(path, options);
  if (static_cast<uint8_t>(head[0]) == 0x80) return read_legacy(path, options);  // a pickle's PROTO opcode
  fail_file(path, "not a PyTorch checkpoint: neither a zip archive (torch.save since 1.6) nor a legacy torch.save stream");
}

std::map<std::string, PthTensor> read_pth_tensors(const fs::path& path, const PickleOptions& options) {
  std::map<std::string, PthTensor> out;
  collect_tensors(read_pth(path, options), "", out, path);
  return out;
}

std::string read_pth_extras_json(const fs::path& path) { return extras_to_json(read_pth(path)); }

}  // namespace ii
