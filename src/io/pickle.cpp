#include "io/pickle.h"

#include <cmath>
#include <cstring>
#include <optional>
#include <unordered_map>
#include <unordered_set>

#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include "common/error.h"
#include "io/byte_reader.h"
#include "io/half.h"

namespace ii {

namespace fs = std::filesystem;
using Kind = PickleValue::Kind;
using Items = std::vector<PickleValue>;
using Entries = std::vector<std::pair<PickleValue, PickleValue>>;

namespace {

// A checkpoint's pickle nests about five levels and keeps a few thousand values on its
// stack and memo; these limits leave a wide margin while keeping a hostile pickle's cost
// proportional to its size.
constexpr size_t kMaxDepth = 256;      // container nesting
constexpr size_t kMaxStack = 1 << 18;  // values and marks on the stack
constexpr size_t kMaxMemo = 1 << 20;   // memo entries
constexpr size_t kMaxDims = 64;        // tensor rank
constexpr size_t kMaxNameLength = 1024;
constexpr uint64_t kMaxDimSize = uint64_t{1} << 48;
// An expanded tensor (a stride-0 view) may hold more elements than its storage; beyond this
// size it must be backed by real data, or a few bytes of pickle could ask for terabytes.
constexpr uint64_t kMaxExpandedBytes = uint64_t{1} << 20;

// torch storage classes -> element type. Their names only tag storages; they are never called.
const std::map<std::string, std::string>& storage_dtypes() {
  static const std::map<std::string, std::string> types = {
      {"torch.FloatStorage", "F32"},   {"torch.DoubleStorage", "F64"},        {"torch.HalfStorage", "F16"},
      {"torch.BFloat16Storage", "BF16"}, {"torch.LongStorage", "I64"},        {"torch.IntStorage", "I32"},
      {"torch.ShortStorage", "I16"},   {"torch.CharStorage", "I8"},           {"torch.ByteStorage", "U8"},
      {"torch.BoolStorage", "BOOL"},   {"torch.UntypedStorage", "U8"},        {"torch.storage.UntypedStorage", "U8"}};
  return types;
}

// What each allowed global becomes. None of them is ever called: REDUCE/NEWOBJ on them
// builds the equivalent plain data.
enum class Builtin { OrderedDict, Namespace, Set, Bytes, CodecsEncode, RebuildTensor, RebuildParameter, TorchSize };

const std::map<std::string, Builtin>& allowed_callables() {
  static const std::map<std::string, Builtin> names = {
      {"collections.OrderedDict", Builtin::OrderedDict},
      {"argparse.Namespace", Builtin::Namespace},
      // Protocol-2 pickles name builtins by their Python 2 module, __builtin__.
      {"builtins.set", Builtin::Set},
      {"builtins.frozenset", Builtin::Set},
      {"__builtin__.set", Builtin::Set},
      {"__builtin__.frozenset", Builtin::Set},
      {"builtins.bytes", Builtin::Bytes},
      {"__builtin__.bytes", Builtin::Bytes},
      {"_codecs.encode", Builtin::CodecsEncode},
      {"torch._utils._rebuild_tensor_v2", Builtin::RebuildTensor},
      {"torch._utils._rebuild_tensor", Builtin::RebuildTensor},
      {"torch._utils._rebuild_parameter", Builtin::RebuildParameter},
      {"torch._utils._rebuild_parameter_with_state", Builtin::RebuildParameter},
      {"torch.Size", Builtin::TorchSize}};
  return names;
}

PickleValue scalar(Kind kind) {
  PickleValue v;
  v.kind = kind;
  return v;
}

bool is_container(const PickleValue& v) {
  return v.kind == Kind::List || v.kind == Kind::Tuple || v.kind == Kind::Dict;
}

const void* container_ptr(const PickleValue& v) {
  return v.kind == Kind::Dict ? static_cast<const void*>(v.entries.get()) : static_cast<const void*>(v.items.get());
}

// Dict keys and list positions as they appear in flattened tensor names and JSON.
std::string key_text(const PickleValue& k) {
  switch (k.kind) {
    case Kind::String: return k.text;
    case Kind::Int: return std::to_string(k.integer);
    case Kind::Bool: return k.boolean ? "True" : "False";
    case Kind::None: return "None";
    case Kind::Float: return fmt::format("{}", k.real);
    case Kind::Bytes: return fmt::format("<{} bytes>", k.text.size());
    case Kind::Global: return "<" + k.text + ">";
    default: return fmt::format("<{}>", k.kind_name());
  }
}

class Unpickler {
 public:
  Unpickler(ByteReader& reader, const std::string& name, const PersistentLoad& load, const PickleOptions& options)
      : r_(reader), name_(name), load_(load), options_(options) {
    // Values shared through the memo may be repeated, but only in proportion to the input.
    budget_ = 16 * static_cast<uint64_t>(reader.remaining()) + (uint64_t{1} << 20);
  }

  Unpickler(const Unpickler&) = delete;
  Unpickler& operator=(const Unpickler&) = delete;

  // Shared containers can form cycles or deep chains that shared_ptr would leak or destroy
  // recursively; empty every container that is not part of the validated result one level
  // at a time instead (the registries keep each alive until then).
  ~Unpickler() {
    if (!ok_) kept_.clear();
    for (auto& list : lists_)
      if (!kept_.count(list.get())) Items().swap(*list);
    for (auto& dict : dicts_)
      if (!kept_.count(dict.get())) Entries().swap(*dict);
  }

  PickleValue run() {
    while (true) {
      at_ = r_.position();
      const uint8_t op = read<uint8_t>("opcode");
      switch (op) {
        case 0x80: {  // PROTO
          const uint8_t version = read<uint8_t>("protocol version");
          if (version > 5) fail("pickle protocol {} is newer than the supported 5", version);
          break;
        }
        case 0x95: read<uint64_t>("FRAME size"); break;  // frames only group opcodes for buffered reading
        case '.': {                                      // STOP
          PickleValue result = pop("STOP");
          check_result(result);
          return result;
        }
        case '(':  // MARK
          if (marks_.size() >= kMaxStack) fail("too many nested MARKs");
          marks_.push_back(stack_.size());
          break;
        case '0':  // POP: removes the top value, or the top mark when nothing is above it
          if (stack_.size() > base()) stack_.pop_back();
          else pop_mark("POP");
          break;
        case '1': pop_mark("POP_MARK"); break;
        case '2': push_copy(top("DUP")); break;
        case 'N': push(scalar(Kind::None)); break;
        case 0x88: case 0x89: {  // NEWTRUE, NEWFALSE
          PickleValue v = scalar(Kind::Bool);
          v.boolean = op == 0x88;
          push(std::move(v));
          break;
        }
        case 'K': push(make_int(read<uint8_t>("BININT1 value"))); break;
        case 'M': push(make_int(read<uint16_t>("BININT2 value"))); break;
        case 'J': push(make_int(read<int32_t>("BININT value"))); break;
        case 0x8a: push(read_long(read<uint8_t>("LONG1 length"))); break;
        case 0x8b: {  // LONG4
          const int32_t n = read<int32_t>("LONG4 length");
          if (n < 0) fail("LONG4 with a negative length");
          push(read_long(static_cast<uint32_t>(n)));
          break;
        }
        case 'G': {  // BINFLOAT, big-endian
          uint64_t bits = 0;
          for (int i = 0; i < 8; ++i) bits = (bits << 8) | read<uint8_t>("BINFLOAT value");
          PickleValue v = scalar(Kind::Float);
          std::memcpy(&v.real, &bits, sizeof bits);
          push(std::move(v));
          break;
        }
        case 0x8c: push(text(Kind::String, read<uint8_t>("SHORT_BINUNICODE length"))); break;
        case 'X': push(text(Kind::String, read<uint32_t>("BINUNICODE length"))); break;
        case 0x8d: push(text(Kind::String, read<uint64_t>("BINUNICODE8 length"))); break;
        // Python 2 str (legacy checkpoints): Python 3 loads it as text.
        case 'U': push(text(Kind::String, read<uint8_t>("SHORT_BINSTRING length"))); break;
        case 'T': {
          const int32_t n = read<int32_t>("BINSTRING length");
          if (n < 0) fail("BINSTRING with a negative length");
          push(text(Kind::String, static_cast<uint32_t>(n)));
          break;
        }
        case 'C': push(text(Kind::Bytes, read<uint8_t>("SHORT_BINBYTES length"))); break;
        case 'B': push(text(Kind::Bytes, read<uint32_t>("BINBYTES length"))); break;
        case 0x8e: push(text(Kind::Bytes, read<uint64_t>("BINBYTES8 length"))); break;
        case 0x96: push(text(Kind::Bytes, read<uint64_t>("BYTEARRAY8 length"))); break;
        case '}': push(make_dict("")); break;
        case ']': push(make_list(Kind::List)); break;
        case ')': push(make_list(Kind::Tuple)); break;
        case 0x8f: push(make_list(Kind::List)); break;  // EMPTY_SET: sets become lists
        case 'l': push(make_list(Kind::List, pop_mark("LIST"))); break;
        case 't': push(make_list(Kind::Tuple, pop_mark("TUPLE"))); break;
        case 0x91: push(make_list(Kind::List, pop_mark("FROZENSET"))); break;
        case 0x85: case 0x86: case 0x87: {  // TUPLE1, TUPLE2, TUPLE3
          const size_t n = op - 0x84;
          if (stack_.size() < base() + n) fail("stack underflow in TUPLE{}", n);
          Items items(std::make_move_iterator(stack_.end() - n), std::make_move_iterator(stack_.end()));
          stack_.resize(stack_.size() - n);
          push(make_list(Kind::Tuple, std::move(items)));
          break;
        }
        case 'd': {  // DICT
          Items items = pop_mark("DICT");
          PickleValue dict = make_dict("");
          set_items(dict, std::move(items), "DICT");
          push(std::move(dict));
          break;
        }
        case 'a': {  // APPEND
          PickleValue v = pop("APPEND");
          list_top("APPEND").items->push_back(std::move(v));
          break;
        }
        case 'e': case 0x90: {  // APPENDS, ADDITEMS (sets are lists)
          const char* what = op == 'e' ? "APPENDS" : "ADDITEMS";
          Items items = pop_mark(what);
          Items& list = *list_top(what).items;
          list.insert(list.end(), std::make_move_iterator(items.begin()), std::make_move_iterator(items.end()));
          break;
        }
        case 's': {  // SETITEM
          PickleValue value = pop("SETITEM");
          PickleValue key = pop("SETITEM");
          Items pair;
          pair.push_back(std::move(key));
          pair.push_back(std::move(value));
          set_items(top("SETITEM"), std::move(pair), "SETITEM");
          break;
        }
        case 'u': {  // SETITEMS
          Items items = pop_mark("SETITEMS");
          set_items(top("SETITEMS"), std::move(items), "SETITEMS");
          break;
        }
        case 'q': memo_put(read<uint8_t>("BINPUT index")); break;
        case 'r': memo_put(read<uint32_t>("LONG_BINPUT index")); break;
        case 0x94: memo_put(memo_.size()); break;  // MEMOIZE
        case 'h': memo_get(read<uint8_t>("BINGET index")); break;
        case 'j': memo_get(read<uint32_t>("LONG_BINGET index")); break;
        case 'c': {  // GLOBAL
          const std::string module = read_line("GLOBAL module");
          const std::string name = read_line("GLOBAL name");
          push(global(module + "." + name));
          break;
        }
        case 0x93: {  // STACK_GLOBAL
          PickleValue name = pop("STACK_GLOBAL"), module = pop("STACK_GLOBAL");
          if (name.kind != Kind::String || module.kind != Kind::String) fail("STACK_GLOBAL needs two strings");
          if (module.text.size() + name.text.size() > kMaxNameLength) fail("STACK_GLOBAL name too long");
          push(global(module.text + "." + name.text));
          break;
        }
        case 'Q': push(persistent(pop("BINPERSID"))); break;
        case 'R': {  // REDUCE
          PickleValue args = pop("REDUCE"), callable = pop("REDUCE");
          push(call(callable, args, "REDUCE"));
          break;
        }
        case 0x81: {  // NEWOBJ
          PickleValue args = pop("NEWOBJ"), cls = pop("NEWOBJ");
          push(call(cls, args, "NEWOBJ"));
          break;
        }
        case 0x92: {  // NEWOBJ_EX
          PickleValue kwargs = pop("NEWOBJ_EX"), args = pop("NEWOBJ_EX"), cls = pop("NEWOBJ_EX");
          if (kwargs.kind != Kind::Dict || !kwargs.entries->empty()) fail("NEWOBJ_EX with keyword arguments is not supported");
          push(call(cls, args, "NEWOBJ_EX"));
          break;
        }
        case 'b': build(pop("BUILD")); break;
        default:
          if (op >= 0x20 && op < 0x7f)
            fail("unsupported pickle opcode 0x{:02x} ('{}')", op, static_cast<char>(op));
          fail("unsupported pickle opcode 0x{:02x}", op);
      }
    }
  }

 private:
  template <typename... Args>
  [[noreturn]] void fail(fmt::format_string<Args...> f, Args&&... args) const {
    fail_file(r_.file(), "{} byte {}: {}", name_, at_, fmt::format(f, std::forward<Args>(args)...));
  }

  void need(uint64_t n, const char* what) const {
    if (n > r_.remaining()) fail("truncated: needs {} bytes for {}, only {} left", n, what, r_.remaining());
  }

  template <typename T>
  T read(const char* what) {
    need(sizeof(T), what);
    return r_.read<T>(what);
  }

  // Strings are bounded by the remaining input before anything is allocated.
  PickleValue text(Kind kind, uint64_t n) {
    need(n, kind == Kind::String ? "string" : "bytes");
    PickleValue v = scalar(kind);
    v.text = r_.read_string(static_cast<size_t>(n), "string");
    return v;
  }

  std::string read_line(const char* what) {
    std::string s;
    while (true) {
      const char c = static_cast<char>(read<uint8_t>(what));
      if (c == '\n') return s;
      if (s.size() >= kMaxNameLength) fail("{} too long", what);
      s.push_back(c);
    }
  }

  static PickleValue make_int(int64_t i) {
    PickleValue v = scalar(Kind::Int);
    v.integer = i;
    return v;
  }

  // Python ints: little-endian two's complement of n bytes. Those that fit 64 bits become Int.
  PickleValue read_long(uint32_t n) {
    need(n, "LONG value");
    const std::string bytes = r_.read_string(n, "LONG value");
    const auto byte = [&](size_t i) { return static_cast<uint8_t>(bytes[i]); };
    const bool negative = n > 0 && (byte(n - 1) & 0x80);
    bool fits = true;
    for (size_t i = 8; i < n; ++i) fits = fits && byte(i) == (negative ? 0xff : 0x00);
    if (n > 8 && fits) fits = ((byte(7) & 0x80) != 0) == negative;
    if (fits) {
      uint64_t u = negative ? ~uint64_t{0} : 0;
      for (size_t i = 0; i < std::min<size_t>(n, 8); ++i) {
        u &= ~(uint64_t{0xff} << (8 * i));
        u |= static_cast<uint64_t>(byte(i)) << (8 * i);
      }
      return make_int(static_cast<int64_t>(u));
    }
    PickleValue v = scalar(Kind::BigInt);
    v.text = bytes;
    for (size_t i = n; i-- > 0;) v.real = v.real * 256 + byte(i);
    if (negative) v.real -= std::ldexp(1.0, static_cast<int>(std::min<uint32_t>(n, 200) * 8));
    return v;
  }

  size_t base() const { return marks_.empty() ? 0 : marks_.back(); }

  void push(PickleValue v) {
    if (stack_.size() >= kMaxStack) fail("pickle stack deeper than {} values", kMaxStack);
    stack_.push_back(std::move(v));
  }

  // Memo gets and DUP copy a value's text: charged so a large string cannot be repeated freely.
  void push_copy(const PickleValue& v) {
    charge(v.text.size());
    push(v);
  }

  void charge(uint64_t n) {
    if (n > budget_) fail("the pickle repeats shared values far more than its size allows");
    budget_ -= n;
  }

  PickleValue pop(const char* op) {
    if (stack_.size() <= base()) fail("stack underflow in {}", op);
    PickleValue v = std::move(stack_.back());
    stack_.pop_back();
    return v;
  }

  PickleValue& top(const char* op) {
    if (stack_.size() <= base()) fail("stack underflow in {}", op);
    return stack_.back();
  }

  Items pop_mark(const char* op) {
    if (marks_.empty()) fail("{} without a MARK", op);
    const size_t m = marks_.back();
    marks_.pop_back();
    Items items(std::make_move_iterator(stack_.begin() + static_cast<std::ptrdiff_t>(m)),
                std::make_move_iterator(stack_.end()));
    stack_.resize(m);
    return items;
  }

  PickleValue& list_top(const char* op) {
    PickleValue& t = top(op);
    if (t.kind != Kind::List) fail("{} on a {}, not a list", op, t.kind_name());
    return t;
  }

  PickleValue make_list(Kind kind, Items items = {}) {
    PickleValue v = scalar(kind);
    v.items = std::make_shared<Items>(std::move(items));
    lists_.push_back(v.items);
    return v;
  }

  PickleValue make_dict(std::string cls) {
    PickleValue v = scalar(Kind::Dict);
    v.text = std::move(cls);
    v.entries = std::make_shared<Entries>();
    dicts_.push_back(v.entries);
    return v;
  }

  // Appends key/value pairs; repeated keys are resolved once the pickle is complete.
  void set_items(PickleValue& dict, Items items, const char* op) {
    if (dict.kind != Kind::Dict) fail("{} on a {}, not a dict", op, dict.kind_name());
    if (items.size() % 2) fail("{} with an odd number of values", op);
    for (size_t i = 0; i < items.size(); i += 2) {
      const Kind k = items[i].kind;
      if (k == Kind::List || k == Kind::Dict) fail("{} with an unhashable {} as a key", op, items[i].kind_name());
      dict.entries->emplace_back(std::move(items[i]), std::move(items[i + 1]));
    }
  }

  void memo_put(uint64_t index) {
    const PickleValue& v = top("memo store");
    auto it = memo_.find(index);
    if (it != memo_.end()) {
      it->second = v;
      return;
    }
    if (memo_.size() >= kMaxMemo) fail("more than {} memo entries", kMaxMemo);
    memo_.emplace(index, v);
  }

  void memo_get(uint64_t index) {
    auto it = memo_.find(index);
    if (it == memo_.end()) fail("memo index {} was never stored", index);
    push_copy(it->second);
  }

  PickleValue global(const std::string& name) {
    if (!allowed_callables().count(name) && !storage_dtypes().count(name)) {
      if (name.rfind("torch.", 0) == 0 && name.size() > 7 && name.compare(name.size() - 7, 7, "Storage") == 0)
        fail_file(r_.file(), "refusing to load: unsupported tensor storage type '{}'", name);
      if (!options_.opaque_objects)
        fail_file(r_.file(),
                  "refusing to load: the pickle references '{}', which is not a tensor, container or plain value", name);
    }
    PickleValue v = scalar(Kind::Global);
    v.text = name;
    return v;
  }

  PickleValue persistent(const PickleValue& pid) {
    if (!load_) fail("a persistent id (external storage reference) where none is expected");
    PickleValue s = load_(pid);
    if (s.kind != Kind::Storage || !s.tensor || !s.tensor->storage || s.tensor->shape.size() != 1 ||
        pth_dtype_size(s.tensor->dtype) == 0)
      fail("persistent id did not resolve to a storage");
    // Count each storage once towards the bytes tensors may materialise.
    if (storages_.insert(s.tensor->storage.get()).second)
      storage_bytes_ += static_cast<uint64_t>(s.tensor->shape[0]) * pth_dtype_size(s.tensor->dtype);
    return s;
  }

  std::vector<int64_t> dims(const PickleValue& v, const char* what) {
    if (v.kind != Kind::Tuple && v.kind != Kind::List) fail("tensor {} is a {}, not a tuple", what, v.kind_name());
    if (v.items->size() > kMaxDims) fail("tensor {} has more than {} dimensions", what, kMaxDims);
    std::vector<int64_t> out;
    for (const PickleValue& x : *v.items) {
      if (x.kind != Kind::Int || x.integer < 0 || static_cast<uint64_t>(x.integer) > kMaxDimSize)
        fail("tensor {} holds {}, not a plausible size", what, x.kind == Kind::Int ? std::to_string(x.integer) : x.kind_name());
      out.push_back(x.integer);
    }
    return out;
  }

  PickleValue rebuild_tensor(const Items& a) {
    if (a.size() < 4) fail("_rebuild_tensor_v2 with {} arguments, expected at least 4", a.size());
    const PickleValue& storage = a[0];
    if (storage.kind != Kind::Storage || !storage.tensor) fail("_rebuild_tensor_v2 on a {}, not a storage", storage.kind_name());
    if (a[1].kind != Kind::Int || a[1].integer < 0) fail("_rebuild_tensor_v2 with an invalid storage offset");
    const PthTensor& s = *storage.tensor;
    auto t = std::make_shared<PthTensor>();
    t->dtype = s.dtype;
    t->storage = s.storage;
    t->shape = dims(a[2], "size");
    t->stride = dims(a[3], "stride");
    if (t->shape.size() != t->stride.size())
      fail("tensor size [{}] and stride [{}] differ in length", fmt::join(t->shape, ", "), fmt::join(t->stride, ", "));
    // Every dimension is below 2^48, so each step stays far from overflow in 128 bits.
    const uint64_t elements = static_cast<uint64_t>(s.shape[0]);
    unsigned __int128 numel = 1, last = static_cast<uint64_t>(a[1].integer);
    for (size_t d = 0; d < t->shape.size(); ++d) {
      numel *= static_cast<uint64_t>(t->shape[d]);
      if (numel > kMaxDimSize) numel = kMaxDimSize + 1;  // saturate: already implausible
      if (t->shape[d] > 0) last += static_cast<unsigned __int128>(t->shape[d] - 1) * static_cast<uint64_t>(t->stride[d]);
    }
    if (numel > 0 && last >= elements)
      fail("a tensor of size [{}], stride [{}] at offset {} reaches element {} of a storage with {} elements",
           fmt::join(t->shape, ", "), fmt::join(t->stride, ", "), a[1].integer, static_cast<uint64_t>(last), elements);
    const uint64_t bytes = static_cast<uint64_t>(numel) * pth_dtype_size(t->dtype);
    if (numel > elements && bytes > kMaxExpandedBytes)
      fail("a tensor of size [{}] has more elements than its storage ({}): refusing to expand it", fmt::join(t->shape, ", "),
           elements);
    tensor_bytes_ += bytes;
    if (tensor_bytes_ > 4 * storage_bytes_ + (uint64_t{64} << 20))
      fail("the tensors view their storages far more often than a checkpoint would");
    t->storage_offset = s.storage_offset + a[1].integer;
    PickleValue v = scalar(Kind::Tensor);
    v.tensor = std::move(t);
    return v;
  }

  // _codecs.encode(text, 'latin1'): how protocol 2 stores bytes. The text arrives as UTF-8;
  // every code point must be below 256.
  PickleValue latin1(const Items& a) {
    if (a.size() != 2 || a[0].kind != Kind::String || a[1].kind != Kind::String ||
        (a[1].text != "latin1" && a[1].text != "latin-1"))
      fail("_codecs.encode is allowed only as encode(text, 'latin1')");
    const std::string& in = a[0].text;
    PickleValue out = scalar(Kind::Bytes);
    for (size_t i = 0; i < in.size(); ++i) {
      const uint8_t c = static_cast<uint8_t>(in[i]);
      if (c < 0x80) {
        out.text.push_back(static_cast<char>(c));
      } else if ((c == 0xc2 || c == 0xc3) && i + 1 < in.size() && (static_cast<uint8_t>(in[i + 1]) & 0xc0) == 0x80) {
        out.text.push_back(static_cast<char>(((c & 0x1f) << 6) | (static_cast<uint8_t>(in[++i]) & 0x3f)));
      } else {
        fail("_codecs.encode: text is not latin-1");
      }
    }
    return out;
  }

  PickleValue call(const PickleValue& callable, const PickleValue& args, const char* op) {
    if (callable.kind != Kind::Global) fail("{} on a {}, not a callable", op, callable.kind_name());
    if (args.kind != Kind::Tuple) fail("{} arguments are a {}, not a tuple", op, args.kind_name());
    const Items& a = *args.items;
    const auto it = allowed_callables().find(callable.text);
    if (it == allowed_callables().end()) {
      if (!options_.opaque_objects) fail("refusing to call '{}'", callable.text);
      // Never called: the instance becomes a dict of the attributes a BUILD gives it (a
      // TorchScript module's parameters and submodules), named by its class.
      return make_dict(callable.text);
    }
    switch (it->second) {
      case Builtin::OrderedDict:
      case Builtin::Namespace:
        if (!a.empty()) fail("{} with constructor arguments is not supported", callable.text);
        return make_dict(callable.text);
      case Builtin::Set:
        if (a.empty()) return make_list(Kind::List);
        if (a.size() != 1 || (a[0].kind != Kind::List && a[0].kind != Kind::Tuple)) fail("{} of something not a list", callable.text);
        return make_list(Kind::List, *a[0].items);
      case Builtin::Bytes:
        if (!a.empty()) fail("{} with arguments is not supported", callable.text);
        return scalar(Kind::Bytes);
      case Builtin::CodecsEncode: return latin1(a);
      case Builtin::TorchSize:
        if (a.size() != 1 || (a[0].kind != Kind::List && a[0].kind != Kind::Tuple)) fail("torch.Size of something not a tuple");
        return make_list(Kind::Tuple, *a[0].items);
      case Builtin::RebuildParameter:
        if (a.empty() || a[0].kind != Kind::Tensor) fail("{} on a {}, not a tensor", callable.text, a.empty() ? "nothing" : a[0].kind_name());
        return a[0];
      case Builtin::RebuildTensor: return rebuild_tensor(a);
    }
    fail("refusing to call '{}'", callable.text);
  }

  void build(PickleValue state) {
    PickleValue& target = top("BUILD");
    const bool opaque_instance = options_.opaque_objects && target.kind == Kind::Dict && !target.text.empty() &&
                                 !allowed_callables().count(target.text);
    if (opaque_instance && state.kind != Kind::Dict &&
        !(state.kind == Kind::Tuple && state.items->size() == 2))
      return;  // a state that is not attributes (a custom __setstate__'s): dropped
    if (opaque_instance || (target.kind == Kind::Dict && target.text == "argparse.Namespace")) {
      // The object's attribute dict (or a (dict, slots) pair) becomes the dict itself.
      std::vector<PickleValue*> parts;
      if (state.kind == Kind::Tuple && state.items->size() == 2) {
        for (PickleValue& p : *state.items) parts.push_back(&p);
      } else {
        parts.push_back(&state);
      }
      for (PickleValue* p : parts) {
        if (p->kind == Kind::None) continue;
        if (p->kind != Kind::Dict) {
          if (opaque_instance) continue;
          fail("argparse.Namespace state is a {}, not a dict", p->kind_name());
        }
        const Entries attributes = *p->entries;  // a copy: the state may be the object itself
        for (const auto& [k, v] : attributes) target.entries->emplace_back(k, v);
      }
      return;
    }
    // An OrderedDict's state is its instance attributes: for a state dict, `_metadata`
    // (module versions), which says nothing about the tensors.
    if (target.kind == Kind::Dict && target.text == "collections.OrderedDict") return;
    fail("BUILD on a {} is not supported", target.kind_name());
  }

  // The finished value must be a tree of bounded depth and bounded expanded size: it is walked
  // (and later flattened) recursively, so cycles, deep chains and "billion laughs" sharing are
  // refused here. Repeated dict keys keep their first position and last value, as in Python.
  void check_result(const PickleValue& result) {
    check(result, 0, 0);
    ok_ = true;
  }

  void check(const PickleValue& v, size_t depth, size_t path) {
    charge(1 + v.text.size() + path);
    if (!is_container(v)) return;
    const void* ptr = container_ptr(v);
    if (depth >= kMaxDepth) fail("containers nest more than {} levels deep", kMaxDepth);
    if (!on_path_.insert(ptr).second) fail("a container contains itself");
    if (kept_.insert(ptr).second && v.kind == Kind::Dict) dedupe(*v.entries);
    if (v.kind == Kind::Dict) {
      for (const auto& [k, x] : *v.entries) {
        check(k, depth + 1, path);
        check(x, depth + 1, path + k.text.size() + 8);
      }
    } else {
      for (const PickleValue& x : *v.items) check(x, depth + 1, path + 8);
    }
    on_path_.erase(ptr);
  }

  static void dedupe(Entries& entries) {
    std::unordered_map<std::string, size_t> first;
    std::vector<bool> drop(entries.size(), false);
    bool repeated = false;
    for (size_t i = 0; i < entries.size(); ++i) {
      const PickleValue& k = entries[i].first;
      std::string id;
      if (k.kind == Kind::String) id = "s" + k.text;
      else if (k.kind == Kind::Int) id = "i" + std::to_string(k.integer);
      else if (k.kind == Kind::Bool) id = k.boolean ? "i1" : "i0";  // True == 1 in Python
      else if (k.kind == Kind::Bytes) id = "b" + k.text;
      else continue;
      auto [it, inserted] = first.emplace(std::move(id), i);
      if (!inserted) {
        entries[it->second].second = std::move(entries[i].second);
        drop[i] = repeated = true;
      }
    }
    if (!repeated) return;
    Entries kept;
    for (size_t i = 0; i < entries.size(); ++i)
      if (!drop[i]) kept.push_back(std::move(entries[i]));
    entries.swap(kept);
  }

  ByteReader& r_;
  std::string name_;
  const PersistentLoad& load_;
  PickleOptions options_;
  size_t at_ = 0;
  uint64_t budget_ = 0;
  std::vector<PickleValue> stack_;
  std::vector<size_t> marks_;
  std::unordered_map<uint64_t, PickleValue> memo_;
  std::vector<std::shared_ptr<Items>> lists_;
  std::vector<std::shared_ptr<Entries>> dicts_;
  std::unordered_set<const void*> kept_, on_path_, storages_;
  uint64_t storage_bytes_ = 0, tensor_bytes_ = 0;
  bool ok_ = false;
};

template <typename T>
T load(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

std::optional<nlohmann::ordered_json> extra_json(const PickleValue& v, size_t depth) {
  using json = nlohmann::ordered_json;
  if (depth > kMaxDepth) fail("checkpoint values nest more than {} levels deep", kMaxDepth);
  switch (v.kind) {
    case Kind::None: return json(nullptr);
    case Kind::Bool: return json(v.boolean);
    case Kind::Int: return json(v.integer);
    case Kind::BigInt: case Kind::Float: return json(v.real);
    case Kind::String: return json(v.text);
    case Kind::Bytes: return json(fmt::format("<{} bytes>", v.text.size()));
    case Kind::Global: return json("<" + v.text + ">");
    case Kind::Tensor: case Kind::Storage: return std::nullopt;
    case Kind::List: case Kind::Tuple: {
      json a = json::array();
      for (const PickleValue& x : *v.items)
        if (auto j = extra_json(x, depth + 1)) a.push_back(std::move(*j));
      if (a.empty() && !v.items->empty()) return std::nullopt;  // held only tensors
      return a;
    }
    case Kind::Dict: {
      json o = json::object();
      for (const auto& [k, x] : *v.entries)
        if (auto j = extra_json(x, depth + 1)) o[key_text(k)] = std::move(*j);
      if (o.empty() && !v.entries->empty()) return std::nullopt;
      return o;
    }
  }
  return std::nullopt;
}

void collect(const PickleValue& v, const std::string& prefix, std::map<std::string, PthTensor>& out,
             const fs::path& file, size_t depth) {
  if (depth > kMaxDepth) {
    if (file.empty()) fail("checkpoint values nest more than {} levels deep", kMaxDepth);
    fail_file(file, "checkpoint values nest more than {} levels deep", kMaxDepth);
  }
  const auto child = [&](const std::string& key) { return prefix.empty() ? key : prefix + "." + key; };
  if (v.kind == Kind::Tensor) {
    if (!out.emplace(prefix, *v.tensor).second) {
      if (file.empty()) fail("two tensors have the same flattened name '{}'", prefix);
      fail_file(file, "two tensors have the same flattened name '{}'", prefix);
    }
  } else if (v.kind == Kind::Dict) {
    for (const auto& [k, x] : *v.entries) collect(x, child(key_text(k)), out, file, depth + 1);
  } else if (v.kind == Kind::List || v.kind == Kind::Tuple) {
    for (size_t i = 0; i < v.items->size(); ++i) collect((*v.items)[i], child(std::to_string(i)), out, file, depth + 1);
  }
}

}  // namespace

size_t pth_dtype_size(const std::string& dtype) {
  static const std::map<std::string, size_t> sizes = {{"F64", 8}, {"F32", 4}, {"F16", 2}, {"BF16", 2}, {"I64", 8},
                                                      {"I32", 4}, {"I16", 2}, {"I8", 1},  {"U8", 1},   {"BOOL", 1}};
  const auto it = sizes.find(dtype);
  return it == sizes.end() ? 0 : it->second;
}

std::string pth_storage_dtype(const std::string& storage_class) {
  const auto it = storage_dtypes().find(storage_class);
  return it == storage_dtypes().end() ? std::string() : it->second;
}

int64_t PthTensor::numel() const {
  int64_t n = 1;
  for (int64_t s : shape) n *= s;
  return n;
}

size_t PthTensor::item_size() const { return pth_dtype_size(dtype); }

std::vector<uint8_t> PthTensor::contiguous_bytes() const {
  const size_t item = item_size();
  // Checked again here: the struct is public and may not come from the unpickler.
  if (item == 0) fail("tensor of unknown dtype '{}'", dtype);
  if (!storage || shape.size() != stride.size() || storage_offset < 0) fail("tensor without a valid storage view");
  const int64_t n = numel();
  if (n == 0) return {};
  unsigned __int128 last = static_cast<uint64_t>(storage_offset);
  for (size_t d = 0; d < shape.size(); ++d) {
    if (shape[d] < 0 || stride[d] < 0) fail("tensor with a negative size or stride");
    last += static_cast<unsigned __int128>(shape[d] - 1) * static_cast<uint64_t>(stride[d]);
  }
  if ((last + 1) * item > storage->size()) fail("tensor view reaches past its storage ({} bytes)", storage->size());

  std::vector<uint8_t> out(static_cast<size_t>(n) * item);
  const uint8_t* src = storage->data();
  // Copy innermost runs whole when they are dense (the usual case: one run per row).
  const size_t ndim = shape.size();
  const bool dense_rows = ndim == 0 || stride[ndim - 1] == 1;
  const int64_t run = (ndim == 0 || !dense_rows) ? 1 : shape[ndim - 1];
  const size_t outer_dims = dense_rows && ndim > 0 ? ndim - 1 : ndim;
  std::vector<int64_t> idx(outer_dims, 0);
  for (size_t pos = 0; pos < out.size(); pos += static_cast<size_t>(run) * item) {
    int64_t at = storage_offset;
    for (size_t d = 0; d < outer_dims; ++d) at += idx[d] * stride[d];
    std::memcpy(out.data() + pos, src + static_cast<size_t>(at) * item, static_cast<size_t>(run) * item);
    for (size_t d = outer_dims; d-- > 0;) {
      if (++idx[d] < shape[d]) break;
      idx[d] = 0;
    }
  }
  return out;
}

std::vector<float> PthTensor::to_float() const {
  const std::vector<uint8_t> bytes = contiguous_bytes();
  const size_t item = item_size(), n = bytes.empty() ? 0 : bytes.size() / item;
  std::vector<float> out(n);
  const uint8_t* p = bytes.data();
  for (size_t i = 0; i < n; ++i, p += item) {
    if (dtype == "F32") out[i] = load<float>(p);
    else if (dtype == "F64") out[i] = static_cast<float>(load<double>(p));
    else if (dtype == "F16") out[i] = half_to_float(load<uint16_t>(p));
    else if (dtype == "BF16") {
      const uint32_t bits = static_cast<uint32_t>(load<uint16_t>(p)) << 16;
      std::memcpy(&out[i], &bits, sizeof bits);
    } else if (dtype == "I64") out[i] = static_cast<float>(load<int64_t>(p));
    else if (dtype == "I32") out[i] = static_cast<float>(load<int32_t>(p));
    else if (dtype == "I16") out[i] = static_cast<float>(load<int16_t>(p));
    else if (dtype == "I8") out[i] = static_cast<float>(load<int8_t>(p));
    else if (dtype == "U8") out[i] = static_cast<float>(*p);
    else out[i] = *p ? 1.0f : 0.0f;  // BOOL
  }
  return out;
}

const PickleValue* PickleValue::get(const std::string& key) const {
  if (kind != Kind::Dict || !entries) return nullptr;
  for (const auto& [k, v] : *entries)
    if (k.kind == Kind::String && k.text == key) return &v;
  return nullptr;
}

const char* PickleValue::kind_name() const {
  switch (kind) {
    case Kind::None: return "None";
    case Kind::Bool: return "bool";
    case Kind::Int: return "int";
    case Kind::BigInt: return "big int";
    case Kind::Float: return "float";
    case Kind::String: return "string";
    case Kind::Bytes: return "bytes";
    case Kind::List: return "list";
    case Kind::Tuple: return "tuple";
    case Kind::Dict: return "dict";
    case Kind::Tensor: return "tensor";
    case Kind::Global: return "global";
    case Kind::Storage: return "storage";
  }
  return "value";
}

PickleValue unpickle(ByteReader& reader, const std::string& name, const PersistentLoad& persistent_load,
                     const PickleOptions& options) {
  Unpickler u(reader, name, persistent_load, options);
  return u.run();
}

void collect_tensors(const PickleValue& value, const std::string& prefix, std::map<std::string, PthTensor>& out,
                     const fs::path& file) {
  collect(value, prefix, out, file, 0);
}

std::string extras_to_json(const PickleValue& value) {
  auto j = extra_json(value, 0);
  if (!j) j = nlohmann::ordered_json::object();
  // Pickled text need not be valid UTF-8: replace bad bytes rather than throw.
  return j->dump(-1, ' ', false, nlohmann::ordered_json::error_handler_t::replace);
}

}  // namespace ii
