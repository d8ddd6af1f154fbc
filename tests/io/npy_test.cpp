// .npy: real LLFF poses, round trips of every dtype, hand-made headers (versions, Fortran
// order, odd spellings) and every kind of bad input with its exact message.
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>

#include "common/files.h"
#include "io/npy.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace npy_test {

namespace fs = std::filesystem;
using test::file_bytes;
using test::raw;
using test::write_bytes;

// A .npy file with the given header dict text (padded with spaces and a newline).
std::string make_npy(const std::string& dict, const std::string& data, int major = 1) {
  std::string header = dict;
  header.append(16 - (header.size() + 1) % 16, ' ');
  header.push_back('\n');
  std::string out = "\x93NUMPY";
  out.push_back(static_cast<char>(major));
  out.push_back('\0');
  if (major == 1) {
    const uint16_t n = static_cast<uint16_t>(header.size());
    out.append(reinterpret_cast<const char*>(&n), 2);
  } else {
    const uint32_t n = static_cast<uint32_t>(header.size());
    out.append(reinterpret_cast<const char*>(&n), 4);
  }
  return out + header + data;
}

// Reads `bytes` written to a fresh file and returns the error message, prefixed check done
// by the caller.
class NpyBad : public ::testing::Test {
 protected:
  fs::path dir = test::temp_dir("npy-bad");
  std::string error(const std::string& name, const std::string& bytes) {
    write_bytes(dir / name, bytes);
    const std::string msg = test::error_message([&] { read_npy(dir / name); });
    const std::string prefix = (dir / name).string() + ": ";
    EXPECT_EQ(msg.rfind(prefix, 0), 0u) << msg;
    return msg.substr(std::min(msg.size(), prefix.size()));
  }
};

TEST(Npy, ReadsFernPosesBounds) {
  II_REQUIRE_SHARED(p, "data/fern/poses_bounds.npy");
  const NpyArray a = read_npy(p);
  EXPECT_EQ(a.dtype, "f8");
  ASSERT_EQ(a.shape, (std::vector<int64_t>{20, 17}));
  EXPECT_EQ(a.numel(), 340);
  const std::vector<double> v = a.as_double();
  ASSERT_EQ(v.size(), 340u);
  // Row 0: 3x5 [R|t|hwf] then near, far. hwf is for the full-resolution images (the
  // images_8 folder is 1/8: 378, 504, 407.57).
  EXPECT_EQ(v[4], 3024.0);
  EXPECT_EQ(v[9], 4032.0);
  EXPECT_EQ(v[14], 3260.5263328805895);
  EXPECT_EQ(v[0], 0.02242251555532968);
  EXPECT_EQ(v[3], -3.6791790683678407);
  EXPECT_EQ(v[15], 17.747087483458166);
  EXPECT_EQ(v[16], 78.25748707131142);
  // Last row: near, far.
  EXPECT_EQ(v[19 * 17 + 15], 17.542520113884287);
  EXPECT_EQ(v[19 * 17 + 16], 76.71614081178825);
  const std::vector<float> f = a.as_float();
  EXPECT_EQ(f[14], 3260.5263328805895f);
}

TEST(Npy, ReadsStatuePosesBounds) {
  II_REQUIRE_SHARED(p, "data/statue/poses_bounds.npy");
  const NpyArray a = read_npy(p);
  EXPECT_EQ(a.dtype, "f8");
  ASSERT_EQ(a.shape, (std::vector<int64_t>{29, 17}));
  const std::vector<double> v = a.as_double();
  EXPECT_EQ(v[4], 756.0);
  EXPECT_EQ(v[9], 1008.0);
  EXPECT_EQ(v[14], 740.3248120912315);
  EXPECT_EQ(v[15], 34.51957330309564);
  EXPECT_EQ(v[16], 376.3888204754601);
  EXPECT_EQ(v[28 * 17 + 3], -4.120480551720077);
}

TEST(Npy, RewritingARealFileIsBitIdentical) {
  II_REQUIRE_SHARED(p, "data/statue/poses_bounds.npy");
  // statue was written by a numpy that pads to 64 bytes, as we do.
  const fs::path out = test::temp_dir("npy") / "copy.npy";
  write_npy(out, read_npy(p));
  EXPECT_EQ(file_bytes(out), file_bytes(p));
}

TEST(Npy, WritesTheNumpyLayout) {
  const fs::path p = test::temp_dir("npy") / "a.npy";
  write_npy(p, {1, 2, 3, 4, 5, 6}, {2, 3});
  const std::string b = file_bytes(p);
  ASSERT_EQ(b.size(), 128u + 48u);  // header padded to 64-byte alignment
  EXPECT_EQ(b.substr(0, 8), std::string("\x93NUMPY\x01\x00", 8));
  EXPECT_EQ(static_cast<uint8_t>(b[8]) | (static_cast<uint8_t>(b[9]) << 8), 118);
  EXPECT_EQ(b.substr(10, 59), "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 3), }");
  EXPECT_EQ(b[127], '\n');
  EXPECT_EQ(b.find_first_not_of(' ', 69), 127u);
  EXPECT_EQ(b.substr(128), raw(std::vector<double>{1, 2, 3, 4, 5, 6}));
  // 1-D and scalar shapes use Python tuple syntax.
  write_npy(p, {7}, {1});
  EXPECT_NE(file_bytes(p).find("'shape': (1,), }"), std::string::npos);
  write_npy(p, {7}, {});
  EXPECT_NE(file_bytes(p).find("'shape': (), }"), std::string::npos);
  EXPECT_EQ(read_npy(p).as_double(), std::vector<double>{7});
}

TEST(Npy, EveryDtypeRoundTripsBitExactly) {
  const fs::path dir = test::temp_dir("npy-rt");
  struct Case {
    std::string dtype;
    std::string data;
    std::vector<double> values;
  };
  const std::vector<Case> cases = {
      {"f4", raw(std::vector<float>{1.5f, -2.25f, 1e-30f, 3e30f, 0.f, -0.f}), {1.5, -2.25, double(1e-30f), double(3e30f), 0, 0}},
      {"f8", raw(std::vector<double>{0.1, -1e300, 5, 6, 7, 8}), {0.1, -1e300, 5, 6, 7, 8}},
      {"i1", raw(std::vector<int8_t>{-128, 127, 0, 1, -1, 2}), {-128, 127, 0, 1, -1, 2}},
      {"i2", raw(std::vector<int16_t>{-32768, 32767, 0, 1, -1, 2}), {-32768, 32767, 0, 1, -1, 2}},
      {"i4", raw(std::vector<int32_t>{-2147483647 - 1, 2147483647, 0, 1, -1, 2}), {-2147483648.0, 2147483647, 0, 1, -1, 2}},
      {"i8", raw(std::vector<int64_t>{-(int64_t(1) << 40), int64_t(1) << 50, 0, 1, -1, 2}), {-1099511627776.0, 1125899906842624.0, 0, 1, -1, 2}},
      {"u1", raw(std::vector<uint8_t>{0, 255, 1, 2, 3, 4}), {0, 255, 1, 2, 3, 4}},
      {"u2", raw(std::vector<uint16_t>{0, 65535, 1, 2, 3, 4}), {0, 65535, 1, 2, 3, 4}},
      {"u4", raw(std::vector<uint32_t>{0, 4294967295u, 1, 2, 3, 4}), {0, 4294967295.0, 1, 2, 3, 4}},
      {"u8", raw(std::vector<uint64_t>{0, uint64_t(1) << 60, 1, 2, 3, 4}), {0, 1152921504606846976.0, 1, 2, 3, 4}},
      {"b1", std::string("\x00\x01\x01\x00\x01\x00", 6), {0, 1, 1, 0, 1, 0}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.dtype);
    NpyArray a;
    a.dtype = c.dtype;
    a.shape = {3, 2};
    a.data.assign(c.data.begin(), c.data.end());
    write_npy(dir / (c.dtype + ".npy"), a);
    const NpyArray back = read_npy(dir / (c.dtype + ".npy"));
    EXPECT_EQ(back.dtype, c.dtype);
    EXPECT_EQ(back.shape, a.shape);
    EXPECT_EQ(back.data, a.data);
    EXPECT_EQ(back.as_double(), c.values);
    // Written again: the same bytes.
    write_npy(dir / (c.dtype + "2.npy"), back);
    EXPECT_EQ(file_bytes(dir / (c.dtype + "2.npy")), file_bytes(dir / (c.dtype + ".npy")));
  }
  // One-byte types are written with '|' (no byte order), as numpy does.
  EXPECT_NE(file_bytes(dir / "u1.npy").find("'descr': '|u1'"), std::string::npos);
  EXPECT_NE(file_bytes(dir / "b1.npy").find("'descr': '|b1'"), std::string::npos);
  EXPECT_NE(file_bytes(dir / "i4.npy").find("'descr': '<i4'"), std::string::npos);
}

TEST(Npy, EmptyArraysRoundTrip) {
  const fs::path p = test::temp_dir("npy") / "empty.npy";
  write_npy(p, {}, {0, 17});
  const NpyArray a = read_npy(p);
  EXPECT_EQ(a.shape, (std::vector<int64_t>{0, 17}));
  EXPECT_TRUE(a.data.empty());
  EXPECT_TRUE(a.as_float().empty());
}

TEST(Npy, ReadsHandWrittenHeaders) {
  const fs::path dir = test::temp_dir("npy-hand");
  const std::string six = raw(std::vector<float>{1, 2, 3, 4, 5, 6});
  auto read = [&](const std::string& name, const std::string& bytes) {
    write_bytes(dir / name, bytes);
    return read_npy(dir / name);
  };
  // Version 2.0 and 3.0 (4-byte header length).
  for (int major : {2, 3}) {
    const NpyArray a = read(fmt::format("v{}.npy", major),
                            make_npy("{'descr': '<f4', 'fortran_order': False, 'shape': (6,), }", six, major));
    EXPECT_EQ(a.shape, std::vector<int64_t>{6});
    EXPECT_EQ(a.as_float(), (std::vector<float>{1, 2, 3, 4, 5, 6}));
  }
  // Keys in another order, double quotes, no trailing comma, Python 2 longs.
  const NpyArray b = read("odd.npy", make_npy("{\"shape\": (2L, 3L), \"fortran_order\": False, \"descr\": \"<f4\"}", six));
  EXPECT_EQ(b.shape, (std::vector<int64_t>{2, 3}));
  EXPECT_EQ(b.dtype, "f4");
  // '<u1' and '=u1' are the same as '|u1'.
  EXPECT_EQ(read("u1.npy", make_npy("{'descr': '<u1', 'fortran_order': False, 'shape': (2,), }", "\x05\x07")).as_double(),
            (std::vector<double>{5, 7}));
  EXPECT_EQ(read("b1.npy", make_npy("{'descr': '|b1', 'fortran_order': False, 'shape': (3,), }", std::string("\x00\x01\x02", 3)))
                .as_float(),
            (std::vector<float>{0, 1, 1}));
  // Scalar.
  const NpyArray s = read("scalar.npy", make_npy("{'descr': '<f8', 'fortran_order': False, 'shape': (), }", raw(std::vector<double>{2.5})));
  EXPECT_TRUE(s.shape.empty());
  EXPECT_EQ(s.as_double(), std::vector<double>{2.5});
}

TEST(Npy, FortranOrderIsReorderedToC) {
  const fs::path dir = test::temp_dir("npy-f");
  // 2x3 matrix [[1,2,3],[4,5,6]] stored column-major.
  write_bytes(dir / "f2.npy", make_npy("{'descr': '<f8', 'fortran_order': True, 'shape': (2, 3), }",
                                       raw(std::vector<double>{1, 4, 2, 5, 3, 6})));
  const NpyArray a = read_npy(dir / "f2.npy");
  EXPECT_EQ(a.shape, (std::vector<int64_t>{2, 3}));
  EXPECT_EQ(a.as_double(), (std::vector<double>{1, 2, 3, 4, 5, 6}));
  // 2x3x4 with value = 100 i + 10 j + k, stored with i fastest.
  std::vector<int32_t> fortran;
  for (int k = 0; k < 4; ++k)
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 2; ++i) fortran.push_back(100 * i + 10 * j + k);
  write_bytes(dir / "f3.npy", make_npy("{'descr': '<i4', 'fortran_order': True, 'shape': (2, 3, 4), }", raw(fortran)));
  const std::vector<double> v = read_npy(dir / "f3.npy").as_double();
  ASSERT_EQ(v.size(), 24u);
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 4; ++k) EXPECT_EQ(v[(i * 3 + j) * 4 + k], 100 * i + 10 * j + k);
  // 1-D Fortran order is the same as C order.
  write_bytes(dir / "f1.npy", make_npy("{'descr': '<f8', 'fortran_order': True, 'shape': (3,), }", raw(std::vector<double>{1, 2, 3})));
  EXPECT_EQ(read_npy(dir / "f1.npy").as_double(), (std::vector<double>{1, 2, 3}));
}

const std::string kGoodData = raw(std::vector<double>{1, 2, 3});
std::string with_descr(const std::string& descr) {
  return make_npy("{'descr': '" + descr + "', 'fortran_order': False, 'shape': (3,), }", kGoodData);
}

TEST_F(NpyBad, WrongMagicOrTooShort) {
  EXPECT_EQ(error("magic.npy", "NOTNUMPY\x01\x00\x10\x00{}"), "not a .npy file (missing \\x93NUMPY magic)");
  EXPECT_EQ(error("empty.npy", ""), "not a .npy file (missing \\x93NUMPY magic)");
  EXPECT_EQ(error("five.npy", "\x93NUMP"), "not a .npy file (missing \\x93NUMPY magic)");
  EXPECT_EQ(error("noversion.npy", "\x93NUMPY\x01"), "truncated file: needs 1 more bytes for version at byte 7, only 0 left");
  EXPECT_EQ(error("nolength.npy", std::string("\x93NUMPY\x01\x00\x10", 9)),
            "truncated file: needs 2 more bytes for header length at byte 8, only 1 left");
  EXPECT_EQ(error("nolength2.npy", std::string("\x93NUMPY\x02\x00\x10\x00", 10)),
            "truncated file: needs 4 more bytes for header length at byte 8, only 2 left");
}

TEST_F(NpyBad, UnsupportedVersion) {
  std::string b = with_descr("<f8");
  b[6] = 4;
  EXPECT_EQ(error("v4.npy", b), "unsupported .npy format version 4.0 (1.0, 2.0 and 3.0 are read)");
  b[6] = 1;
  b[7] = 1;
  EXPECT_EQ(error("v11.npy", b), "unsupported .npy format version 1.1 (1.0, 2.0 and 3.0 are read)");
}

TEST_F(NpyBad, LyingHeaderLength) {
  std::string b = with_descr("<f8");
  b[8] = '\xff';
  b[9] = '\x7f';  // 32767 bytes of header in a 98-byte file
  EXPECT_EQ(error("len.npy", b), "truncated file: needs 32767 more bytes for header at byte 10, only 88 left");
  std::string c = make_npy("{'descr': '<f8', 'fortran_order': False, 'shape': (3,), }", kGoodData, 2);
  c[11] = '\x40';  // 4-byte length: 1 GiB + 64
  EXPECT_EQ(error("len2.npy", c), "truncated file: needs 1073741888 more bytes for header at byte 12, only 88 left");
}

TEST_F(NpyBad, DataSizeMismatch) {
  const std::string good = with_descr("<f8");
  EXPECT_EQ(error("cut.npy", good.substr(0, good.size() - 5)),
            "data size mismatch: shape (3,) of <f8 needs 24 bytes, the file has 19");
  EXPECT_EQ(error("long.npy", good + "xx"), "data size mismatch: shape (3,) of <f8 needs 24 bytes, the file has 26");
  EXPECT_EQ(error("huge.npy", make_npy("{'descr': '<f8', 'fortran_order': False, 'shape': (1000000, 1000000), }", kGoodData)),
            "data size mismatch: shape (1000000, 1000000) of <f8 needs 8000000000000 bytes, the file has 24");
  // A product that overflows 64 bits must not wrap around to a plausible size.
  EXPECT_EQ(error("wrap.npy", make_npy("{'descr': '<f8', 'fortran_order': False, 'shape': (4611686018427387904, 4, 1), }", kGoodData)),
            "data size mismatch: shape (4611686018427387904, 4, 1) of <f8 needs more than 2^64 bytes, the file has 24");
  EXPECT_EQ(error("zero.npy", make_npy("{'descr': '<f8', 'fortran_order': False, 'shape': (0,), }", kGoodData)),
            "data size mismatch: shape (0,) of <f8 needs 0 bytes, the file has 24");
}

TEST_F(NpyBad, RefusedDtypes) {
  EXPECT_EQ(error("big.npy", with_descr(">f8")), "big-endian dtype '>f8' is not supported");
  EXPECT_EQ(error("big4.npy", with_descr(">i4")), "big-endian dtype '>i4' is not supported");
  EXPECT_EQ(error("obj.npy", with_descr("|O")), "unsupported dtype '|O' (object arrays and pickles are refused)");
  EXPECT_EQ(error("obj8.npy", with_descr("|O8")), "unsupported dtype '|O8' (object arrays and pickles are refused)");
  EXPECT_EQ(error("str.npy", with_descr("<U10")),
            "unsupported dtype '<U10' (numeric little-endian dtypes only: f4 f8 i1 i2 i4 i8 u1 u2 u4 u8 b1)");
  EXPECT_EQ(error("c16.npy", with_descr("<c16")),
            "unsupported dtype '<c16' (numeric little-endian dtypes only: f4 f8 i1 i2 i4 i8 u1 u2 u4 u8 b1)");
  EXPECT_EQ(error("noorder.npy", with_descr("f8")),
            "unsupported dtype 'f8' (numeric little-endian dtypes only: f4 f8 i1 i2 i4 i8 u1 u2 u4 u8 b1)");
  EXPECT_EQ(error("pipe.npy", with_descr("|f8")), "dtype '|f8' has no byte order");
  EXPECT_EQ(error("one.npy", with_descr("f")), "unsupported dtype 'f'");
  EXPECT_EQ(error("struct.npy", make_npy("{'descr': [('a', '<f8')], 'fortran_order': False, 'shape': (3,), }", kGoodData)),
            "structured dtypes are not supported (header \"{'descr': [('a', '<f8')], 'fortran_order': False, "
            "'shape': (3,), }\")");
}

TEST_F(NpyBad, MalformedHeaders) {
  EXPECT_EQ(error("nodescr.npy", make_npy("{'fortran_order': False, 'shape': (3,), }", kGoodData)),
            "header has no 'descr' entry");
  EXPECT_EQ(error("noorder.npy", make_npy("{'descr': '<f8', 'shape': (3,), }", kGoodData)),
            "header has no 'fortran_order' entry");
  EXPECT_EQ(error("noshape.npy", make_npy("{'descr': '<f8', 'fortran_order': False, }", kGoodData)),
            "header has no 'shape' entry");
  EXPECT_EQ(error("key.npy", make_npy("{'descr': '<f8', 'fortran_order': False, 'shape': (3,), 'x': 1}", kGoodData)),
            "malformed .npy header: unexpected key 'x' at character 56 of \"{'descr': '<f8', 'fortran_order': "
            "False, 'shape': (3,), 'x': 1}\"");
  EXPECT_EQ(error("neg.npy", make_npy("{'descr': '<f8', 'fortran_order': False, 'shape': (-3,), }", kGoodData)),
            "malformed .npy header: negative dimension at character 51 of \"{'descr': '<f8', 'fortran_order': "
            "False, 'shape': (-3,), }\"");
  EXPECT_EQ(error("bool.npy", make_npy("{'descr': '<f8', 'fortran_order': 0, 'shape': (3,), }", kGoodData)),
            "malformed .npy header: expected True or False at character 34 of \"{'descr': '<f8', "
            "'fortran_order': 0, 'shape': (3,), }\"");
  EXPECT_EQ(error("list.npy", make_npy("[1, 2]", kGoodData)),
            "malformed .npy header: expected '{' at character 0 of \"[1, 2]\"");
  EXPECT_EQ(error("open.npy", make_npy("{'descr': '<f8", kGoodData)),
            "malformed .npy header: unterminated string at character 10 of \"{'descr': '<f8\"");
  EXPECT_EQ(error("dim.npy", make_npy("{'descr': '<f8', 'fortran_order': False, 'shape': (99999999999999999999,), }", kGoodData)),
            "malformed .npy header: dimension too large at character 51 of \"{'descr': '<f8', 'fortran_order': "
            "False, 'shape': (99999999999999999999,), }\"");
  EXPECT_EQ(error("twice.npy", make_npy("{'descr': '<f8', 'descr': '<f4', 'fortran_order': False, 'shape': (3,)}", kGoodData)),
            "malformed .npy header: 'descr' appears twice at character 17 of \"{'descr': '<f8', 'descr': '<f4', "
            "'fortran_order': False, 'shape': (3,)}\"");
  EXPECT_EQ(error("after.npy", make_npy("{'descr': '<f8', 'fortran_order': False, 'shape': (3,)} x", kGoodData)),
            "malformed .npy header: text after the closing '}' at character 56 of \"{'descr': '<f8', "
            "'fortran_order': False, 'shape': (3,)} x\"");
}

TEST(Npy, WriteRefusesInconsistentArrays) {
  const fs::path p = test::temp_dir("npy-w") / "w.npy";
  EXPECT_EQ(test::error_message([&] { write_npy(p, std::vector<double>{1, 2, 3}, {2, 2}); }),
            p.string() + ": array data (24 bytes) does not match shape (2, 2) of f8");
  NpyArray a;
  a.dtype = "f16";
  EXPECT_EQ(test::error_message([&] { write_npy(p, a); }), p.string() + ": cannot write dtype 'f16'");
  a.dtype = "f4";
  a.shape = {-1, 2};
  EXPECT_EQ(test::error_message([&] { write_npy(p, a); }),
            p.string() + ": cannot write shape (-1, 2) with a negative dimension");
  EXPECT_FALSE(fs::exists(p));
  // Conversions refuse arrays whose data does not match the shape instead of reading past it.
  a.shape = {4};
  a.data.resize(8);
  EXPECT_EQ(test::error_message([&] { a.as_double(); }), "npy array: 8 data bytes do not match shape (4,) of f4");
  a.dtype = "x";
  EXPECT_EQ(test::error_message([&] { a.as_float(); }), "npy array: unknown dtype 'x'");
}

}  // namespace npy_test
}  // namespace
}  // namespace ii
