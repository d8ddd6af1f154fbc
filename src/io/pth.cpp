#include "io/pth.h"

#include <zip.h>

#include <cstring>
#include <set>

#include <nlohmann/json.hpp>

#include "common/error.h"
#include "io/byte_reader.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

size_t item_size(const std::string& dtype) {
  static const std::map<std::string, size_t> sizes = {{"F32", 4}, {"F64", 8}, {"F16", 2}, {"BF16", 2}, {"I64", 8},
                                                      {"I32", 4}, {"I16", 2}, {"I8", 1},  {"U8", 1},   {"BOOL", 1}};
  auto it = sizes.find(dtype);
  return it == sizes.end() ? 0 : it->second;
}

// torch storage classes -> element type.
const std::map<std::string, std::string>& storage_types() {
  static const std::map<std::string, std::string> types = {
      {"torch.FloatStorage", "F32"},  {"torch.DoubleStorage", "F64"}, {"torch.HalfStorage", "F16"},
      {"torch.BFloat16Storage", "BF16"}, {"torch.LongStorage", "I64"}, {"torch.IntStorage", "I32"},
      {"torch.ShortStorage", "I16"},  {"torch.CharStorage", "I8"},   {"torch.ByteStorage", "U8"},
      {"torch.BoolStorage", "BOOL"}};
  return types;
}

// Globals a checkpoint may reference. Each is turned into data; none is ever called.
const std::set<std::string>& allowed_globals() {
  static const std::set<std::string> names = {"collections.OrderedDict", "torch._utils._rebuild_tensor_v2",
                                              "torch._utils._rebuild_parameter", "argparse.Namespace",
                                              "_codecs.encode", "builtins.set", "builtins.frozenset"};
  return names;
}

class ZipArchive {
 public:
  explicit ZipArchive(const fs::path& path) : path_(path) {
    int err = 0;
    zip_ = zip_open(path.c_str(), ZIP_RDONLY, &err);
    if (!zip_) {
      if (!fs::exists(path)) fail_file(path, "file not found");
      zip_error_t ze;
      zip_error_init_with_code(&ze, err);
      std::string why = zip_error_strerror(&ze);
      zip_error_fini(&ze);
      fail_file(path, "not a PyTorch zip checkpoint ({}); legacy (pre-1.6) checkpoints are not supported: "
                      "re-save it with a current PyTorch or convert it to safetensors", why);
    }
  }
  ~ZipArchive() { zip_discard(zip_); }
  ZipArchive(const ZipArchive&) = delete;
  ZipArchive& operator=(const ZipArchive&) = delete;

  std::vector<std::string> names() const {
    std::vector<std::string> out;
    const zip_int64_t n = zip_get_num_entries(zip_, 0);
    for (zip_int64_t i = 0; i < n; ++i)
      if (const char* name = zip_get_name(zip_, i, 0)) out.emplace_back(name);
    return out;
  }

  bool has(const std::string& name) const { return zip_name_locate(zip_, name.c_str(), 0) >= 0; }

  std::vector<uint8_t> read(const std::string& name) const {
    zip_stat_t st;
    zip_stat_init(&st);
    if (zip_stat(zip_, name.c_str(), 0, &st) != 0) fail_file(path_, "archive has no entry {}", name);
    if (!(st.valid & ZIP_STAT_SIZE) || st.size > (1ULL << 40)) fail_file(path_, "entry {} has an invalid size", name);
    zip_file_t* f = zip_fopen(zip_, name.c_str(), 0);
    if (!f) fail_file(path_, "cannot open archive entry {}: {}", name, zip_strerror(zip_));
    std::vector<uint8_t> data(st.size);
    const zip_int64_t got = st.size ? zip_fread(f, data.data(), st.size) : 0;
    zip_fclose(f);
    if (got < 0 || static_cast<zip_uint64_t>(got) != st.size)
      fail_file(path_, "archive entry {} is truncated or corrupt", name);
    return data;
  }

 private:
  fs::path path_;
  zip_t* zip_ = nullptr;
};

PickleValue make(PickleValue::Kind kind) {
  PickleValue v;
  v.kind = kind;
  if (kind == PickleValue::Kind::List || kind == PickleValue::Kind::Tuple)
    v.items = std::make_shared<std::vector<PickleValue>>();
  if (kind == PickleValue::Kind::Dict) v.entries = std::make_shared<std::vector<std::pair<PickleValue, PickleValue>>>();
  return v;
}

PickleValue make_int(int64_t i) {
  PickleValue v = make(PickleValue::Kind::Int);
  v.integer = i;
  return v;
}

PickleValue make_text(PickleValue::Kind kind, std::string s) {
  PickleValue v = make(kind);
  v.text = std::move(s);
  return v;
}

class Unpickler {
 public:
  Unpickler(const std::vector<uint8_t>& bytes, const fs::path& file, const ZipArchive& zip, std::string prefix)
      : r_(bytes.data(), bytes.size(), file), file_(file), zip_(zip), prefix_(std::move(prefix)) {}

  PickleValue run() {
    while (true) {
      const size_t at = r_.position();
      const uint8_t op = r_.read<uint8_t>("pickle opcode");
      switch (op) {
        case 0x80: r_.read<uint8_t>("protocol"); break;                        // PROTO
        case 0x95: r_.read<uint64_t>("frame size"); break;                     // FRAME
        case '.': return pop("STOP");                                          // STOP
        case '(': marks_.push_back(stack_.size()); break;                      // MARK
        case '}': push(make(PickleValue::Kind::Dict)); break;                  // EMPTY_DICT
        case ']': push(make(PickleValue::Kind::List)); break;                  // EMPTY_LIST
        case ')': push(make(PickleValue::Kind::Tuple)); break;                 // EMPTY_TUPLE
        case 'N': push(make(PickleValue::Kind::None)); break;                  // NONE
        case 0x88: case 0x89: {                                                // NEWTRUE/NEWFALSE
          PickleValue v = make(PickleValue::Kind::Bool);
          v.boolean = op == 0x88;
          push(v);
          break;
        }
        case 'K': push(make_int(r_.read<uint8_t>("BININT1"))); break;
        case 'M': push(make_int(r_.read<uint16_t>("BININT2"))); break;
        case 'J': push(make_int(r_.read<int32_t>("BININT"))); break;
        case 0x8a: case 0x8b: {                                                // LONG1/LONG4
          const uint32_t n = op == 0x8a ? r_.read<uint8_t>("LONG1 size") : r_.read<uint32_t>("LONG4 size");
          if (n > 8) fail_at(at, "integer of {} bytes is too large", n);
          uint64_t u = 0;
          for (uint32_t i = 0; i < n; ++i) u |= static_cast<uint64_t>(r_.read<uint8_t>("LONG bytes")) << (8 * i);
          if (n > 0 && n < 8 && (u >> (8 * n - 1)) & 1) u |= ~0ULL << (8 * n);  // sign-extend
          push(make_int(static_cast<int64_t>(u)));
          break;
        }
        case 'G': {                                                            // BINFLOAT (big-endian)
          uint64_t bits = 0;
          for (int i = 0; i < 8; ++i) bits = (bits << 8) | r_.read<uint8_t>("BINFLOAT");
          PickleValue v = make(PickleValue::Kind::Float);
          std::memcpy(&v.real, &bits, 8);
          push(v);
          break;
        }
        case 0x8c: push(make_text(PickleValue::Kind::String, r_.read_string(r_.read<uint8_t>("length"), "string"))); break;
        case 'X': push(make_text(PickleValue::Kind::String, r_.read_string(r_.read<uint32_t>("length"), "string"))); break;
        case 0x8d: push(make_text(PickleValue::Kind::String, r_.read_string(checked_len(r_.read<uint64_t>("length")), "string"))); break;
        case 'C': push(make_text(PickleValue::Kind::Bytes, r_.read_string(r_.read<uint8_t>("length"), "bytes"))); break;
        case 'B': push(make_text(PickleValue::Kind::Bytes, r_.read_string(r_.read<uint32_t>("length"), "bytes"))); break;
        case 0x8e: push(make_text(PickleValue::Kind::Bytes, r_.read_string(checked_len(r_.read<uint64_t>("length")), "bytes"))); break;
        case 'q': memo_put(r_.read<uint8_t>("BINPUT index")); break;
        case 'r': memo_put(r_.read<uint32_t>("LONG_BINPUT index")); break;
        case 0x94: memo_put(memo_.size()); break;                              // MEMOIZE
        case 'h': memo_get(r_.read<uint8_t>("BINGET index"), at); break;
        case 'j': memo_get(r_.read<uint32_t>("LONG_BINGET index"), at); break;
        case 't': push(tuple_of(pop_mark("TUPLE"))); break;
        case 0x85: case 0x86: case 0x87: {                                     // TUPLE1/2/3
          const size_t n = op - 0x84;
          if (stack_.size() < n + base()) fail_at(at, "stack underflow in TUPLE{}", n);
          std::vector<PickleValue> items(stack_.end() - n, stack_.end());
          stack_.resize(stack_.size() - n);
          push(tuple_of(std::move(items)));
          break;
        }
        case 'a': {                                                            // APPEND
          PickleValue v = pop("APPEND");
          list_target("APPEND", at).items->push_back(std::move(v));
          break;
        }
        case 'e': {                                                            // APPENDS
          auto items = pop_mark("APPENDS");
          auto& list = list_target("APPENDS", at);
          list.items->insert(list.items->end(), items.begin(), items.end());
          break;
        }
        case 's': {                                                            // SETITEM
          PickleValue value = pop("SETITEM");
          PickleValue key = pop("SETITEM");
          dict_target("SETITEM", at).entries->emplace_back(std::move(key), std::move(value));
          break;
        }
        case 'u': {                                                            // SETITEMS
          auto items = pop_mark("SETITEMS");
          if (items.size() % 2) fail_at(at, "SETITEMS with an odd number of values");
          auto& dict = dict_target("SETITEMS", at);
          for (size_t i = 0; i < items.size(); i += 2) dict.entries->emplace_back(items[i], items[i + 1]);
          break;
        }
        case 'c': {                                                            // GLOBAL
          std::string module = read_line(), name = read_line();
          push(global(module + "." + name, at));
          break;
        }
        case 0x93: {                                                           // STACK_GLOBAL
          PickleValue name = pop("STACK_GLOBAL"), module = pop("STACK_GLOBAL");
          if (name.kind != PickleValue::Kind::String || module.kind != PickleValue::Kind::String)
            fail_at(at, "STACK_GLOBAL needs two strings");
          push(global(module.text + "." + name.text, at));
          break;
        }
        case 'Q': {                                                            // BINPERSID
          push(persistent_load(pop("BINPERSID"), at));
          break;
        }
        case 'R': {                                                            // REDUCE
          PickleValue args = pop("REDUCE"), callable = pop("REDUCE");
          push(reduce(callable, args, at));
          break;
        }
        case 0x81: {                                                           // NEWOBJ
          PickleValue args = pop("NEWOBJ"), cls = pop("NEWOBJ");
          push(reduce(cls, args, at));
          break;
        }
        case 'b': {                                                            // BUILD
          PickleValue state = pop("BUILD");
          PickleValue& target = top("BUILD", at);
          // argparse.Namespace: its attribute dict becomes the dict itself. An OrderedDict
          // state (e.g. a state dict's _metadata) carries nothing we need.
          if (target.kind == PickleValue::Kind::Dict && target.entries->empty() && state.kind == PickleValue::Kind::Dict)
            *target.entries = *state.entries;
          break;
        }
        case 0x8f: push(make(PickleValue::Kind::List)); break;                 // EMPTY_SET (as a list)
        case 0x90: {                                                           // ADDITEMS
          auto items = pop_mark("ADDITEMS");
          auto& set = list_target("ADDITEMS", at);
          set.items->insert(set.items->end(), items.begin(), items.end());
          break;
        }
        default:
          fail_at(at, "unsupported pickle opcode 0x{:02x}", op);
      }
    }
  }

 private:
  template <typename... Args>
  [[noreturn]] void fail_at(size_t at, fmt::format_string<Args...> f, Args&&... args) {
    fail_file(file_, "data.pkl byte {}: {}", at, fmt::format(f, std::forward<Args>(args)...));
  }

  size_t checked_len(uint64_t n) {
    if (n > r_.remaining()) r_.require(n, "string");
    return static_cast<size_t>(n);
  }

  size_t base() const { return marks_.empty() ? 0 : marks_.back(); }

  void push(PickleValue v) {
    if (stack_.size() > 100000) fail_file(file_, "data.pkl: pickle stack too deep");
    stack_.push_back(std::move(v));
  }

  PickleValue pop(const char* op) {
    if (stack_.size() <= base()) fail_file(file_, "data.pkl: stack underflow in {}", op);
    PickleValue v = std::move(stack_.back());
    stack_.pop_back();
    return v;
  }

  PickleValue& top(const char* op, size_t at) {
    if (stack_.size() <= base()) fail_at(at, "stack underflow in {}", op);
    return stack_.back();
  }

  std::vector<PickleValue> pop_mark(const char* op) {
    if (marks_.empty()) fail_file(file_, "data.pkl: {} without a MARK", op);
    const size_t m = marks_.back();
    marks_.pop_back();
    std::vector<PickleValue> items(stack_.begin() + m, stack_.end());
    stack_.resize(m);
    return items;
  }

  PickleValue& list_target(const char* op, size_t at) {
    PickleValue& t = top(op, at);
    if (t.kind != PickleValue::Kind::List) fail_at(at, "{} on something that is not a list", op);
    return t;
  }

  PickleValue& dict_target(const char* op, size_t at) {
    PickleValue& t = top(op, at);
    if (t.kind != PickleValue::Kind::Dict) fail_at(at, "{} on something that is not a dict", op);
    return t;
  }

  static PickleValue tuple_of(std::vector<PickleValue> items) {
    PickleValue t = make(PickleValue::Kind::Tuple);
    *t.items = std::move(items);
    return t;
  }

  void memo_put(size_t index) {
    if (stack_.empty()) fail_file(file_, "data.pkl: memo store with an empty stack");
    if (index > 10000000) fail_file(file_, "data.pkl: memo index {} is implausible", index);
    memo_[index] = stack_.back();
  }

  void memo_get(size_t index, size_t at) {
    auto it = memo_.find(index);
    if (it == memo_.end()) fail_at(at, "memo index {} was never stored", index);
    push(it->second);
  }

  std::string read_line() {
    std::string s;
    while (true) {
      const char c = static_cast<char>(r_.read<uint8_t>("GLOBAL name"));
      if (c == '\n') return s;
      if (s.size() > 256) fail_file(file_, "data.pkl: GLOBAL name too long");
      s.push_back(c);
    }
  }

  PickleValue global(const std::string& name, size_t at) {
    if (!allowed_globals().count(name) && !storage_types().count(name))
      fail_file(file_, "refusing to load: the pickle references '{}', which is not a tensor, container or plain value",
                name);
    return make_text(PickleValue::Kind::Global, name);
  }

  PickleValue persistent_load(const PickleValue& pid, size_t at) {
    // ('storage', storage_type, key, location, numel)
    if (pid.kind != PickleValue::Kind::Tuple || pid.items->size() < 5 || (*pid.items)[0].text != "storage")
      fail_at(at, "unexpected persistent id (expected a storage reference)");
    const auto& it = *pid.items;
    if (it[1].kind != PickleValue::Kind::Global || !storage_types().count(it[1].text))
      fail_at(at, "unknown storage type '{}'", it[1].text);
    if (it[2].kind != PickleValue::Kind::String || it[4].kind != PickleValue::Kind::Int || it[4].integer < 0)
      fail_at(at, "malformed storage reference");
    const std::string dtype = storage_types().at(it[1].text), key = it[2].text;
    auto cached = storages_.find(key);
    if (cached == storages_.end()) {
      const std::string entry = prefix_ + "data/" + key;
      if (!zip_.has(entry)) fail_file(file_, "storage {} is missing from the archive (no entry {})", key, entry);
      auto data = std::make_shared<const std::vector<uint8_t>>(zip_.read(entry));
      const uint64_t need = static_cast<uint64_t>(it[4].integer) * item_size(dtype);
      if (data->size() < need)
        fail_file(file_, "storage {} holds {} bytes, its {} elements of {} need {}", key, data->size(), it[4].integer, dtype, need);
      cached = storages_.emplace(key, data).first;
    }
    PickleValue s = make_text(PickleValue::Kind::Storage, dtype);
    s.tensor = std::make_shared<PthTensor>();
    s.tensor->dtype = dtype;
    s.tensor->storage = cached->second;
    return s;
  }

  std::vector<int64_t> int_tuple(const PickleValue& v, const char* what, size_t at) {
    if (v.kind != PickleValue::Kind::Tuple) fail_at(at, "tensor {} is not a tuple", what);
    std::vector<int64_t> out;
    for (const PickleValue& x : *v.items) {
      if (x.kind != PickleValue::Kind::Int || x.integer < 0) fail_at(at, "tensor {} holds a non-integer or negative value", what);
      out.push_back(x.integer);
    }
    return out;
  }

  PickleValue reduce(const PickleValue& callable, const PickleValue& args, size_t at) {
    if (callable.kind != PickleValue::Kind::Global) fail_at(at, "REDUCE on something that is not an allowed global");
    if (args.kind != PickleValue::Kind::Tuple) fail_at(at, "REDUCE arguments are not a tuple");
    const auto& a = *args.items;
    const std::string& name = callable.text;
    if (name == "collections.OrderedDict" || name == "argparse.Namespace") {
      if (!a.empty()) fail_at(at, "{} with constructor arguments is not supported", name);
      return make(PickleValue::Kind::Dict);
    }
    if (name == "builtins.set" || name == "builtins.frozenset") {
      PickleValue l = make(PickleValue::Kind::List);
      if (!a.empty() && a[0].items) *l.items = *a[0].items;
      return l;
    }
    if (name == "_codecs.encode") {  // protocol-2 bytes: encode(str, 'latin1')
      if (a.empty() || a[0].kind != PickleValue::Kind::String) fail_at(at, "malformed _codecs.encode call");
      std::string out;
      // latin1: each code point < 256 becomes one byte (the str is UTF-8 here).
      for (size_t i = 0; i < a[0].text.size(); ++i) {
        const uint8_t c = a[0].text[i];
        if (c < 0x80) out.push_back(c);
        else if ((c & 0xe0) == 0xc0 && i + 1 < a[0].text.size())
          out.push_back(static_cast<char>(((c & 0x1f) << 6) | (a[0].text[++i] & 0x3f)));
        else fail_at(at, "_codecs.encode: character outside latin1");
      }
      return make_text(PickleValue::Kind::Bytes, out);
    }
    if (name == "torch._utils._rebuild_parameter") {
      if (a.empty() || a[0].kind != PickleValue::Kind::Tensor) fail_at(at, "malformed _rebuild_parameter call");
      return a[0];
    }
    if (name == "torch._utils._rebuild_tensor_v2") {
      if (a.size() < 4 || a[0].kind != PickleValue::Kind::Storage || a[1].kind != PickleValue::Kind::Int)
        fail_at(at, "malformed _rebuild_tensor_v2 call");
      auto t = std::make_shared<PthTensor>(*a[0].tensor);
      t->storage_offset = a[1].integer;
      t->shape = int_tuple(a[2], "size", at);
      t->stride = int_tuple(a[3], "stride", at);
      if (t->shape.size() != t->stride.size()) fail_at(at, "tensor size and stride differ in length");
      // Largest element index must lie inside the storage.
      const uint64_t elements = t->storage->size() / item_size(t->dtype);
      uint64_t last = static_cast<uint64_t>(t->storage_offset);
      bool empty = false;
      for (size_t d = 0; d < t->shape.size(); ++d) {
        if (t->shape[d] == 0) empty = true;
        else if (t->shape[d] > (1LL << 40) || t->stride[d] > (1LL << 40)) fail_at(at, "implausible tensor size or stride");
        else last += static_cast<uint64_t>(t->shape[d] - 1) * static_cast<uint64_t>(t->stride[d]);
      }
      if (!empty && last >= elements)
        fail_file(file_, "a tensor of size [{}] reaches element {} of a storage with {} elements",
                  fmt::join(t->shape, ", "), last, elements);
      PickleValue v = make(PickleValue::Kind::Tensor);
      v.tensor = t;
      return v;
    }
    fail_at(at, "refusing to call '{}'", name);
  }

  ByteReader r_;
  fs::path file_;
  const ZipArchive& zip_;
  std::string prefix_;
  std::vector<PickleValue> stack_;
  std::vector<size_t> marks_;
  std::map<size_t, PickleValue> memo_;
  std::map<std::string, std::shared_ptr<const std::vector<uint8_t>>> storages_;
};

std::string key_text(const PickleValue& k) {
  if (k.kind == PickleValue::Kind::String) return k.text;
  if (k.kind == PickleValue::Kind::Int) return std::to_string(k.integer);
  return "?";
}

nlohmann::json to_json(const PickleValue& v) {
  using K = PickleValue::Kind;
  switch (v.kind) {
    case K::None: return nullptr;
    case K::Bool: return v.boolean;
    case K::Int: return v.integer;
    case K::Float: return v.real;
    case K::String: return v.text;
    case K::Bytes: return fmt::format("<{} bytes>", v.text.size());
    case K::Global: return "<" + v.text + ">";
    case K::List: case K::Tuple: {
      nlohmann::json a = nlohmann::json::array();
      for (const auto& x : *v.items)
        if (x.kind != K::Tensor) a.push_back(to_json(x));
      return a;
    }
    case K::Dict: {
      nlohmann::json o = nlohmann::json::object();
      for (const auto& [k, x] : *v.entries)
        if (x.kind != K::Tensor && !(x.kind == K::Dict && !x.entries->empty() && x.entries->front().second.kind == K::Tensor))
          o[key_text(k)] = to_json(x);
      return o;
    }
    default: return nullptr;
  }
}

}  // namespace

int64_t PthTensor::numel() const {
  int64_t n = 1;
  for (int64_t s : shape) n *= s;
  return n;
}

std::vector<uint8_t> PthTensor::contiguous_bytes() const {
  const size_t item = item_size(dtype);
  const int64_t n = numel();
  std::vector<uint8_t> out(static_cast<size_t>(n) * item);
  std::vector<int64_t> idx(shape.size(), 0);
  for (int64_t i = 0; i < n; ++i) {
    int64_t src = storage_offset;
    for (size_t d = 0; d < shape.size(); ++d) src += idx[d] * stride[d];
    std::memcpy(&out[static_cast<size_t>(i) * item], storage->data() + static_cast<size_t>(src) * item, item);
    for (size_t d = shape.size(); d-- > 0;) {
      if (++idx[d] < shape[d]) break;
      idx[d] = 0;
    }
  }
  return out;
}

std::vector<float> PthTensor::to_float() const {
  if (dtype != "F32") fail("tensor of dtype {}: only F32 converts directly", dtype);
  const auto bytes = contiguous_bytes();
  std::vector<float> out(bytes.size() / 4);
  std::memcpy(out.data(), bytes.data(), bytes.size());
  return out;
}

const PickleValue* PickleValue::get(const std::string& key) const {
  if (kind != Kind::Dict) return nullptr;
  for (const auto& [k, v] : *entries)
    if (k.kind == Kind::String && k.text == key) return &v;
  return nullptr;
}

PickleValue read_pth(const fs::path& path) {
  const ZipArchive zip(path);
  std::string pkl;
  for (const std::string& name : zip.names()) {
    const size_t slash = name.find('/');
    if (slash != std::string::npos && name.compare(slash, std::string::npos, "/data.pkl") == 0) {
      pkl = name;
      break;
    }
  }
  if (pkl.empty()) fail_file(path, "zip archive has no <name>/data.pkl: not a PyTorch checkpoint");
  if (const std::string bo = pkl.substr(0, pkl.size() - 8) + "byteorder"; zip.has(bo)) {
    const auto order = zip.read(bo);
    if (std::string(order.begin(), order.end()) != "little") fail_file(path, "big-endian checkpoints are not supported");
  }
  const std::vector<uint8_t> bytes = zip.read(pkl);
  Unpickler u(bytes, path, zip, pkl.substr(0, pkl.size() - 8));
  return u.run();
}

void collect_tensors(const PickleValue& value, const std::string& prefix, std::map<std::string, PthTensor>& out) {
  using K = PickleValue::Kind;
  if (value.kind == K::Tensor) {
    out[prefix] = *value.tensor;
  } else if (value.kind == K::Dict) {
    for (const auto& [k, v] : *value.entries) collect_tensors(v, prefix.empty() ? key_text(k) : prefix + "." + key_text(k), out);
  } else if (value.kind == K::List || value.kind == K::Tuple) {
    for (size_t i = 0; i < value.items->size(); ++i)
      collect_tensors((*value.items)[i], prefix.empty() ? std::to_string(i) : prefix + "." + std::to_string(i), out);
  }
}

std::string extras_to_json(const PickleValue& value) { return to_json(value).dump(); }

std::map<std::string, PthTensor> read_pth_tensors(const fs::path& path) {
  std::map<std::string, PthTensor> out;
  collect_tensors(read_pth(path), "", out);
  return out;
}

std::string read_pth_extras_json(const fs::path& path) { return extras_to_json(read_pth(path)); }

}  // namespace ii
