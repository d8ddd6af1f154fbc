// The .pth reader: the official fixture loads bit-identically to its safetensors twin, and
// hostile or broken checkpoints are refused with a clear message, never executed.
#include <gtest/gtest.h>
#include <gmock/gmock.h>
#include <zip.h>

#include <cstring>
#include <fstream>

#include <nlohmann/json.hpp>

#include "io/byte_reader.h"
#include "io/pth.h"
#include "io/safetensors.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace pth_test {

namespace fs = std::filesystem;

// ---- fixture ---------------------------------------------------------------------------

TEST(Pth, OfficialFixtureMatchesSafetensors) {
  II_REQUIRE_SHARED(pth, "fixtures/official-tiny/checkpoint.pth");
  const auto tensors = read_pth_tensors(pth);
  const SafetensorsFile st = read_safetensors(test::shared_path("fixtures/official-tiny/weights.safetensors"));
  ASSERT_EQ(tensors.size(), st.tensors.size());
  for (const auto& [name, t] : st.tensors) {
    // Released checkpoints prefix state-dict keys with "module."; accept both forms.
    const size_t dot = name.find('.');
    auto it = tensors.find(name.substr(0, dot) + ".module" + name.substr(dot));
    if (it == tensors.end()) it = tensors.find(name);
    ASSERT_NE(it, tensors.end()) << name;
    EXPECT_EQ(it->second.dtype, t.dtype) << name;
    EXPECT_EQ(it->second.shape, t.shape) << name;
    EXPECT_EQ(it->second.contiguous_bytes(), t.bytes) << name;  // bit-identical
    EXPECT_EQ(it->second.to_float(), t.to_float()) << name;
  }
  EXPECT_EQ(tensors.at("gaudecoder.blocks.0.attn.qkv.weight_v").shape, (std::vector<int64_t>{384, 128}));

  const PickleValue tree = read_pth(pth);
  ASSERT_EQ(tree.kind, PickleValue::Kind::Dict);
  std::vector<std::string> top;
  for (const auto& [k, v] : *tree.entries) top.push_back(k.text);
  EXPECT_EQ(top, (std::vector<std::string>{"mvencoder", "extra_token_embed", "gaudecoder", "gauupsampler", "epoch"}));
  // extra_token_embed is an empty state dict; its `_metadata` attribute must not leak into it.
  EXPECT_TRUE(tree.get("extra_token_embed")->entries->empty());
  EXPECT_EQ(tree.get("mvencoder")->text, "collections.OrderedDict");
  EXPECT_EQ(nlohmann::json::parse(read_pth_extras_json(pth)), nlohmann::json::parse(R"({"extra_token_embed": {}, "epoch": 0})"));
}

// ---- builders for synthetic checkpoints ------------------------------------------------

// Pickle pieces (protocol 2, as torch.save writes). Built from parts, never from string
// literals holding NULs.
std::string u32(uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); }
std::string str(const std::string& s) { return "X" + u32(static_cast<uint32_t>(s.size())) + s; }
std::string num(int64_t v) {
  if (v >= 0 && v < 256) return "K" + std::string(1, static_cast<char>(v));
  return "J" + u32(static_cast<uint32_t>(v));
}
std::string global(const std::string& module, const std::string& name) { return "c" + module + "\n" + name + "\n"; }
std::string ints(const std::vector<int64_t>& v) {
  std::string s = "(";
  for (int64_t x : v) s += num(x);
  return s + "t";
}
const std::string kProto = "\x80\x02";
std::string put(uint32_t i) { return "r" + u32(i); }
std::string get(uint32_t i) { return "j" + u32(i); }

std::string storage_pid(const std::string& key, int64_t numel, const std::string& type = "FloatStorage",
                        bool legacy = false) {
  return "(" + str("storage") + global("torch", type) + str(key) + str("cpu") + num(numel) + (legacy ? "N" : "") + "tQ";
}
std::string tensor(const std::string& pid, int64_t offset, const std::vector<int64_t>& shape,
                   const std::vector<int64_t>& stride) {
  return global("torch._utils", "_rebuild_tensor_v2") + "(" + pid + num(offset) + ints(shape) + ints(stride) + "\x89" +
         global("collections", "OrderedDict") + ")RtR";
}
std::string floats(const std::vector<float>& v) { return std::string(reinterpret_cast<const char*>(v.data()), v.size() * 4); }

using Entries = std::vector<std::pair<std::string, std::string>>;

// A zip with archive/data.pkl = pickle, plus `extra` entries.
fs::path make_pth(const std::string& name, const std::string& pickle, const Entries& extra = {}) {
  static const fs::path dir = test::temp_dir("pth");
  const fs::path p = dir / name;
  int err = 0;
  zip_t* z = zip_open(p.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &err);
  EXPECT_NE(z, nullptr);
  Entries all = extra;
  all.insert(all.begin(), {"archive/data.pkl", pickle});
  for (const auto& [entry, bytes] : all) {
    zip_source_t* s = zip_source_buffer(z, bytes.data(), bytes.size(), 0);  // `all` outlives zip_close
    EXPECT_GE(zip_file_add(z, entry.c_str(), s, ZIP_FL_OVERWRITE), 0);
  }
  EXPECT_EQ(zip_close(z), 0);
  return p;
}

fs::path write_file(const std::string& name, const std::string& bytes) {
  static const fs::path dir = test::temp_dir("pth-raw");
  std::ofstream(dir / name, std::ios::binary) << bytes;
  return dir / name;
}

std::string err(const fs::path& p) { return test::error_message([&] { read_pth(p); }); }

// Errors inside the pickle name the file, the entry and the opcode's byte offset.
std::string at(const fs::path& p, size_t byte, const std::string& problem) {
  return p.string() + ": archive/data.pkl byte " + std::to_string(byte) + ": " + problem;
}

// ---- plain data --------------------------------------------------------------------------

// pickle.dumps({'args': argparse.Namespace(lr=1e-4, name='run', views=[4, 8], flag=True,
// none=None, seed=2**70, b=b'\x00\xff', s={1}, t=(1, 'a')), 'epoch': 3}, protocol=2)
const char kArgsPickle[] =
    "\200\002}q\000(X\004\000\000\000argsq\001cargparse\012Namespace\012q\002)\201q\003}q\004(X\002\000\000\000lrq\005"
    "G\077\0326\342\353\034C-X\004\000\000\000nameq\006X\003\000\000\000runq\007X\005\000\000\000viewsq\010]q\011(K\004K"
    "\010eX\004\000\000\000flagq\012\210X\004\000\000\000noneq\013NX\004\000\000\000seedq\014\212\011\000\000\000\000\000"
    "\000\000\000@X\001\000\000\000bq\015c_codecs\012encode\012q\016X\003\000\000\000\000\303\277q\017X\006\000\000\000la"
    "tin1q\020\206q\021Rq\022X\001\000\000\000sq\023c__builtin__\012set\012q\024]q\025K\001a\205q\026Rq\027X\001\000\000"
    "\000tq\030K\001X\001\000\000\000aq\031\206q\032ubX\005\000\000\000epochq\033K\003u.";

TEST(Pth, NamespaceArgumentsArePlainData) {
  const auto p = make_pth("args.pth", std::string(kArgsPickle, sizeof kArgsPickle - 1));
  const PickleValue v = read_pth(p);
  const PickleValue* args = v.get("args");
  ASSERT_NE(args, nullptr);
  EXPECT_EQ(args->kind, PickleValue::Kind::Dict);
  EXPECT_EQ(args->text, "argparse.Namespace");
  EXPECT_EQ(args->get("b")->text, std::string("\x00\xff", 2));
  EXPECT_EQ(args->get("seed")->kind, PickleValue::Kind::BigInt);
  EXPECT_EQ(args->get("lr")->real, 1e-4);
  const auto json = nlohmann::json::parse(read_pth_extras_json(p));
  EXPECT_EQ(json, nlohmann::json::parse(R"({"args": {"lr": 0.0001, "name": "run", "views": [4, 8], "flag": true,
      "none": null, "seed": 1.180591620717411303424e21, "b": "<2 bytes>", "s": [1], "t": [1, "a"]}, "epoch": 3})"));
  EXPECT_TRUE(read_pth_tensors(p).empty());
}

// pickle.dumps({'a': b'xy', 's': {1}, 'f': frozenset([2]), 'neg': -5, 'big': -2**63, 'x': 1.5}, protocol=4)
const char kProto4Pickle[] =
    "\200\004\225I\000\000\000\000\000\000\000}\224(\214\001a\224C\002xy\224\214\001s\224\217\224(K\001\220\214\001f\224"
    "(K\002\221\224\214\003neg\224J\373\377\377\377\214\003big\224\212\010\000\000\000\000\000\000\000\200\214\001x\224G"
    "\077\370\000\000\000\000\000\000u.";

TEST(Pth, Protocol4Opcodes) {
  const auto p = make_pth("p4.pth", std::string(kProto4Pickle, sizeof kProto4Pickle - 1));
  EXPECT_EQ(nlohmann::json::parse(read_pth_extras_json(p)),
            nlohmann::json::parse(R"({"a": "<2 bytes>", "s": [1], "f": [2], "neg": -5, "big": -9223372036854775808, "x": 1.5})"));
}

TEST(Pth, RepeatedKeysKeepTheLastValue) {
  const auto p = make_pth("dup.pth", kProto + "}(" + str("a") + num(1) + str("b") + num(2) + str("a") + num(3) + "u.");
  EXPECT_EQ(read_pth_extras_json(p), R"({"a":3,"b":2})");
}

// ---- tensors -----------------------------------------------------------------------------

TEST(Pth, TensorsAreRebuiltFromStorages) {
  // {'w': 2x3 tensor, 'wt': its transpose (a strided view), 'tail': elements 4.. of the same
  //  storage, 'tied': the same tensor as 'w' again, 'p': a Parameter, 'h': fp16,
  //  'opt': {'state': {0: {'step': 1-element tensor}}, 'lr': 0.5}}
  const std::vector<float> data = {0, 1, 2, 3, 4, 5};
  const std::string half = std::string("\x00\x3c\x00\xc0", 4);  // 1.0, -2.0
  const std::string pickle =
      kProto + "}(" + str("w") + tensor(storage_pid("0", 6), 0, {2, 3}, {3, 1}) + put(100) +   //
      str("wt") + tensor(storage_pid("0", 6), 0, {3, 2}, {1, 3}) +                            //
      str("tail") + tensor(storage_pid("0", 6), 4, {2}, {1}) +                                //
      str("tied") + get(100) +                                                                //
      str("p") + global("torch._utils", "_rebuild_parameter") + "(" + tensor(storage_pid("0", 6), 0, {6}, {1}) +
      "\x88" + global("collections", "OrderedDict") + ")RtR" +                                //
      str("h") + tensor(storage_pid("1", 2, "HalfStorage"), 0, {2}, {1}) +                    //
      str("opt") + "}(" + str("state") + "}" + num(0) + "}" + str("step") + tensor(storage_pid("0", 6), 5, {}, {}) +
      "ss" + str("lr") + "G\x3f\xe0" + std::string(6, '\0') + "uu.";
  const auto p = make_pth("t.pth", pickle, {{"archive/data/0", floats(data)}, {"archive/data/1", half}});
  const auto t = read_pth_tensors(p);
  std::vector<std::string> keys;
  for (const auto& [k, v] : t) keys.push_back(k);
  EXPECT_EQ(keys, (std::vector<std::string>{"h", "opt.state.0.step", "p", "tail", "tied", "w", "wt"}));
  EXPECT_EQ(t.at("w").to_float(), data);
  EXPECT_EQ(t.at("tied").to_float(), data);
  EXPECT_EQ(t.at("p").shape, (std::vector<int64_t>{6}));
  EXPECT_EQ(t.at("wt").to_float(), (std::vector<float>{0, 3, 1, 4, 2, 5}));
  EXPECT_EQ(t.at("tail").to_float(), (std::vector<float>{4, 5}));
  EXPECT_EQ(t.at("opt.state.0.step").to_float(), (std::vector<float>{5}));
  EXPECT_EQ(t.at("h").dtype, "F16");
  EXPECT_EQ(t.at("h").contiguous_bytes(), std::vector<uint8_t>(half.begin(), half.end()));
  EXPECT_EQ(t.at("h").to_float(), (std::vector<float>{1.0f, -2.0f}));
  EXPECT_EQ(t.at("w").storage, t.at("wt").storage);  // one storage, read once
  EXPECT_EQ(read_pth_extras_json(p), R"({"opt":{"lr":0.5}})");
}

TEST(Pth, TensorViewsAreCheckedAgainstTheirStorage) {
  const std::string data = floats({0, 1, 2, 3});
  auto one = [&](const std::string& name, const std::string& t, const Entries& entries) {
    return make_pth(name, kProto + "}" + str("w") + t + "s.", entries);
  };
  const Entries ok = {{"archive/data/0", data}};
  const auto too_big = one("big.pth", tensor(storage_pid("0", 4), 0, {3, 2}, {2, 1}), ok);
  EXPECT_NE(err(too_big).find(": a tensor of size [3, 2], stride [2, 1] at offset 0 reaches element 5 of a storage with 4 elements"),
            std::string::npos)
      << err(too_big);
  const auto offset = one("offset.pth", tensor(storage_pid("0", 4), 3, {2}, {1}), ok);
  EXPECT_NE(err(offset).find("reaches element 4 of a storage with 4 elements"), std::string::npos) << err(offset);
  const auto rank = one("rank.pth", tensor(storage_pid("0", 4), 0, {2, 2}, {1}), ok);
  EXPECT_NE(err(rank).find("tensor size [2, 2] and stride [1] differ in length"), std::string::npos) << err(rank);
  const auto expand = one("expand.pth", tensor(storage_pid("0", 4), 0, {1 << 20, 1 << 20}, {0, 0}), ok);
  EXPECT_NE(err(expand).find("a tensor of size [1048576, 1048576] has more elements than its storage (4): refusing to expand it"),
            std::string::npos)
      << err(expand);

  const auto missing = one("missing.pth", tensor(storage_pid("0", 4), 0, {4}, {1}), {});
  EXPECT_EQ(err(missing), missing.string() + ": storage 0 is missing from the archive (no entry archive/data/0)");
  const auto small = one("small.pth", tensor(storage_pid("0", 4), 0, {4}, {1}), {{"archive/data/0", data.substr(0, 8)}});
  EXPECT_EQ(err(small), small.string() + ": storage 0 holds 8 bytes, but 4 elements of F32 need 16");
  const auto lying = one("lying.pth", tensor(storage_pid("0", int64_t{1} << 30), 0, {4}, {1}), ok);
  EXPECT_EQ(err(lying), lying.string() + ": storage 0 holds 16 bytes, but 1073741824 elements of F32 need 4294967296");
  const auto odd = one("odd.pth", tensor(storage_pid("0", 4, "ComplexFloatStorage"), 0, {4}, {1}), ok);
  EXPECT_EQ(err(odd), odd.string() + ": refusing to load: unsupported tensor storage type 'torch.ComplexFloatStorage'");
}

TEST(Pth, BigEndianArchivesAreRefused) {
  const auto p = make_pth("be.pth", kProto + "}.", {{"archive/byteorder", "big"}});
  EXPECT_EQ(err(p), p.string() + ": stores big-endian data (byteorder 'big'); only little-endian checkpoints are supported");
  const auto le = make_pth("le.pth", kProto + "}.", {{"archive/byteorder", "little"}});
  EXPECT_NO_THROW(read_pth(le));
}

TEST(Pth, FlattenedNamesMustBeUnique) {
  const std::string pickle = kProto + "}(" + str("a.b") + tensor(storage_pid("0", 1), 0, {1}, {1}) + str("a") + "}" +
                             str("b") + tensor(storage_pid("0", 1), 0, {1}, {1}) + "su.";
  const auto p = make_pth("clash.pth", pickle, {{"archive/data/0", floats({1})}});
  EXPECT_EQ(test::error_message([&] { read_pth_tensors(p); }),
            p.string() + ": two tensors have the same flattened name 'a.b'");
}

// ---- hostile pickles ---------------------------------------------------------------------

TEST(Pth, DisallowedGlobalsAreRefused) {
  for (const auto& [module, name] : std::vector<std::pair<std::string, std::string>>{
           {"os", "system"}, {"builtins", "eval"}, {"subprocess", "Popen"}, {"__builtin__", "getattr"}, {"torch", "load"}}) {
    const auto p = make_pth(name + ".pth", kProto + global(module, name) + "(" + str("touch /tmp/pwned") + "tR.");
    EXPECT_EQ(err(p), p.string() + ": refusing to load: the pickle references '" + module + "." + name +
                          "', which is not a tensor, container or plain value");
  }
  // The same through STACK_GLOBAL (protocol 4).
  const auto stack = make_pth("stack.pth", "\x80\x04" + str("posix") + str("system") + "\x93" + "(" + str("id") + "tR.");
  EXPECT_EQ(err(stack), stack.string() +
                            ": refusing to load: the pickle references 'posix.system', which is not a tensor, container or plain value");
}

TEST(Pth, ReduceOnlyBuildsAllowedValues) {
  // An allowed global that is not a constructor: a storage class is only a type tag.
  const auto storage_call = make_pth("call.pth", kProto + global("torch", "FloatStorage") + ")R.");
  EXPECT_EQ(err(storage_call), at(storage_call, 23, "refusing to call 'torch.FloatStorage'"));
  // A string is not callable.
  const auto string_call = make_pth("string.pth", kProto + str("os.system") + ")R.");
  EXPECT_EQ(err(string_call), at(string_call, 17, "REDUCE on a string, not a callable"));
  // OrderedDict may only be built empty.
  const auto od = make_pth("od.pth", kProto + global("collections", "OrderedDict") + "(" + num(1) + "tR.");
  EXPECT_EQ(err(od), at(od, 31, "collections.OrderedDict with constructor arguments is not supported"));
  // BUILD would call __setstate__ on anything else.
  const auto build = make_pth("build.pth", kProto + "]}b.");
  EXPECT_EQ(err(build), at(build, 4, "BUILD on a list is not supported"));
  // Persistent ids must be storage references.
  const auto pid = make_pth("pid.pth", kProto + "(" + str("module") + str("evil") + str("src") + "tQ.");
  EXPECT_EQ(err(pid), pid.string() +
                          ": refusing to load: the checkpoint stores a whole nn.Module (Python source), not a state dict");
}

TEST(Pth, BrokenPicklesAreClearErrors) {
  const auto trunc = make_pth("trunc.pth", kProto + "}" + str("abc").substr(0, 3));
  EXPECT_EQ(err(trunc), at(trunc, 3, "truncated: needs 4 bytes for BINUNICODE length, only 2 left"));
  const auto no_stop = make_pth("nostop.pth", kProto + "}");
  EXPECT_EQ(err(no_stop), at(no_stop, 3, "truncated: needs 1 bytes for opcode, only 0 left"));
  const auto huge = make_pth("huge.pth", kProto + "\x8d" + u32(0) + u32(1 << 30) + ".");
  EXPECT_EQ(err(huge), at(huge, 2, "truncated: needs 4611686018427387904 bytes for string, only 1 left"));
  const auto opcode = make_pth("op.pth", kProto + "\xff.");
  EXPECT_EQ(err(opcode), at(opcode, 2, "unsupported pickle opcode 0xff"));
  const auto inst = make_pth("inst.pth", kProto + "(ios\nsystem\n.");
  EXPECT_EQ(err(inst), at(inst, 3, "unsupported pickle opcode 0x69 ('i')"));
  const auto underflow = make_pth("under.pth", kProto + "}" + num(1) + "s.");
  EXPECT_EQ(err(underflow), at(underflow, 5, "stack underflow in SETITEM"));
  // Values below a MARK are out of reach until the mark is closed.
  const auto mark_underflow = make_pth("mark.pth", kProto + num(1) + "(" + num(2) + "\x86.");
  EXPECT_EQ(err(mark_underflow), at(mark_underflow, 7, "stack underflow in TUPLE2"));
  const auto memo = make_pth("memo.pth", kProto + "h\x05.");
  EXPECT_EQ(err(memo), at(memo, 2, "memo index 5 was never stored"));
  const auto no_mark = make_pth("nomark.pth", kProto + "]" + num(1) + "e.");
  EXPECT_EQ(err(no_mark), at(no_mark, 5, "APPENDS without a MARK"));
  const auto not_dict = make_pth("notdict.pth", kProto + "]" + num(1) + num(2) + "s.");
  EXPECT_EQ(err(not_dict), at(not_dict, 7, "SETITEM on a list, not a dict"));
  const auto protocol = make_pth("proto.pth", "\x80\x07}.");
  EXPECT_EQ(err(protocol), at(protocol, 0, "pickle protocol 7 is newer than the supported 5"));
}

TEST(Pth, ResourceAttacksAreBounded) {
  // A list that contains itself: refused, and freed without leaking (ASan checks).
  const auto cycle = make_pth("cycle.pth", kProto + "]" + put(0) + get(0) + "a.");
  EXPECT_EQ(err(cycle), at(cycle, 14, "a container contains itself"));

  // A chain 30000 lists deep, built through the memo with a tiny stack: refused, and torn
  // down without deep recursion.
  std::string deep = kProto + "]" + put(0) + "0";
  for (uint32_t i = 1; i <= 30000; ++i) deep += "]" + get(i - 1) + "a" + put(i) + "0";
  deep += get(30000) + ".";
  const auto chain = make_pth("deep.pth", deep);
  EXPECT_EQ(err(chain), at(chain, deep.size() - 1, "containers nest more than 256 levels deep"));

  // "Billion laughs": each level holds the previous one twice, 2^60 leaves in ~1 KB.
  std::string laughs = kProto + "]" + put(0) + "0";
  for (uint32_t i = 1; i <= 60; ++i) laughs += "](" + get(i - 1) + get(i - 1) + "e" + put(i) + "0";
  laughs += get(60) + ".";
  const auto bomb = make_pth("laughs.pth", laughs);
  EXPECT_EQ(err(bomb), at(bomb, laughs.size() - 1, "the pickle repeats shared values far more than its size allows"));

  // One large string repeated through the memo.
  std::string repeat = kProto + "]" + str(std::string(1 << 18, 'x')) + put(0) + "0";
  for (int i = 0; i < 100; ++i) repeat += get(0) + "0";
  repeat += ".";
  const auto rep = make_pth("repeat.pth", repeat);
  EXPECT_NE(err(rep).find("the pickle repeats shared values far more than its size allows"), std::string::npos);
}

// ---- containers --------------------------------------------------------------------------

TEST(Pth, NotACheckpoint) {
  const auto text = write_file("x.pth", "plain text");
  EXPECT_EQ(err(text), text.string() +
                           ": not a PyTorch checkpoint: neither a zip archive (torch.save since 1.6) nor a legacy torch.save stream");
  const auto empty = write_file("empty.pth", "");
  EXPECT_EQ(err(empty), empty.string() +
                            ": not a PyTorch checkpoint: neither a zip archive (torch.save since 1.6) nor a legacy torch.save stream");
  const auto bad_zip = write_file("badzip.pth", "PK\x03\x04 but not really a zip");
  // libzip's own reason varies with its version (1.9: "Not a zip archive", 1.11: "Possibly
  // truncated or corrupted zip archive"); the part that is ours is exact.
  EXPECT_THAT(err(bad_zip), ::testing::StartsWith(bad_zip.string() + ": not a readable zip archive (libzip: "));
  EXPECT_EQ(err("/nonexistent/x.pth"), "/nonexistent/x.pth: file not found");

  static const fs::path dir = test::temp_dir("pth-nopkl");
  int e = 0;
  zip_t* z = zip_open((dir / "other.pth").c_str(), ZIP_CREATE | ZIP_TRUNCATE, &e);
  zip_file_add(z, "archive/other", zip_source_buffer(z, "x", 1, 0), 0);
  ASSERT_EQ(zip_close(z), 0);
  EXPECT_EQ(err(dir / "other.pth"), (dir / "other.pth").string() + ": zip archive has no <name>/data.pkl: not a PyTorch checkpoint");

  // A plain pickle file is not a torch.save stream either.
  const auto pickle = write_file("plain.pkl", kProto + "}.");
  EXPECT_EQ(err(pickle), pickle.string() + ": not a PyTorch checkpoint: a pickle without torch.save's magic number");
}

// The legacy stream: magic, protocol, system info, main pickle, storage keys, storages.
std::string legacy(const std::string& main, const std::vector<std::pair<std::string, std::string>>& storages,
                   int64_t declared_count = -1) {
  std::string s = kProto + "\x8a\x0a" + std::string("\x6c\xfc\x9c\x46\xf9\x20\x6a\xa8\x50\x19", 10) + ".";
  s += kProto + "M" + std::string("\xe9\x03", 2) + ".";
  s += kProto + "}(" + str("protocol_version") + "M" + std::string("\xe9\x03", 2) + str("little_endian") + "\x88" + "u.";
  s += main;
  s += kProto + "](";
  for (const auto& [key, data] : storages) s += str(key);
  s += "e.";
  for (const auto& [key, data] : storages) {
    const int64_t count = declared_count >= 0 ? declared_count : static_cast<int64_t>(data.size() / 4);
    s += std::string(reinterpret_cast<const char*>(&count), 8) + data;
  }
  return s;
}

TEST(Pth, LegacyFormat) {
  const std::string main = kProto + "}(" + str("w") + tensor(storage_pid("7", 3, "FloatStorage", true), 1, {2}, {1}) +
                           str("epoch") + num(4) + "u.";
  const auto p = write_file("legacy.pth", legacy(main, {{"7", floats({1, 2, 3})}}));
  const auto t = read_pth_tensors(p);
  ASSERT_EQ(t.size(), 1u);
  EXPECT_EQ(t.at("w").to_float(), (std::vector<float>{2, 3}));
  EXPECT_EQ(read_pth_extras_json(p), R"({"epoch":4})");

  const auto count = write_file("legacy-count.pth", legacy(main, {{"7", floats({1, 2, 3})}}, 5));
  EXPECT_NE(err(count).find(": storage 7 at byte "), std::string::npos);
  EXPECT_NE(err(count).find(" holds 5 elements, its tensors expect 3"), std::string::npos);
  std::string cut = legacy(main, {{"7", floats({1, 2, 3})}});
  cut.resize(cut.size() - 4);
  const auto truncated = write_file("legacy-cut.pth", cut);
  EXPECT_NE(err(truncated).find(": truncated file: storage 7 needs 12 bytes at byte "), std::string::npos) << err(truncated);
  const auto nodata = write_file("legacy-nodata.pth", legacy(main, {}));
  EXPECT_EQ(err(nodata), nodata.string() + ": storage 7 has no data in the file");
  const std::string view_main = kProto + "}(" + str("w") +
                                tensor("(" + str("storage") + global("torch", "FloatStorage") + str("7") + str("cpu") +
                                           num(3) + "(" + str("7") + num(0) + num(12) + "ttQ",
                                       0, {3}, {1}) +
                                "u.";
  const auto view = write_file("legacy-view.pth", legacy(view_main, {{"7", floats({1, 2, 3})}}));
  EXPECT_EQ(err(view), view.string() + ": storage 7 is a view of another storage (pre-1.0 checkpoints): not supported");
}

// The unpickler on its own: a persistent id without a loader is an error.
TEST(Pickle, PersistentIdNeedsALoader) {
  const std::string bytes = kProto + storage_pid("0", 1) + ".";
  ByteReader r(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), "mem");
  EXPECT_EQ(test::error_message([&] { unpickle(r, "pickle"); }),
            "mem: pickle byte " + std::to_string(bytes.size() - 2) +
                ": a persistent id (external storage reference) where none is expected");
}

}  // namespace pth_test
}  // namespace
}  // namespace ii
