#pragma once
// PyTorch `.pth` checkpoints (the zip container written by torch.save since 1.6) read
// without Python. The pickle inside is interpreted by a restricted unpickler that knows
// exactly the objects checkpoints hold — dicts, lists, tuples, plain values, tensor rebuild
// calls, storages, OrderedDict and argparse.Namespace (as plain dicts) — and refuses every
// other global. It never calls or imports anything: a malicious pickle is an error.
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace ii {

struct PthTensor {
  std::string dtype;  // safetensors names: F32 F64 F16 BF16 I64 I32 I16 I8 U8 BOOL
  std::vector<int64_t> shape, stride;
  int64_t storage_offset = 0;  // in elements
  std::shared_ptr<const std::vector<uint8_t>> storage;

  int64_t numel() const;
  std::vector<uint8_t> contiguous_bytes() const;  // C order
  std::vector<float> to_float() const;
};

struct PickleValue {
  enum class Kind { None, Bool, Int, Float, String, Bytes, List, Tuple, Dict, Tensor, Global, Storage };
  Kind kind = Kind::None;
  bool boolean = false;
  int64_t integer = 0;
  double real = 0;
  std::string text;  // String, Bytes, Global ("module.name"), Storage dtype
  std::shared_ptr<std::vector<PickleValue>> items;                           // List, Tuple
  std::shared_ptr<std::vector<std::pair<PickleValue, PickleValue>>> entries;  // Dict, in order
  std::shared_ptr<PthTensor> tensor;                                          // Tensor, Storage

  const PickleValue* get(const std::string& key) const;  // Dict lookup by string key
};

// The whole object tree of a checkpoint.
PickleValue read_pth(const std::filesystem::path& path);

// Every tensor in nested dicts (and lists), under dotted keys ("gaudecoder.module.blocks.0...").
std::map<std::string, PthTensor> read_pth_tensors(const std::filesystem::path& path);

// Everything that is not a tensor (training arguments, epoch, ...), as JSON text.
std::string read_pth_extras_json(const std::filesystem::path& path);

// Tree helpers, shared by the two functions above (exposed for tests).
void collect_tensors(const PickleValue& value, const std::string& prefix, std::map<std::string, PthTensor>& out);
std::string extras_to_json(const PickleValue& value);

}  // namespace ii
