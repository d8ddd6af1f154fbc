#pragma once
// A restricted reader for the Python pickles inside PyTorch checkpoints. It understands the
// opcodes torch.save writes (protocols 2-5) and a fixed allow-list of globals — tensor and
// storage rebuilds, OrderedDict, argparse.Namespace, set, bytes — each turned into plain
// data. It never imports or calls anything: any other global is an Error, so a hostile
// pickle cannot run code. Sizes, nesting and sharing are bounded by the input's size, so a
// lying pickle cannot make it allocate absurd amounts either.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace ii {

class ByteReader;

// A tensor as a checkpoint stores it: a strided view into a shared byte storage.
struct PthTensor {
  std::string dtype;                   // safetensors names: F64 F32 F16 BF16 I64 I32 I16 I8 U8 BOOL
  std::vector<int64_t> shape, stride;  // in elements
  int64_t storage_offset = 0;          // in elements
  std::shared_ptr<const std::vector<uint8_t>> storage;  // little-endian bytes

  int64_t numel() const;
  size_t item_size() const;
  std::vector<uint8_t> contiguous_bytes() const;  // C order, little-endian
  std::vector<float> to_float() const;            // any dtype, converted to float
};

// Bytes per element of a safetensors dtype name; 0 if unknown.
size_t pth_dtype_size(const std::string& dtype);

// The element type a torch storage class name ("torch.FloatStorage") stands for; "" if unknown.
std::string pth_storage_dtype(const std::string& storage_class);

struct PickleValue {
  enum class Kind { None, Bool, Int, BigInt, Float, String, Bytes, List, Tuple, Dict, Tensor, Global, Storage };
  Kind kind = Kind::None;
  bool boolean = false;
  int64_t integer = 0;
  double real = 0;  // Float; BigInt's approximate value
  // String (UTF-8 as stored), Bytes, Global ("module.name"), BigInt (little-endian two's
  // complement bytes, as pickled), Dict (its class: "" for a dict, "collections.OrderedDict",
  // "argparse.Namespace", or with PickleOptions::opaque_objects any other class whose instance it
  // stands for), Storage (dtype).
  std::string text;
  std::shared_ptr<std::vector<PickleValue>> items;                            // List, Tuple
  std::shared_ptr<std::vector<std::pair<PickleValue, PickleValue>>> entries;  // Dict, in order
  // Tensor; Storage: the whole storage (or a legacy view of it), its element count in shape[0].
  std::shared_ptr<PthTensor> tensor;

  const PickleValue* get(const std::string& key) const;  // Dict lookup by string key
  const char* kind_name() const;
};

// Resolves a persistent id (the pickle's reference to a storage kept outside it) to a Storage
// value. It is handed the id as unpickled; the unpickler checks what it returns.
using PersistentLoad = std::function<PickleValue(const PickleValue& pid)>;

struct PickleOptions {
  // A global outside the allow-list (a class, a function) is an opaque value instead of an
  // Error, and an instance made from one a dict of the attributes its BUILD gives it (its
  // arguments dropped; a state that is not attributes dropped): still never imported nor called.
  // For checkpoints that keep training objects beside their tensors (PyTorch Lightning's: its
  // callbacks' classes as keys, their states) and TorchScript archives (modules as objects whose
  // attributes hold their parameters and submodules).
  bool opaque_objects = false;
};

// Reads one pickle from `reader`'s position through its STOP opcode and leaves the reader
// just after it. Errors read "<file>: <name> byte <offset>: <problem>", offsets being reader
// positions. Without `persistent_load`, a persistent id is an error.
PickleValue unpickle(ByteReader& reader, const std::string& name, const PersistentLoad& persistent_load = {},
                     const PickleOptions& options = {});

// Every tensor in nested dicts, lists and tuples, under dotted keys: dict keys as text, list
// positions as numbers ("gaudecoder.module.blocks.0.attn.qkv.weight_v", "optimizer.state.3.exp_avg").
// Two tensors flattening to one key is an Error naming `file`.
void collect_tensors(const PickleValue& value, const std::string& prefix, std::map<std::string, PthTensor>& out,
                     const std::filesystem::path& file = {});

// Everything that is not a tensor, as JSON text: containers that held only tensors are left
// out, bytes become "<N bytes>", sets and tuples become arrays, non-string keys their JSON text.
std::string extras_to_json(const PickleValue& value);

}  // namespace ii
