// safetensors: real fixtures, round trips, dtype conversions and every kind of bad input
// with its exact message.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>

#include <nlohmann/json.hpp>

#include "common/files.h"
#include "io/safetensors.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace safetensors_test {

namespace fs = std::filesystem;
using test::file_bytes;
using test::write_bytes;

template <typename T>
std::vector<uint8_t> raw(const std::vector<T>& v) {
  const auto* p = reinterpret_cast<const uint8_t*>(v.data());
  return std::vector<uint8_t>(p, p + v.size() * sizeof(T));
}

std::string make_file(const std::string& header, const std::string& data) {
  std::string out(8, '\0');
  const uint64_t n = header.size();
  std::memcpy(out.data(), &n, 8);
  return out + header + data;
}

TEST(Safetensors, ReadsWeightsFixture) {
  II_REQUIRE_SHARED(p, "fixtures/official-tiny/weights.safetensors");
  const SafetensorsFile f = read_safetensors(p);
  EXPECT_EQ(f.tensors.size(), 39u);
  // __metadata__.config is itself JSON text.
  ASSERT_EQ(f.metadata.count("config"), 1u);
  EXPECT_TRUE(nlohmann::json::parse(f.metadata.at("config")).is_object());
  // File order is offset order.
  EXPECT_EQ(f.tensors.front().first, "gaudecoder.blocks.0.attn.proj.weight_g");
  EXPECT_EQ(f.tensors.back().first, "mvencoder.patch_embed.proj_plucker.weight");
  const TensorData& qkv = f.at("gaudecoder.blocks.0.attn.qkv.weight_v", p);
  EXPECT_EQ(qkv.dtype, "F32");
  EXPECT_EQ(qkv.shape, (std::vector<int64_t>{384, 128}));
  EXPECT_EQ(qkv.bytes.size(), 384u * 128 * 4);
  EXPECT_EQ(f.at("mvencoder.patch_embed.proj_plucker.weight", p).shape, (std::vector<int64_t>{128, 6, 8, 8}));
  EXPECT_EQ(f.find("nope"), nullptr);
  EXPECT_EQ(test::error_message([&] { f.at("nope", p); }), p.string() + ": no tensor nope");
  // Tensors are contiguous: together they fill the data section.
  size_t total = 0;
  for (const auto& kv : f.tensors) total += kv.second.bytes.size();
  EXPECT_EQ(total, 2275072u);
}

TEST(Safetensors, ReadsIoFixture) {
  II_REQUIRE_SHARED(p, "fixtures/official-tiny/io.safetensors");
  const SafetensorsFile f = read_safetensors(p);
  EXPECT_EQ(f.tensors.size(), 17u);
  EXPECT_TRUE(f.metadata.empty());
  EXPECT_EQ(f.tensors.front().first, "c2w");
  EXPECT_EQ(f.at("c2w", p).shape, (std::vector<int64_t>{1, 4, 4, 4}));
  EXPECT_EQ(f.at("cameras", p).shape, (std::vector<int64_t>{1, 4, 20}));
  EXPECT_EQ(f.at("encoder_input", p).shape, (std::vector<int64_t>{4, 4, 32, 48}));
  EXPECT_EQ(f.at("tokens_transformer", p).shape, (std::vector<int64_t>{1, 96, 128}));
  // Camera-to-world matrices end with the row 0 0 0 1.
  const std::vector<float> c2w = f.at("c2w", p).to_float();
  ASSERT_EQ(c2w.size(), 64u);
  EXPECT_EQ(c2w[0], 0.9987523555755615f);
  EXPECT_EQ(c2w[3], 0.1f);
  EXPECT_EQ(c2w[11], 2.f);
  EXPECT_EQ(c2w[16 + 0], 0.8f);
  for (int v = 0; v < 4; ++v) {
    EXPECT_EQ(c2w[v * 16 + 12], 0.f);
    EXPECT_EQ(c2w[v * 16 + 13], 0.f);
    EXPECT_EQ(c2w[v * 16 + 14], 0.f);
    EXPECT_EQ(c2w[v * 16 + 15], 1.f);
  }
}

TEST(Safetensors, ReadsLpipsAndRenderGolden) {
  II_REQUIRE_SHARED(alex, "data/lpips/alex.safetensors");
  const SafetensorsFile a = read_safetensors(alex);
  ASSERT_EQ(a.tensors.size(), 5u);
  const int64_t channels[5] = {64, 192, 384, 256, 256};
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(a.tensors[i].first, fmt::format("lin{}.model.1.weight", i));
    EXPECT_EQ(a.tensors[i].second.shape, (std::vector<int64_t>{1, channels[i], 1, 1}));
  }
  for (const char* key : {"source", "source_sha256", "licence", "content"}) EXPECT_EQ(a.metadata.count(key), 1u) << key;
  // LPIPS linear-layer weights are non-negative.
  for (float w : a.tensors[0].second.to_float()) EXPECT_GE(w, 0.f);

  II_REQUIRE_SHARED(golden, "data/render-golden/basic_case.safetensors");
  const SafetensorsFile g = read_safetensors(golden);
  ASSERT_EQ(g.tensors.size(), 6u);
  EXPECT_EQ(g.at("coeffs", golden).shape, (std::vector<int64_t>{16, 16, 3}));
  EXPECT_EQ(g.at("means", golden).shape, (std::vector<int64_t>{16, 3}));
  EXPECT_EQ(g.at("opacities", golden).shape, (std::vector<int64_t>{16}));
  EXPECT_EQ(g.at("out_img", golden).shape, (std::vector<int64_t>{82, 123, 4}));
  EXPECT_EQ(g.at("quats", golden).shape, (std::vector<int64_t>{16, 4}));
  EXPECT_EQ(g.at("scales", golden).shape, (std::vector<int64_t>{16, 3}));
}

TEST(Safetensors, RewritingARealFileKeepsEveryTensor) {
  II_REQUIRE_SHARED(p, "fixtures/official-tiny/weights.safetensors");
  const SafetensorsFile f = read_safetensors(p);
  const fs::path out = test::temp_dir("st") / "copy.safetensors";
  write_safetensors(out, f.tensors, f.metadata);
  const SafetensorsFile g = read_safetensors(out);
  EXPECT_EQ(g.metadata, f.metadata);
  ASSERT_EQ(g.tensors.size(), f.tensors.size());
  for (size_t i = 0; i < f.tensors.size(); ++i) {
    EXPECT_EQ(g.tensors[i].first, f.tensors[i].first);
    EXPECT_EQ(g.tensors[i].second.dtype, f.tensors[i].second.dtype);
    EXPECT_EQ(g.tensors[i].second.shape, f.tensors[i].second.shape);
    EXPECT_EQ(g.tensors[i].second.bytes, f.tensors[i].second.bytes);
  }
  // The data section is byte-identical (same order, no gaps).
  const std::string a = file_bytes(p), b = file_bytes(out);
  EXPECT_EQ(a.substr(a.size() - 2275072), b.substr(b.size() - 2275072));
}

TEST(Safetensors, RoundTripIsBitExactAndKeepsTheGivenOrder) {
  const fs::path p = test::temp_dir("st") / "t.safetensors";
  TensorData z{"F32", {2, 2}, raw(std::vector<float>{1.5f, -2.f, 3.25f, std::numeric_limits<float>::quiet_NaN()})};
  TensorData b{"BF16", {3}, {0x80, 0x3f, 0x00, 0x40, 0x40, 0xc0}};  // 1, 2, -3
  TensorData e{"I64", {0, 5}, {}};
  TensorData u{"U8", {3}, {0, 128, 255}};
  TensorData s{"F64", {}, raw(std::vector<double>{0.1})};  // scalar
  const std::vector<std::pair<std::string, TensorData>> tensors = {{"z", z}, {"b", b}, {"e", e}, {"u", u}, {"s", s}};
  write_safetensors(p, tensors, {{"k", "v"}, {"config", "{\"a\": 1}"}});
  const SafetensorsFile f = read_safetensors(p);
  EXPECT_EQ(f.metadata, (std::map<std::string, std::string>{{"k", "v"}, {"config", "{\"a\": 1}"}}));
  ASSERT_EQ(f.tensors.size(), 5u);
  for (size_t i = 0; i < tensors.size(); ++i) {
    EXPECT_EQ(f.tensors[i].first, tensors[i].first);  // not sorted by name: offset order = given order
    EXPECT_EQ(f.tensors[i].second.dtype, tensors[i].second.dtype);
    EXPECT_EQ(f.tensors[i].second.shape, tensors[i].second.shape);
    EXPECT_EQ(f.tensors[i].second.bytes, tensors[i].second.bytes);
  }
  EXPECT_EQ(f.at("e", p).numel(), 0);
  EXPECT_EQ(f.at("s", p).numel(), 1);
  EXPECT_EQ(f.at("b", p).to_float(), (std::vector<float>{1, 2, -3}));
  // Header: 8-byte length, JSON padded with spaces to a multiple of 8.
  const std::string bytes = file_bytes(p);
  uint64_t n;
  std::memcpy(&n, bytes.data(), 8);
  EXPECT_EQ(n % 8, 0u);
  const std::string header = bytes.substr(8, n);
  EXPECT_EQ(header.front(), '{');
  EXPECT_EQ(header.find_last_not_of(' '), header.rfind('}'));
  EXPECT_EQ(bytes.size(), 8 + n + 16 + 6 + 0 + 3 + 8);
  // Writing what was read gives the same file.
  const fs::path p2 = test::temp_dir("st") / "t2.safetensors";
  write_safetensors(p2, f.tensors, f.metadata);
  EXPECT_EQ(file_bytes(p2), bytes);
}

TEST(Safetensors, NoTensorsAndNoMetadata) {
  const fs::path p = test::temp_dir("st") / "empty.safetensors";
  write_safetensors(p, {});
  EXPECT_EQ(file_bytes(p), make_file("{}      ", ""));
  const SafetensorsFile f = read_safetensors(p);
  EXPECT_TRUE(f.tensors.empty());
  EXPECT_TRUE(f.metadata.empty());
}

TEST(Safetensors, ConvertsEveryDtypeToFloat) {
  auto conv = [](const std::string& dtype, std::vector<uint8_t> bytes, std::vector<int64_t> shape) {
    return TensorData{dtype, std::move(shape), std::move(bytes)}.to_float();
  };
  // F16: 1, -2, 65504 (max), 2^-24 (smallest subnormal), 2^-15 (subnormal), 2^-14 (smallest normal), inf.
  const std::vector<float> h = conv("F16", raw(std::vector<uint16_t>{0x3c00, 0xc000, 0x7bff, 0x0001, 0x0200, 0x0400, 0x7c00, 0x8000}), {8});
  EXPECT_EQ(h[0], 1.f);
  EXPECT_EQ(h[1], -2.f);
  EXPECT_EQ(h[2], 65504.f);
  EXPECT_EQ(h[3], std::ldexp(1.f, -24));
  EXPECT_EQ(h[4], std::ldexp(1.f, -15));
  EXPECT_EQ(h[5], std::ldexp(1.f, -14));
  EXPECT_TRUE(std::isinf(h[6]) && h[6] > 0);
  EXPECT_TRUE(h[7] == 0.f && std::signbit(h[7]));
  EXPECT_TRUE(std::isnan(conv("F16", raw(std::vector<uint16_t>{0x7e00}), {1})[0]));
  EXPECT_EQ(conv("BF16", raw(std::vector<uint16_t>{0x3f80, 0xc0a0, 0x4049}), {3}), (std::vector<float>{1.f, -5.f, 3.140625f}));
  EXPECT_EQ(conv("F64", raw(std::vector<double>{0.5, -1e10}), {2}), (std::vector<float>{0.5f, -1e10f}));
  EXPECT_EQ(conv("F32", raw(std::vector<float>{0.25f}), {1}), std::vector<float>{0.25f});
  EXPECT_EQ(conv("I64", raw(std::vector<int64_t>{-7, int64_t(1) << 40}), {2}), (std::vector<float>{-7.f, 1099511627776.f}));
  EXPECT_EQ(conv("I32", raw(std::vector<int32_t>{-3, 100000}), {2}), (std::vector<float>{-3.f, 100000.f}));
  EXPECT_EQ(conv("I16", raw(std::vector<int16_t>{-32768, 5}), {2}), (std::vector<float>{-32768.f, 5.f}));
  EXPECT_EQ(conv("I8", raw(std::vector<int8_t>{-128, 127}), {2}), (std::vector<float>{-128.f, 127.f}));
  EXPECT_EQ(conv("U8", {0, 200}, {2}), (std::vector<float>{0.f, 200.f}));
  EXPECT_EQ(conv("U16", raw(std::vector<uint16_t>{65535}), {1}), std::vector<float>{65535.f});
  EXPECT_EQ(conv("U32", raw(std::vector<uint32_t>{4000000000u}), {1}), std::vector<float>{4e9f});
  EXPECT_EQ(conv("U64", raw(std::vector<uint64_t>{uint64_t(1) << 63}), {1}), std::vector<float>{9223372036854775808.f});
  EXPECT_EQ(conv("BOOL", {0, 1, 7}, {3}), (std::vector<float>{0.f, 1.f, 1.f}));
  // A record whose bytes do not match its shape is an error, not an out-of-bounds read.
  EXPECT_EQ(test::error_message([&] { conv("F32", {1, 2, 3}, {1}); }), "tensor of shape [1] and dtype F32 holds 3 bytes");
  EXPECT_EQ(test::error_message([&] { conv("F8_E4M3", {1}, {1}); }), "cannot convert tensor of dtype F8_E4M3 to float");
}

class SafetensorsBad : public ::testing::Test {
 protected:
  fs::path dir = test::temp_dir("st-bad");
  std::string error(const std::string& name, const std::string& bytes) {
    write_bytes(dir / name, bytes);
    const std::string msg = test::error_message([&] { read_safetensors(dir / name); });
    const std::string prefix = (dir / name).string() + ": ";
    EXPECT_EQ(msg.rfind(prefix, 0), 0u) << msg;
    return msg.substr(std::min(msg.size(), prefix.size()));
  }
};

TEST_F(SafetensorsBad, MissingFileOrAFolder) {
  EXPECT_EQ(test::error_message([&] { read_safetensors(dir / "absent"); }), (dir / "absent").string() + ": file not found");
  EXPECT_EQ(test::error_message([&] { read_safetensors(dir); }), dir.string() + ": is a directory, expected a file");
}

TEST_F(SafetensorsBad, TruncatedOrLyingHeaderLength) {
  EXPECT_EQ(error("short", "abc"), "not a safetensors file: shorter than its 8-byte header length");
  EXPECT_EQ(error("empty", ""), "not a safetensors file: shorter than its 8-byte header length");
  EXPECT_EQ(error("lying", make_file("{}", "").substr(0, 8) + "{"), "not a safetensors file: header length 2 exceeds the file size 9");
  std::string huge = make_file("{}", "");
  huge[7] = '\x7f';
  EXPECT_EQ(error("huge", huge), "not a safetensors file: header length 9151314442816847874 exceeds the file size 10");
  // A real file cut short: its header promises more data than there is.
  II_REQUIRE_SHARED(p, "data/lpips/alex.safetensors");
  const std::string real = file_bytes(p);
  EXPECT_EQ(error("cut", real.substr(0, real.size() - 100)),
            "tensor 'lin4.model.1.weight' data_offsets [3584, 4608] lie outside the 4508-byte data section");
  EXPECT_EQ(error("cut-header", real.substr(0, 300)), "not a safetensors file: header length 712 exceeds the file size 300");
}

TEST_F(SafetensorsBad, HeaderIsNotJson) {
  EXPECT_EQ(error("json", make_file("{not json", "")),
            "header is not valid JSON ([json.exception.parse_error.101] parse error at line 1, column 3: syntax error "
            "while parsing object key - invalid literal; last read: '{no'; expected string literal)");
  EXPECT_EQ(error("array", make_file("[1, 2]", "")), "header is not a JSON object");
  EXPECT_EQ(error("meta", make_file(R"({"__metadata__": [1]})", "")), "__metadata__ is not an object");
  EXPECT_EQ(error("metaval", make_file(R"({"__metadata__": {"a": 1}})", "")), "__metadata__ value of 'a' is not a string");
}

TEST_F(SafetensorsBad, BadTensorEntries) {
  EXPECT_EQ(error("fields", make_file(R"({"t":{"dtype":"F32"}})", "")),
            "tensor 't' needs dtype, shape and data_offsets [begin, end]");
  EXPECT_EQ(error("notobj", make_file(R"({"t":5})", "")), "tensor 't' needs dtype, shape and data_offsets [begin, end]");
  EXPECT_EQ(error("offs3", make_file(R"({"t":{"dtype":"F32","shape":[1],"data_offsets":[0,4,8]}})", "1234")),
            "tensor 't' needs dtype, shape and data_offsets [begin, end]");
  EXPECT_EQ(error("dtype", make_file(R"({"t":{"dtype":"Q7","shape":[1],"data_offsets":[0,4]}})", "1234")),
            "tensor 't' has unknown dtype Q7");
  EXPECT_EQ(error("neg", make_file(R"({"t":{"dtype":"F32","shape":[-1],"data_offsets":[0,4]}})", "1234")),
            "tensor 't' has a negative or non-integer dimension");
  EXPECT_EQ(error("frac", make_file(R"({"t":{"dtype":"F32","shape":[1.5],"data_offsets":[0,4]}})", "1234")),
            "tensor 't' has a negative or non-integer dimension");
  EXPECT_EQ(error("bigdim", make_file(R"({"t":{"dtype":"F32","shape":[0, 18446744073709551615],"data_offsets":[0,0]}})", "")),
            "tensor 't' has an implausible dimension 18446744073709551615");
  EXPECT_EQ(error("negoff", make_file(R"({"t":{"dtype":"F32","shape":[1],"data_offsets":[-4,0]}})", "1234")),
            "tensor 't' has invalid data_offsets");
}

TEST_F(SafetensorsBad, ShapeAndOffsetsDisagree) {
  EXPECT_EQ(error("size", make_file(R"({"t":{"dtype":"F32","shape":[2],"data_offsets":[0,4]}})", "1234")),
            "tensor 't' of shape [2] and dtype F32 needs 8 bytes, data_offsets give 4");
  EXPECT_EQ(error("bf16", make_file(R"({"t":{"dtype":"BF16","shape":[2, 3],"data_offsets":[0,8]}})", "12345678")),
            "tensor 't' of shape [2, 3] and dtype BF16 needs 12 bytes, data_offsets give 8");
  // A shape whose product overflows 64 bits must not wrap around to match.
  EXPECT_EQ(error("wrap", make_file(R"({"t":{"dtype":"U8","shape":[4294967296, 4294967296],"data_offsets":[0,0]}})", "")),
            "tensor 't' of shape [4294967296, 4294967296] and dtype U8 needs more than 0 bytes, data_offsets give 0");
  EXPECT_EQ(error("range", make_file(R"({"t":{"dtype":"F32","shape":[1],"data_offsets":[0,4]}})", "12")),
            "tensor 't' data_offsets [0, 4] lie outside the 2-byte data section");
  EXPECT_EQ(error("reversed", make_file(R"({"t":{"dtype":"F32","shape":[0],"data_offsets":[4,0]}})", "1234")),
            "tensor 't' data_offsets [4, 0] lie outside the 4-byte data section");
  EXPECT_EQ(error("overlap",
                  make_file(R"({"a":{"dtype":"F32","shape":[1],"data_offsets":[0,4]},"b":{"dtype":"F32","shape":[1],"data_offsets":[2,6]}})",
                            "123456")),
            "tensors 'a' and 'b' overlap");
  EXPECT_EQ(error("same",
                  make_file(R"({"a":{"dtype":"F32","shape":[1],"data_offsets":[0,4]},"b":{"dtype":"I32","shape":[1],"data_offsets":[0,4]}})",
                            "1234")),
            "tensors 'a' and 'b' overlap");
}

TEST_F(SafetensorsBad, OversizedHeader) {
  // Over the 100 MB limit: refused before parsing (the file is sparse beyond its header).
  const fs::path p = dir / "big";
  {
    std::ofstream out(p, std::ios::binary);
    const uint64_t n = 100'000'008;
    out.write(reinterpret_cast<const char*>(&n), 8);
    out.seekp(static_cast<std::streamoff>(8 + n - 1));
    out.put(' ');
  }
  EXPECT_EQ(test::error_message([&] { read_safetensors(p); }), p.string() + ": header length 100000008 is above the 100 MB limit");
}

TEST(Safetensors, WriteRefusesBadTensors) {
  const fs::path p = test::temp_dir("st-w") / "w.safetensors";
  auto err = [&](const std::vector<std::pair<std::string, TensorData>>& t) {
    return test::error_message([&] { write_safetensors(p, t); });
  };
  EXPECT_EQ(err({{"a", TensorData{"F32", {2}, {1, 2, 3, 4}}}}), p.string() + ": tensor 'a': 4 bytes do not match shape [2] of F32");
  EXPECT_EQ(err({{"a", TensorData{"X", {1}, {1}}}}), p.string() + ": cannot write tensor 'a' of unknown dtype X");
  EXPECT_EQ(err({{"a", TensorData{"U8", {-1}, {}}}}), p.string() + ": tensor 'a' has a negative dimension in shape [-1]");
  EXPECT_EQ(err({{"a", TensorData{"U8", {1}, {1}}}, {"a", TensorData{"U8", {1}, {2}}}}), p.string() + ": tensor 'a' is given twice");
  EXPECT_EQ(err({{"__metadata__", TensorData{"U8", {1}, {1}}}}), p.string() + ": a tensor cannot be named __metadata__");
  EXPECT_FALSE(fs::exists(p));
}

}  // namespace safetensors_test
}  // namespace
}  // namespace ii
