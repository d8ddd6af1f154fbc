// COLMAP sparse-model reader and writer: real files, exact round trips, and every kind of
// bad input with its message.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>

#include "common/files.h"
#include "io/colmap.h"
#include "io/npy.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace colmap_test {

namespace fs = std::filesystem;

TEST(Colmap, ReadsRealCameras) {
  II_REQUIRE_SHARED(fern, "data/fern/sparse/0/cameras.bin");
  const auto cams = read_colmap_cameras(fern);
  ASSERT_EQ(cams.size(), 1u);
  const ColmapCamera& c = cams.begin()->second;
  EXPECT_EQ(c.id, 1);
  EXPECT_EQ(c.model, "SIMPLE_RADIAL");
  EXPECT_EQ(c.width, 4032);
  EXPECT_EQ(c.height, 3024);
  ASSERT_EQ(c.params.size(), 4u);
  EXPECT_NEAR(c.params[0], 3260.53, 0.01);
  EXPECT_NEAR(c.params[1], 2016, 1e-9);
  EXPECT_NEAR(c.params[2], 1512, 1e-9);
  EXPECT_NEAR(c.params[3], 0.01975, 1e-5);
}

TEST(Colmap, StatueTextAndBinaryCamerasAgree) {
  II_REQUIRE_SHARED(txt, "data/statue/cameras.txt");
  II_REQUIRE_SHARED(bin, "data/statue/sparse/0/cameras.bin");
  const auto a = read_colmap_cameras(txt);
  const auto b = read_colmap_cameras(bin);
  ASSERT_EQ(a.size(), 1u);
  ASSERT_EQ(b.size(), 1u);
  const ColmapCamera& t = a.at(1);
  EXPECT_EQ(t.model, "PINHOLE");
  EXPECT_EQ(t.width, 1008);
  EXPECT_EQ(t.height, 756);
  EXPECT_EQ(t.params, (std::vector<double>{740.325, 742.618, 504, 378}));
  EXPECT_EQ(b.at(1).model, "PINHOLE");
  EXPECT_EQ(b.at(1).width, 1008);
  for (int k = 0; k < 4; ++k) EXPECT_NEAR(b.at(1).params[k], t.params[k], 1e-3);
}

TEST(Colmap, ReadsRealPoints) {
  II_REQUIRE_SHARED(dir, "data/fern/sparse/0");
  const ColmapModel m = read_colmap_model(dir);
  EXPECT_EQ(m.cameras.size(), 1u);
  EXPECT_TRUE(m.images.empty());  // images.bin is not in the shared sample
  ASSERT_EQ(m.points.size(), 10091u);
  size_t track_entries = 0;
  for (const auto& [id, p] : m.points) {
    EXPECT_EQ(p.id, id);
    EXPECT_GE(p.track.size(), 2u);  // COLMAP keeps only points seen at least twice
    for (const auto& [image, index] : p.track) {
      EXPECT_GE(image, 1);
      EXPECT_LE(image, 20);  // fern has 20 images
      EXPECT_GE(index, 0);
    }
    track_entries += p.track.size();
  }
  EXPECT_GT(track_entries, 2 * m.points.size());
}

// Every field exercised, with doubles whose decimal form is long (1/3) or extreme.
ColmapModel synthetic_model() {
  ColmapModel m;
  m.cameras[1] = {1, "OPENCV", 64, 48, {50, 51, 32.5, 24.25, 0.01, -0.002, 0.0003, 0.0004}};
  m.cameras[2] = {2, "SIMPLE_PINHOLE", 32, 24, {30, 16, 12}};
  m.cameras[7] = {7, "RAD_TAN_THIN_PRISM_FISHEYE", 10, 10, std::vector<double>(16, 1.0 / 7.0)};
  ColmapImage a;
  a.id = 3;
  a.qvec = {0.9, 0.1, -0.2, 0.3};
  a.tvec = {1.0 / 3.0, -2e-300, 123456789.123456789};
  a.camera_id = 1;
  a.name = "sub dir/a b.png";  // spaces survive the text format
  a.xys = {{1.5, 2.25}, {3, 4}, {std::nextafter(5.0, 6.0), -0.0}};
  a.point3d_ids = {7, -1, 8};
  ColmapImage b = a;
  b.id = 4;
  b.camera_id = 2;
  b.name = "b.png";
  b.xys.clear();  // an image without points: an empty line in images.txt
  b.point3d_ids.clear();
  m.images[3] = a;
  m.images[4] = b;
  ColmapPoint p;
  p.id = 7;
  p.xyz = {0.1, 0.2, 0.3};
  p.rgb = {1, 2, 255};
  p.error = 0.5;
  p.track = {{3, 0}, {4, 12}};
  m.points[7] = p;
  p.id = 8;
  p.xyz = {-1e10, 1.0 / 3.0, 0};
  p.rgb = {0, 128, 64};
  p.error = 1.0 / 9.0;
  p.track = {};
  m.points[8] = p;
  return m;
}

template <typename T>
bool same_bits(const T& a, const T& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), sizeof(a[0]) * a.size()) == 0;
}

void expect_same(const ColmapModel& a, const ColmapModel& b) {
  ASSERT_EQ(a.cameras.size(), b.cameras.size());
  for (const auto& [id, c] : a.cameras) {
    const ColmapCamera& o = b.cameras.at(id);
    EXPECT_EQ(o.id, c.id);
    EXPECT_EQ(o.model, c.model);
    EXPECT_EQ(o.width, c.width);
    EXPECT_EQ(o.height, c.height);
    EXPECT_TRUE(same_bits(o.params, c.params)) << "camera " << id;
  }
  ASSERT_EQ(a.images.size(), b.images.size());
  for (const auto& [id, im] : a.images) {
    const ColmapImage& o = b.images.at(id);
    EXPECT_EQ(o.id, im.id);
    EXPECT_EQ(o.name, im.name);
    EXPECT_EQ(o.camera_id, im.camera_id);
    EXPECT_TRUE(same_bits(o.qvec, im.qvec)) << "image " << id;
    EXPECT_TRUE(same_bits(o.tvec, im.tvec)) << "image " << id;
    ASSERT_EQ(o.xys.size(), im.xys.size());
    for (size_t k = 0; k < im.xys.size(); ++k) EXPECT_TRUE(same_bits(o.xys[k], im.xys[k])) << "image " << id;
    EXPECT_EQ(o.point3d_ids, im.point3d_ids);
  }
  ASSERT_EQ(a.points.size(), b.points.size());
  for (const auto& [id, p] : a.points) {
    const ColmapPoint& o = b.points.at(id);
    EXPECT_EQ(o.id, p.id);
    EXPECT_TRUE(same_bits(o.xyz, p.xyz)) << "point " << id;
    EXPECT_EQ(o.rgb, p.rgb);
    EXPECT_EQ(std::memcmp(&o.error, &p.error, sizeof(double)), 0);
    EXPECT_EQ(o.track, p.track);
  }
}

TEST(Colmap, BinaryAndTextRoundTripsAreBitExact) {
  const ColmapModel m = synthetic_model();
  const fs::path bin = test::temp_dir("colmap-bin"), txt = test::temp_dir("colmap-txt");
  write_colmap_model(bin, m, true);
  write_colmap_model(txt, m, false);
  for (const char* f : {"cameras.bin", "images.bin", "points3D.bin"}) EXPECT_TRUE(fs::exists(bin / f));
  for (const char* f : {"cameras.txt", "images.txt", "points3D.txt"}) EXPECT_TRUE(fs::exists(txt / f));
  expect_same(m, read_colmap_model(bin));
  expect_same(m, read_colmap_model(txt));
  // text -> model -> binary gives the same bytes as writing binary directly.
  const fs::path again = test::temp_dir("colmap-again");
  write_colmap_model(again, read_colmap_model(txt), true);
  for (const char* f : {"cameras.bin", "images.bin", "points3D.bin"})
    EXPECT_EQ(read_file_bytes(again / f), read_file_bytes(bin / f)) << f;
  // The writer creates missing folders.
  const fs::path nested = test::temp_dir("colmap-nested") / "sparse" / "0";
  write_colmap_model(nested, m, true);
  expect_same(m, read_colmap_model(nested));
}

TEST(Colmap, BinaryLayoutMatchesColmap) {
  // cameras.bin: u64 count, then per camera i32 id, i32 model id, u64 width, u64 height,
  // f64 params. Checked byte by byte so files interoperate with COLMAP itself.
  ColmapModel m;
  m.cameras[5] = {5, "PINHOLE", 640, 480, {500, 501, 320, 240}};
  const fs::path dir = test::temp_dir("colmap-layout");
  write_colmap_model(dir, m, true);
  const auto bytes = read_file_bytes(dir / "cameras.bin");
  ASSERT_EQ(bytes.size(), 8u + 4 + 4 + 8 + 8 + 4 * 8);
  auto at = [&](size_t offset, auto value) {
    decltype(value) v;
    std::memcpy(&v, bytes.data() + offset, sizeof(v));
    return v;
  };
  EXPECT_EQ(at(0, uint64_t{}), 1u);
  EXPECT_EQ(at(8, int32_t{}), 5);
  EXPECT_EQ(at(12, int32_t{}), 1);  // PINHOLE
  EXPECT_EQ(at(16, uint64_t{}), 640u);
  EXPECT_EQ(at(24, uint64_t{}), 480u);
  EXPECT_EQ(at(32, double{}), 500.0);
  EXPECT_EQ(at(56, double{}), 240.0);
  EXPECT_EQ(read_file_bytes(dir / "images.bin"), std::vector<uint8_t>(8, 0));  // empty lists: count 0
}

TEST(Colmap, ModelTable) {
  EXPECT_EQ(colmap_model_params("SIMPLE_PINHOLE"), 3);
  EXPECT_EQ(colmap_model_params("PINHOLE"), 4);
  EXPECT_EQ(colmap_model_params("SIMPLE_RADIAL"), 4);
  EXPECT_EQ(colmap_model_params("RADIAL"), 5);
  EXPECT_EQ(colmap_model_params("OPENCV"), 8);
  EXPECT_EQ(colmap_model_params("FULL_OPENCV"), 12);
  EXPECT_EQ(colmap_model_params("pinhole"), -1);
  EXPECT_EQ(colmap_model_id("OPENCV"), 4);
  EXPECT_EQ(colmap_model_id("THIN_PRISM_FISHEYE"), 10);
  EXPECT_EQ(colmap_model_id("NOPE"), -1);
}

TEST(Colmap, ReadsColmapStyleTextFiles) {
  // As COLMAP exports them: comment headers, an image with no points (empty second line),
  // Windows line ends in one file, tabs between numbers.
  const fs::path dir = test::temp_dir("colmap-handmade");
  std::ofstream(dir / "cameras.txt") << "# Camera list with one line of data per camera:\n"
                                        "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
                                        "# Number of cameras: 2\n"
                                        "1 SIMPLE_RADIAL 4032 3024 3260.53 2016 1512 0.01975\n"
                                        "2 PINHOLE 1008 756 740.325 742.618 504 378\n";
  std::ofstream(dir / "images.txt", std::ios::binary)
      << "# Image list with two lines of data per image:\r\n"
         "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\r\n"
         "#   POINTS2D[] as (X, Y, POINT3D_ID)\r\n"
         "1 1 0 0 0 0.5 -1 2 1 IMG_0001.JPG\r\n"
         "10.5 20.25 1\t30 40 -1\r\n"
         "2 0.7071067811865476 0 0.7071067811865476 0 0 0 0 2 IMG_0002.JPG\r\n"
         "\r\n";
  std::ofstream(dir / "points3D.txt") << "# 3D point list\n1 0.1 0.2 0.3 255 0 10 0.75 1 0 2 5\n";
  const ColmapModel m = read_colmap_model(dir);
  ASSERT_EQ(m.cameras.size(), 2u);
  EXPECT_EQ(m.cameras.at(1).params, (std::vector<double>{3260.53, 2016, 1512, 0.01975}));
  ASSERT_EQ(m.images.size(), 2u);
  const ColmapImage& a = m.images.at(1);
  EXPECT_EQ(a.name, "IMG_0001.JPG");
  EXPECT_EQ(a.tvec, Eigen::Vector3d(0.5, -1, 2));
  ASSERT_EQ(a.xys.size(), 2u);
  EXPECT_EQ(a.xys[1], Eigen::Vector2d(30, 40));
  EXPECT_EQ(a.point3d_ids, (std::vector<int64_t>{1, -1}));
  EXPECT_EQ(m.images.at(2).camera_id, 2);
  EXPECT_EQ(m.images.at(2).name, "IMG_0002.JPG");
  EXPECT_TRUE(m.images.at(2).xys.empty());
  ASSERT_EQ(m.points.size(), 1u);
  EXPECT_EQ(m.points.at(1).rgb, (std::array<uint8_t, 3>{255, 0, 10}));
  EXPECT_EQ(m.points.at(1).track, (std::vector<std::pair<int, int>>{{1, 0}, {2, 5}}));
}

TEST(Colmap, BinaryPreferredAndOptionalFiles) {
  const fs::path dir = test::temp_dir("colmap-prefer");
  ColmapModel bin_model = synthetic_model();
  write_colmap_model(dir, bin_model, true);
  ColmapModel txt_model = synthetic_model();
  txt_model.cameras.erase(7);
  write_colmap_model(dir, txt_model, false);
  EXPECT_EQ(read_colmap_model(dir).cameras.size(), 3u);  // from cameras.bin
  // Cameras alone: images and points stay empty for the caller to judge.
  const fs::path only = test::temp_dir("colmap-only-cameras");
  fs::copy_file(dir / "cameras.txt", only / "cameras.txt");
  const ColmapModel m = read_colmap_model(only);
  EXPECT_EQ(m.cameras.size(), 2u);
  EXPECT_TRUE(m.images.empty());
  EXPECT_TRUE(m.points.empty());
  const fs::path none = test::temp_dir("colmap-none");
  EXPECT_EQ(test::error_message([&] { read_colmap_model(none); }),
            none.string() + ": no COLMAP model here (cameras.bin or cameras.txt)");
}

// Fern's LLFF poses (poses_bounds.npy) written as COLMAP images: the COLMAP pose of an LLFF
// camera is the inverse of its camera-to-world in OpenCV axes.
TEST(Colmap, FernLlffPosesAsColmapModel) {
  II_REQUIRE_SHARED(poses_file, "data/fern/poses_bounds.npy");
  const std::vector<double> v = read_npy(poses_file).as_double();
  ASSERT_EQ(v.size(), 20u * 17);
  ColmapModel m;
  m.cameras = read_colmap_cameras(test::shared_path("data/fern/sparse/0/cameras.bin"));
  std::vector<Eigen::Vector3d> centres;
  for (int k = 0; k < 20; ++k) {
    auto e = [&](int r, int c) { return v[k * 17 + r * 5 + c]; };
    // LLFF columns: down, right, back. OpenCV camera axes: right, down, forward.
    Eigen::Matrix3d R_c2w;
    for (int r = 0; r < 3; ++r) R_c2w.row(r) << e(r, 1), e(r, 0), -e(r, 2);
    const Eigen::Vector3d c(e(0, 3), e(1, 3), e(2, 3));
    ColmapImage im;
    im.id = k + 1;
    im.camera_id = 1;
    im.name = fmt::format("image{:03d}.png", k);
    const Eigen::Quaterniond q(R_c2w.transpose());
    im.qvec = {q.w(), q.x(), q.y(), q.z()};
    im.tvec = -(R_c2w.transpose() * c);
    m.images[im.id] = im;
    centres.push_back(c);
  }
  for (bool binary : {true, false}) {
    const fs::path dir = test::temp_dir("colmap-fern");
    write_colmap_model(dir, m, binary);
    const ColmapModel back = read_colmap_model(dir);
    ASSERT_EQ(back.images.size(), 20u);
    for (const auto& [id, im] : back.images) {
      const Eigen::Matrix3d R = Eigen::Quaterniond(im.qvec[0], im.qvec[1], im.qvec[2], im.qvec[3]).toRotationMatrix();
      EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
      const Eigen::Vector3d centre = -R.transpose() * im.tvec;
      EXPECT_LT((centre - centres[id - 1]).norm(), 1e-9) << "image " << id;
    }
  }
}

// ---- bad input --------------------------------------------------------------------------

struct BadFiles {
  fs::path dir = test::temp_dir("colmap-bad");
  fs::path write(const std::string& name, const std::vector<uint8_t>& bytes) const {
    std::ofstream(dir / name, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), bytes.size());
    return dir / name;
  }
  fs::path write_text(const std::string& name, const std::string& text) const {
    std::ofstream(dir / name, std::ios::binary) << text;
    return dir / name;
  }
  template <typename T>
  static void poke(std::vector<uint8_t>& bytes, size_t offset, T value) {
    std::memcpy(bytes.data() + offset, &value, sizeof(T));
  }
};

std::vector<uint8_t> synthetic_file(const char* name) {
  const fs::path dir = test::temp_dir("colmap-src");
  write_colmap_model(dir, synthetic_model(), true);
  return read_file_bytes(dir / name);
}

TEST(ColmapBad, TruncatedCamerasBin) {
  const BadFiles b;
  const auto cams = synthetic_file("cameras.bin");  // 3 cameras
  // Cut inside the header's promise: the count itself cannot fit.
  const auto tiny = b.write("tiny.bin", std::vector<uint8_t>(cams.begin(), cams.begin() + 40));
  EXPECT_EQ(test::error_message([&] { read_colmap_cameras(tiny); }),
            tiny.string() + ": 3 cameras cannot fit in the 32 bytes left (truncated or corrupt file)");
  // Cut inside a camera record.
  const auto cut = b.write("cut.bin", std::vector<uint8_t>(cams.begin(), cams.end() - 4));
  EXPECT_EQ(test::error_message([&] { read_colmap_cameras(cut); }),
            cut.string() + ": truncated file: needs 8 more bytes for camera parameters at byte " +
                std::to_string(cams.size() - 8) + ", only 4 left");
  const auto empty = b.write("empty.bin", {});
  EXPECT_EQ(test::error_message([&] { read_colmap_cameras(empty); }),
            empty.string() + ": truncated file: needs 8 more bytes for cameras at byte 0, only 0 left");
}

TEST(ColmapBad, CountLargerThanFile) {
  const BadFiles b;
  auto cams = synthetic_file("cameras.bin");
  BadFiles::poke<uint64_t>(cams, 0, uint64_t{1} << 40);
  const auto lying = b.write("many.bin", cams);
  EXPECT_EQ(test::error_message([&] { read_colmap_cameras(lying); }),
            lying.string() + ": 1099511627776 cameras cannot fit in the " + std::to_string(cams.size() - 8) +
                " bytes left (truncated or corrupt file)");
}

TEST(ColmapBad, ImageAndPointCounts) {
  const BadFiles b;
  b.write("cameras.bin", synthetic_file("cameras.bin"));
  auto images = synthetic_file("images.bin");
  // The first image's 2D-point count sits right after its name.
  const size_t count_at = 8 + 4 + 32 + 24 + 4 + std::strlen("sub dir/a b.png") + 1;
  BadFiles::poke<uint64_t>(images, count_at, uint64_t{1} << 62);
  const auto ims = b.write("images.bin", images);
  const std::string left = std::to_string(images.size() - count_at - 8);
  EXPECT_EQ(test::error_message([&] { read_colmap_model(b.dir); }),
            ims.string() + ": 4611686018427387904 2D points cannot fit in the " + left +
                " bytes left (truncated or corrupt file)");
  // An unterminated name.
  std::vector<uint8_t> unterminated(images.begin(), images.begin() + count_at - 3);
  BadFiles::poke<uint64_t>(unterminated, 0, 1);  // one image, so the count itself fits
  b.write("images.bin", unterminated);
  EXPECT_EQ(test::error_message([&] { read_colmap_model(b.dir); }),
            ims.string() + ": truncated file: unterminated image name at byte " + std::to_string(8 + 4 + 32 + 24 + 4));
  b.write("images.bin", synthetic_file("images.bin"));
  auto points = synthetic_file("points3D.bin");
  BadFiles::poke<uint64_t>(points, 8 + 8 + 24 + 3 + 8, uint64_t{1} << 61);  // first track length
  const auto pts = b.write("points3D.bin", points);
  EXPECT_EQ(test::error_message([&] { read_colmap_model(b.dir); }).rfind(
                pts.string() + ": 2305843009213693952 track entries cannot fit", 0),
            0u);
}

TEST(ColmapBad, TrailingBytesAndDuplicates) {
  const BadFiles b;
  auto cams = synthetic_file("cameras.bin");
  cams.push_back(0);
  const auto extra = b.write("extra.bin", cams);
  EXPECT_EQ(test::error_message([&] { read_colmap_cameras(extra); }),
            extra.string() + ": 1 bytes left over after 3 cameras (corrupt file or wrong count)");
  const auto dup = b.write_text("dup.txt", "1 PINHOLE 10 10 5 5 5 5\n1 PINHOLE 10 10 5 5 5 5\n");
  EXPECT_EQ(test::error_message([&] { read_colmap_cameras(dup); }), dup.string() + ": duplicate camera id 1");
}

TEST(ColmapBad, UnknownModelAndSize) {
  const BadFiles b;
  auto cams = synthetic_file("cameras.bin");
  BadFiles::poke<int32_t>(cams, 12, 99);  // first camera's model id
  const auto unknown = b.write("model.bin", cams);
  EXPECT_EQ(test::error_message([&] { read_colmap_cameras(unknown); }), unknown.string() + ": camera 1 has unknown model id 99");
  cams = synthetic_file("cameras.bin");
  BadFiles::poke<uint64_t>(cams, 16, 0);  // width 0
  const auto zero = b.write("zero.bin", cams);
  EXPECT_EQ(test::error_message([&] { read_colmap_cameras(zero); }), zero.string() + ": camera 1 has implausible size 0x48");
  const auto name = b.write_text("name.txt", "3 FISHEYE_X 10 10 1 2 3\n");
  EXPECT_EQ(test::error_message([&] { read_colmap_cameras(name); }),
            name.string() + ": line 1: camera 3 has unknown model FISHEYE_X");
}

TEST(ColmapBad, NaNPose) {
  const fs::path dir = test::temp_dir("colmap-nan");
  write_colmap_model(dir, synthetic_model(), true);
  auto images = read_file_bytes(dir / "images.bin");
  BadFiles::poke<double>(images, 8 + 4, std::nan(""));  // first image's qw
  std::ofstream(dir / "images.bin", std::ios::binary).write(reinterpret_cast<const char*>(images.data()), images.size());
  EXPECT_EQ(test::error_message([&] { read_colmap_model(dir); }),
            (dir / "images.bin").string() + ": the rotation of entry 3 is NaN or infinite");
  const fs::path tdir = test::temp_dir("colmap-nan-txt");
  std::ofstream(tdir / "cameras.txt") << "1 PINHOLE 10 10 5 5 5 5\n";
  std::ofstream(tdir / "images.txt") << "1 1 0 0 0 0 inf 0 1 a.png\n\n";
  EXPECT_EQ(test::error_message([&] { read_colmap_model(tdir); }),
            (tdir / "images.txt").string() + ": the translation of entry 1 is NaN or infinite");
}

TEST(ColmapBad, MalformedText) {
  const BadFiles b;
  const auto few = b.write_text("few.txt", "# header\n1 PINHOLE 10 10 5 5 5\n");
  EXPECT_EQ(test::error_message([&] { read_colmap_cameras(few); }),
            few.string() + ": line 2: camera 1 (PINHOLE) has 3 parameters, expected 4");
  const auto word = b.write_text("word.txt", "1 PINHOLE 10 10 5 5 5 five\n");
  EXPECT_EQ(test::error_message([&] { read_colmap_cameras(word); }),
            word.string() + ": line 1: 'five' is not a valid camera parameter");
  const auto half = b.write_text("half.txt", "1 PINHOLE 10\n");
  EXPECT_EQ(test::error_message([&] { read_colmap_cameras(half); }), half.string() + ": line 1: missing height");
  const auto neg = b.write_text("neg.txt", "1 PINHOLE -10 10 5 5 5 5\n");
  EXPECT_EQ(test::error_message([&] { read_colmap_cameras(neg); }), neg.string() + ": camera 1 has implausible size -10x10");

  const fs::path dir = test::temp_dir("colmap-bad-text");
  std::ofstream(dir / "cameras.txt") << "1 PINHOLE 10 10 5 5 5 5\n";
  std::ofstream(dir / "images.txt") << "1 1 0 0 0 0 0 0 1\n";
  EXPECT_EQ(test::error_message([&] { read_colmap_model(dir); }), (dir / "images.txt").string() + ": line 1: missing image name");
  std::ofstream(dir / "images.txt") << "1 1 0 0 0 0 0 0 1 a.png\n1.0 2.0\n";
  EXPECT_EQ(test::error_message([&] { read_colmap_model(dir); }), (dir / "images.txt").string() + ": line 2: missing point3D id");
  std::ofstream(dir / "images.txt") << "1 1 0 0 0 0 0 0 1 a.png\n# comment\n";
  EXPECT_EQ(test::error_message([&] { read_colmap_model(dir); }),
            (dir / "images.txt").string() + ": line 2: expected the 2D points of image 1, found a comment");
  std::ofstream(dir / "images.txt") << "1 1 0 0 0 0 0 0 1 a.png\n\n";
  std::ofstream(dir / "points3D.txt") << "1 0 0 0 256 0 0 0.5\n";
  EXPECT_EQ(test::error_message([&] { read_colmap_model(dir); }),
            (dir / "points3D.txt").string() + ": line 1: colour 256 is outside 0..255");
  std::ofstream(dir / "points3D.txt") << "1 0 0 0 1 2 3 0.5 1\n";
  EXPECT_EQ(test::error_message([&] { read_colmap_model(dir); }),
            (dir / "points3D.txt").string() + ": line 1: missing track point index");
}

TEST(ColmapBad, WriterRefusesWhatWouldNotReadBack) {
  const fs::path dir = test::temp_dir("colmap-write-bad");
  ColmapModel m = synthetic_model();
  m.images[3].point3d_ids.pop_back();
  EXPECT_EQ(test::error_message([&] { write_colmap_model(dir, m, true); }),
            dir.string() + ": image 3: 3 2D points but 2 point3D ids");
  m = synthetic_model();
  m.cameras[1].params.pop_back();
  EXPECT_EQ(test::error_message([&] { write_colmap_model(dir, m, true); }),
            dir.string() + ": camera 1: model OPENCV needs 8 parameters, got 7");
  m = synthetic_model();
  m.images[4].name = "two\nlines.png";
  EXPECT_EQ(test::error_message([&] { write_colmap_model(dir, m, false); }),
            dir.string() + ": image 4: name 'two\nlines.png' cannot be stored in a COLMAP file");
  m = synthetic_model();
  m.images[4].tvec.x() = NAN;
  EXPECT_EQ(test::error_message([&] { write_colmap_model(dir, m, false); }), dir.string() + ": image 4: pose is NaN or infinite");
  EXPECT_FALSE(fs::exists(dir / "cameras.txt"));  // nothing written on refusal
  EXPECT_FALSE(fs::exists(dir / "cameras.bin"));
}

}  // namespace colmap_test
}  // namespace
}  // namespace ii
