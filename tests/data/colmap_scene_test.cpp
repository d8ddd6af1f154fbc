// COLMAP scene reader (poses, intrinsics, layouts, errors) and the undistortion used when
// views with lens distortion are loaded.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>

#include "common/files.h"
#include "data/colmap_run.h"
#include "data/scene.h"
#include "data/scene_readers.h"
#include "data/undistort.h"
#include "io/colmap.h"
#include "io/npy.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;

// COLMAP image (world-to-camera, OpenCV axes) of a camera at `centre` looking at `target`
// with world "down" roughly along `down`.
ColmapImage look_at(int id, const std::string& name, const Eigen::Vector3d& centre, const Eigen::Vector3d& target,
                    const Eigen::Vector3d& down = Eigen::Vector3d(0, -1, 0)) {
  const Eigen::Vector3d z = (target - centre).normalized();
  const Eigen::Vector3d x = down.cross(z).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;  // rows: camera axes in world coordinates
  R.row(0) = x;
  R.row(1) = y;
  R.row(2) = z;
  const Eigen::Quaterniond q(R);
  ColmapImage im;
  im.id = id;
  im.camera_id = 1;
  im.name = name;
  im.qvec = {q.w(), q.x(), q.y(), q.z()};
  im.tvec = -R * centre;
  return im;
}

// A scene folder with the given model in `model_sub` and one w x h PNG per image.
fs::path make_scene(const ColmapModel& m, int w, int h, const std::string& model_sub = "sparse/0", bool binary = true,
                    const std::string& image_sub = "images") {
  const fs::path dir = test::temp_dir("colmap-scene");
  write_colmap_model(dir / model_sub, m, binary);
  for (const auto& [id, im] : m.images) {
    const fs::path p = dir / image_sub / im.name;
    fs::create_directories(p.parent_path());
    write_png(p, Image(w, h, 3, 0.25f));
  }
  return dir;
}

ColmapModel one_camera(const std::string& model, std::vector<double> params, int w = 32, int h = 24) {
  ColmapModel m;
  m.cameras[1] = {1, model, w, h, std::move(params)};
  return m;
}

TEST(ColmapScene, LookAtCamerasBecomeOpenGlCameraToWorld) {
  ColmapModel m = one_camera("PINHOLE", {30, 31, 16, 12});
  const Eigen::Vector3d c1(0, 0, -5), c2(3, 1, 4);
  const Eigen::Vector3d down1(0, 1, 0), down2(0, -1, 0);  // world y down / world y up
  m.images[1] = look_at(1, "b.png", c1, Eigen::Vector3d::Zero(), down1);
  m.images[2] = look_at(2, "a.png", c2, Eigen::Vector3d::Zero(), down2);
  const Scene s = load_scene(make_scene(m, 32, 24));
  EXPECT_EQ(s.format, "colmap");
  ASSERT_EQ(s.views.size(), 2u);
  // Sorted by image name, named by stem.
  EXPECT_EQ(s.views[0].name, "a");
  EXPECT_EQ(s.views[1].name, "b");
  struct Expect {
    const View* view;
    Eigen::Vector3d centre, down;
  };
  for (const Expect& e : {Expect{&s.views[0], c2, down2}, Expect{&s.views[1], c1, down1}}) {
    const Camera& c = e.view->camera;
    EXPECT_LT((c.center() - e.centre).norm(), 1e-12);
    // OpenGL: the camera looks along -z_cam (here at the origin) and +y_cam is up.
    EXPECT_LT((-c.rotation().col(2) - (-e.centre).normalized()).norm(), 1e-12);
    EXPECT_LT(c.rotation().col(1).dot(e.down), 0);
    EXPECT_NEAR(c.rotation().determinant(), 1.0, 1e-12);
    EXPECT_EQ(c.c2w.row(3), Eigen::RowVector4d(0, 0, 0, 1));
    // Back to COLMAP's world-to-camera: the origin is straight ahead at the camera's distance.
    const Eigen::Matrix4d w2c = c.w2c_opencv();
    EXPECT_LT((w2c.block<3, 1>(0, 3) - Eigen::Vector3d(0, 0, e.centre.norm())).norm(), 1e-12);
  }
  // Camera b sits on -z looking along +z with y down = world +y: the identity OpenCV
  // rotation, i.e. an OpenGL c2w rotation of diag(1, -1, -1).
  Eigen::Matrix4d expected = Eigen::Matrix4d::Identity();
  expected.block<3, 3>(0, 0) = Eigen::Vector3d(1, -1, -1).asDiagonal();
  expected.block<3, 1>(0, 3) = c1;
  EXPECT_LT((s.views[1].camera.c2w - expected).norm(), 1e-12);
  EXPECT_DOUBLE_EQ(s.views[0].camera.K.fx, 30);
  EXPECT_DOUBLE_EQ(s.views[0].camera.K.fy, 31);
  EXPECT_FALSE(s.views[0].distortion.any());
  EXPECT_FALSE(s.near.has_value());  // no points, no depth bounds
}

TEST(ColmapScene, DownscaledImagesScaleIntrinsics) {
  ColmapModel m = one_camera("PINHOLE", {30, 31, 16, 12}, 64, 48);
  m.images[1] = look_at(1, "a.jpg", Eigen::Vector3d(0, 0, -5), Eigen::Vector3d::Zero());
  // images_4 of the full-size model, PNG instead of the model's JPG (as LLFF's tools write).
  const fs::path dir = test::temp_dir("colmap-images4");
  write_colmap_model(dir / "sparse" / "0", m, true);
  fs::create_directories(dir / "images_4");
  write_png(dir / "images_4" / "a.png", Image(16, 12, 3));
  SceneOptions o;
  o.image_folder = "images_4";
  for (const Scene& s : {load_scene(dir, o), load_scene(dir)}) {  // images_4 is also the fallback
    ASSERT_EQ(s.views.size(), 1u);
    const Intrinsics& K = s.views[0].camera.K;
    EXPECT_EQ(K.width, 16);
    EXPECT_EQ(K.height, 12);
    EXPECT_DOUBLE_EQ(K.fx, 7.5);
    EXPECT_DOUBLE_EQ(K.fy, 7.75);
    EXPECT_DOUBLE_EQ(K.cx, 4);
    EXPECT_DOUBLE_EQ(K.cy, 3);
    EXPECT_EQ(s.views[0].image_path, dir / "images_4" / "a.png");
    EXPECT_TRUE(s.warnings.empty());
  }
  // A non-uniform rescale is kept (per-axis scaling) but reported.
  write_png(dir / "images_4" / "a.png", Image(16, 16, 3));
  const Scene s = load_scene(dir, o);
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("is not a uniform rescale of camera 1 (64x48)"), std::string::npos) << s.warnings[0];
  EXPECT_DOUBLE_EQ(s.views[0].camera.K.fy, 31.0 / 3);
}

TEST(ColmapScene, DistortionInOpenCvOrder) {
  struct Case {
    std::string model;
    std::vector<double> params;
    std::array<double, 5> coeffs;
    double fx, fy;
  };
  const Case cases[] = {
      {"SIMPLE_PINHOLE", {30, 16, 12}, {0, 0, 0, 0, 0}, 30, 30},
      {"SIMPLE_RADIAL", {30, 16, 12, 0.1}, {0.1, 0, 0, 0, 0}, 30, 30},
      {"RADIAL", {30, 16, 12, 0.1, -0.2}, {0.1, -0.2, 0, 0, 0}, 30, 30},
      {"OPENCV", {30, 31, 16, 12, 0.1, -0.2, 0.003, -0.004}, {0.1, -0.2, 0.003, -0.004, 0}, 30, 31},
  };
  for (const Case& c : cases) {
    ColmapModel m = one_camera(c.model, c.params);
    m.images[1] = look_at(1, "a.png", Eigen::Vector3d(0, 0, -5), Eigen::Vector3d::Zero());
    const Scene s = load_scene(make_scene(m, 32, 24, "sparse", false));  // text model in sparse/
    ASSERT_EQ(s.views.size(), 1u);
    EXPECT_EQ(s.views[0].distortion.coeffs, c.coeffs) << c.model;
    EXPECT_EQ(s.views[0].camera.K.fx, c.fx) << c.model;
    EXPECT_EQ(s.views[0].camera.K.fy, c.fy) << c.model;
    EXPECT_EQ(s.views[0].camera.K.cx, 16) << c.model;
    // Loading undistorts; the image keeps its size.
    const Image img = load_view_image(s.views[0]);
    EXPECT_EQ(img.width, 32);
    EXPECT_NEAR(img.at(12, 16, 1), 0.25, 0.01);
  }
}

TEST(ColmapScene, ModelInTheFolderItselfAndSubfolderNames) {
  ColmapModel m = one_camera("PINHOLE", {30, 31, 16, 12});
  m.images[1] = look_at(1, "cam0/0001.png", Eigen::Vector3d(0, 0, -5), Eigen::Vector3d::Zero());
  m.images[2] = look_at(2, "cam1/0001.png", Eigen::Vector3d(1, 0, -5), Eigen::Vector3d::Zero());
  m.images[3] = look_at(3, "cam1/0002.png", Eigen::Vector3d(2, 0, -5), Eigen::Vector3d::Zero());
  const Scene s = load_scene(make_scene(m, 32, 24, "."));
  ASSERT_EQ(s.views.size(), 3u);
  // Stems collide between rig folders: those views are named by their relative path.
  EXPECT_EQ(s.views[0].name, "cam0_0001");
  EXPECT_EQ(s.views[1].name, "cam1_0001");
  EXPECT_EQ(s.views[2].name, "0002");
}

// Fern's LLFF poses converted to a COLMAP model (see tests/io/colmap_test.cpp) beside the
// real cameras.bin and points3D.bin: the COLMAP reader must give the LLFF reader's poses,
// the focal scaled from 4032 to 504 pixels, the radial term, and depth bounds from the
// points close to those stored in poses_bounds.npy.
TEST(ColmapScene, FernMatchesTheLlffReader) {
  II_REQUIRE_SHARED(fern, "data/fern");
  const std::vector<double> v = read_npy(fern / "poses_bounds.npy").as_double();
  ASSERT_EQ(v.size(), 20u * 17);
  ColmapModel m;
  for (int k = 0; k < 20; ++k) {
    auto e = [&](int r, int c) { return v[k * 17 + r * 5 + c]; };
    Eigen::Matrix3d R_c2w;  // LLFF (down, right, back) -> OpenCV (right, down, forward)
    for (int r = 0; r < 3; ++r) R_c2w.row(r) << e(r, 1), e(r, 0), -e(r, 2);
    const Eigen::Quaterniond q(R_c2w.transpose());
    ColmapImage im;
    im.id = k + 1;
    im.camera_id = 1;
    im.name = fmt::format("image{:03d}.png", k);
    im.qvec = {q.w(), q.x(), q.y(), q.z()};
    im.tvec = -(R_c2w.transpose() * Eigen::Vector3d(e(0, 3), e(1, 3), e(2, 3)));
    m.images[im.id] = im;
  }
  const fs::path dir = test::temp_dir("colmap-fern");
  write_colmap_model(dir / "sparse" / "0", m, true);
  // The real cameras and points replace the synthetic (empty) ones.
  for (const char* f : {"cameras.bin", "points3D.bin"})
    fs::copy_file(fern / "sparse" / "0" / f, dir / "sparse" / "0" / f, fs::copy_options::overwrite_existing);
  fs::create_directory_symlink(fern / "images_8", dir / "images");

  const Scene c = load_colmap_scene(dir, {});
  const Scene l = load_llff_scene(fern, {});
  ASSERT_EQ(c.views.size(), 20u);
  ASSERT_EQ(l.views.size(), 20u);
  for (size_t k = 0; k < 20; ++k) {
    EXPECT_EQ(c.views[k].name, l.views[k].name);
    EXPECT_LT((c.views[k].camera.c2w - l.views[k].camera.c2w).norm(), 1e-9) << k;
    const Intrinsics& K = c.views[k].camera.K;
    EXPECT_EQ(K.width, 504);
    EXPECT_EQ(K.height, 378);
    EXPECT_NEAR(K.fx, l.views[k].camera.K.fx, 1e-9);
    EXPECT_NEAR(K.fx, 407.566, 1e-3);
    EXPECT_DOUBLE_EQ(K.cx, 252);
    EXPECT_DOUBLE_EQ(K.cy, 189);
    EXPECT_NEAR(c.views[k].distortion.coeffs[0], 0.01975, 1e-5);
  }
  // poses_bounds.npy: near 17.0-18.9, far 65.2-80.0; LLFF computed them from these points.
  ASSERT_TRUE(c.near && c.far);
  EXPECT_NEAR(*c.near, *l.near, 0.02 * *l.near);
  EXPECT_NEAR(*c.far, *l.far, 0.02 * *l.far);
  EXPECT_TRUE(c.warnings.empty());
}

TEST(ColmapScene, DepthBoundsFromVisiblePoints) {
  ColmapModel m = one_camera("PINHOLE", {30, 31, 16, 12});
  m.images[1] = look_at(1, "a.png", Eigen::Vector3d(0, 0, -10), Eigen::Vector3d::Zero());
  // 1001 points on the optical axis at depths 5..15, seen by image 1; one far outlier seen
  // by nobody.
  for (int k = 0; k <= 1000; ++k) {
    ColmapPoint p;
    p.id = k + 1;
    p.xyz = {0, 0, -5 + k * 0.01};
    p.track = {{1, k}};
    m.points[p.id] = p;
  }
  ColmapPoint outlier;
  outlier.id = 5000;
  outlier.xyz = {0, 0, 1000};
  m.points[outlier.id] = outlier;
  const Scene s = load_scene(make_scene(m, 32, 24));
  ASSERT_TRUE(s.near && s.far);
  // numpy.percentile(linspace(5, 15, 1001), [0.1, 99.9]) = 5.01, 14.99
  EXPECT_NEAR(*s.near, 5.01, 1e-9);
  EXPECT_NEAR(*s.far, 14.99, 1e-9);
}

TEST(ColmapScene, BadInputIsAClearError) {
  ColmapModel m = one_camera("PINHOLE", {30, 31, 16, 12});
  m.images[1] = look_at(1, "a.png", Eigen::Vector3d(0, 0, -5), Eigen::Vector3d::Zero());
  m.images[2] = look_at(2, "b.png", Eigen::Vector3d(1, 0, -5), Eigen::Vector3d::Zero());
  const fs::path dir = make_scene(m, 32, 24);
  const fs::path model_dir = dir / "sparse" / "0";

  fs::remove(dir / "images" / "b.png");
  EXPECT_EQ(test::error_message([&] { load_scene(dir); }),
            (dir / "images" / "b.png").string() + ": image listed in the COLMAP model is missing");
  write_png(dir / "images" / "b.png", Image(32, 24, 3));

  ColmapModel bad = m;
  bad.cameras[1] = {1, "OPENCV_FISHEYE", 32, 24, {30, 31, 16, 12, 0, 0, 0, 0}};
  write_colmap_model(model_dir, bad, true);
  EXPECT_EQ(test::error_message([&] { load_scene(dir); }),
            model_dir.string() +
                ": camera 1: unsupported camera model OPENCV_FISHEYE (supported: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, "
                "RADIAL, OPENCV)");

  bad = m;
  bad.images[2].camera_id = 9;
  write_colmap_model(model_dir, bad, true);
  EXPECT_EQ(test::error_message([&] { load_scene(dir); }), model_dir.string() + ": image b.png refers to missing camera 9");

  bad = m;
  bad.images[2].qvec.setZero();
  write_colmap_model(model_dir, bad, true);
  EXPECT_EQ(test::error_message([&] { load_scene(dir); }), model_dir.string() + ": image b.png has a zero rotation quaternion");

  bad = m;
  bad.cameras[1].params[0] = 0;
  write_colmap_model(model_dir, bad, true);
  EXPECT_EQ(test::error_message([&] { load_scene(dir); }), model_dir.string() + ": camera 1: focal length must be positive");

  bad = m;
  bad.images.clear();
  write_colmap_model(model_dir, bad, true);
  EXPECT_EQ(test::error_message([&] { load_scene(dir); }),
            model_dir.string() + ": COLMAP model has no images (images.bin / images.txt missing or empty)");

  // NaN in a pose, straight in the file (the writer refuses to write one).
  write_colmap_model(model_dir, m, true);
  {
    std::fstream f(model_dir / "images.bin", std::ios::in | std::ios::out | std::ios::binary);
    const double nan = std::nan("");
    f.seekp(8 + 4 + 32);  // first image's tx
    f.write(reinterpret_cast<const char*>(&nan), 8);
  }
  EXPECT_EQ(test::error_message([&] { load_scene(dir); }),
            (model_dir / "images.bin").string() + ": the translation of entry 1 is NaN or infinite");

  write_colmap_model(model_dir, m, true);
  SceneOptions o;
  o.image_folder = "images_2";
  EXPECT_EQ(test::error_message([&] { load_scene(dir, o); }), (dir / "images_2").string() + ": image folder not found");
  fs::remove_all(dir / "images");
  EXPECT_EQ(test::error_message([&] { load_colmap_scene(dir, {}); }),
            dir.string() + ": no images/ or images_K/ folder next to the COLMAP model");
  const fs::path empty = test::temp_dir("colmap-empty");
  EXPECT_EQ(test::error_message([&] { load_colmap_scene(empty, {}); }),
            empty.string() +
                ": no COLMAP model found (looked for cameras.bin / cameras.txt in sparse/0/, sparse/ and the folder itself)");
}

TEST(ColmapScene, SameStemTwiceIsAnError) {
  ColmapModel m = one_camera("PINHOLE", {30, 31, 16, 12});
  m.images[1] = look_at(1, "a.png", Eigen::Vector3d(0, 0, -5), Eigen::Vector3d::Zero());
  m.images[2] = look_at(2, "a.jpg", Eigen::Vector3d(1, 0, -5), Eigen::Vector3d::Zero());
  const fs::path dir = make_scene(m, 32, 24);
  EXPECT_EQ(test::error_message([&] { load_scene(dir); }),
            (dir / "images" / "a.png").string() + ": has the same name 'a' as " + (dir / "images" / "a.jpg").string() +
                ": rename one of them");
}

// ---- undistortion -------------------------------------------------------------------------

// Normalised undistorted coordinates of a distorted normalised point (fixed-point
// inversion of the OpenCV model, independent of OpenCV's own code).
Eigen::Vector2d undistort_point(const Eigen::Vector2d& pd, const Distortion& d) {
  const auto& k = d.coeffs;
  Eigen::Vector2d p = pd;
  for (int it = 0; it < 100; ++it) {
    const double x = p.x(), y = p.y(), r2 = x * x + y * y;
    const double radial = 1 + k[0] * r2 + k[1] * r2 * r2 + k[4] * r2 * r2 * r2;
    const double dx = 2 * k[2] * x * y + k[3] * (r2 + 2 * x * x);
    const double dy = k[2] * (r2 + 2 * y * y) + 2 * k[3] * x * y;
    p = Eigen::Vector2d((pd.x() - dx) / radial, (pd.y() - dy) / radial);
  }
  return p;
}

// What a distorted camera records of a scene given as a function of undistorted continuous
// pixel coordinates (pixel centres at +0.5), supersampled 4x4.
template <typename F>
Image render_distorted(const Intrinsics& K, const Distortion& d, int channels, F&& scene) {
  Image img(K.width, K.height, channels);
  for (int i = 0; i < K.height; ++i)
    for (int j = 0; j < K.width; ++j)
      for (int s = 0; s < 16; ++s) {
        const double u = j + (s % 4 + 0.5) / 4, v = i + (s / 4 + 0.5) / 4;
        const Eigen::Vector2d p = undistort_point({(u - K.cx) / K.fx, (v - K.cy) / K.fy}, d);
        const Eigen::Vector2d q(p.x() * K.fx + K.cx, p.y() * K.fy + K.cy);
        for (int c = 0; c < channels; ++c) img.at(i, j, c) += static_cast<float>(scene(q, c) / 16);
      }
  return img;
}

TEST(Undistort, CheckerboardComesBackStraight) {
  const Intrinsics K{96, 72, 80, 82, 49.5, 35};
  Distortion d;
  d.coeffs = {-0.25, 0.06, 0.002, -0.0015, 0.01};
  // Channel 0: a checkerboard of 8-pixel squares; channels 1, 2: linear ramps (x, y).
  auto scene = [&](const Eigen::Vector2d& q, int c) {
    if (c == 1) return q.x() / K.width;
    if (c == 2) return q.y() / K.height;
    return ((static_cast<int>(std::floor(q.x() / 8)) + static_cast<int>(std::floor(q.y() / 8))) % 2) ? 1.0 : 0.0;
  };
  const Image distorted = render_distorted(K, d, 3, scene);
  const Image u = undistort_image(distorted, K, d);
  ASSERT_EQ(u.width, 96);
  ASSERT_EQ(u.channels, 3);
  // Away from the squares' edges (where resampling blurs), the undistorted checkerboard is
  // exact, while the distorted one is off wherever the lens moved an edge across a pixel.
  double checker_err = 0, ramp_err = 0;
  int n = 0, raw_wrong = 0;
  for (int i = 6; i < 66; ++i)
    for (int j = 8; j < 88; ++j) {
      const Eigen::Vector2d centre(j + 0.5, i + 0.5);
      // The ramps pin down the half-pixel convention: a shift of half a pixel would be
      // 0.5 / 96 = 0.005 off.
      ramp_err = std::max(ramp_err, std::abs(u.at(i, j, 1) - centre.x() / K.width));
      ramp_err = std::max(ramp_err, std::abs(u.at(i, j, 2) - centre.y() / K.height));
      auto edge_distance = [](double x) { return std::abs(x - 8 * std::round(x / 8)); };
      if (std::min(edge_distance(centre.x()), edge_distance(centre.y())) < 1.5) continue;
      const double truth = scene(centre, 0);
      checker_err = std::max(checker_err, std::abs(u.at(i, j, 0) - truth));
      raw_wrong += std::abs(distorted.at(i, j, 0) - truth) > 0.5;
      ++n;
    }
  EXPECT_GT(n, 1000);
  EXPECT_LT(checker_err, 0.05);
  EXPECT_GT(raw_wrong, n / 20);  // the distortion was real
  EXPECT_LT(ramp_err, 0.001);
}

TEST(Undistort, MaskStaysBinaryAndNoDistortionIsIdentity) {
  const Intrinsics K{40, 30, 35, 35, 20, 15};
  Distortion d;
  d.coeffs = {-0.3, 0, 0, 0, 0};
  Image mask(40, 30, 1);
  for (int i = 8; i < 22; ++i)
    for (int j = 10; j < 30; ++j) mask.at(i, j) = 1;
  const Image u = undistort_mask(mask, K, d);
  int ones = 0;
  for (float v : u.pixels) {
    EXPECT_TRUE(v == 0.f || v == 1.f);
    ones += v == 1.f;
  }
  EXPECT_GT(ones, 0);
  EXPECT_EQ(u.at(15, 20), 1.f);  // the centre is a fixed point of the distortion
  const Image same = undistort_image(mask, K, Distortion{});
  EXPECT_EQ(same.pixels, mask.pixels);
  EXPECT_EQ(test::error_message([&] { undistort_image(Image(10, 10, 3), K, d); }),
            "undistortion: image is 10x10 but the camera is 40x30");
}

// ---- running colmap --------------------------------------------------------------------

// A stand-in for the colmap executable: logs its arguments, fails at `fail_step`, and
// "reconstructs" by copying a prepared model into <output_path>/0. With `slow`, the feature
// step logs COLMAP's counter for one of two images and takes 1.5 s (progress is polled).
fs::path fake_colmap(const fs::path& model, const std::string& fail_step = "", bool slow = false) {
  const fs::path script = test::temp_dir("fake-colmap") / "colmap";
  write_file_atomic(script, "#!/bin/sh\n"
                            "echo \"fake colmap $*\"\n"
                            "if [ \"$1\" = \"" + fail_step + "\" ]; then echo \"boom: no features\"; exit 3; fi\n" +
                            (slow ? "if [ \"$1\" = feature_extractor ]; then echo 'Processed file [1/2]'; sleep 1.5; fi\n" : "") +
                            "prev=\"\"; out=\"\"\n"
                            "for a in \"$@\"; do [ \"$prev\" = \"--output_path\" ] && out=\"$a\"; prev=\"$a\"; done\n"
                            "if [ \"$1\" = mapper ]; then mkdir -p \"$out/0\" && cp \"" + model.string() + "\"/* \"$out/0/\"; fi\n");
  fs::permissions(script, fs::perms::owner_all);
  return script;
}

TEST(ColmapRun, MissingExecutableIsAClearError) {
  ColmapRunOptions o;
  o.executable = "colmap-not-installed-here";
  EXPECT_TRUE(find_colmap(o.executable).empty());
  const fs::path dir = test::temp_dir("colmap-run-missing");
  EXPECT_EQ(test::error_message([&] { run_colmap(dir, o); }),
            "COLMAP is not installed ('colmap-not-installed-here' not found on PATH): install it (e.g. `apt install "
            "colmap`) or give the path to the executable, or pose the images with another tool and use its "
            "transforms.json / sparse model");
  EXPECT_FALSE(find_colmap("sh").empty());  // PATH lookup itself works
}

TEST(ColmapRun, RunsTheThreeStepsAndFindsTheModel) {
  ColmapModel m = one_camera("OPENCV", {30, 31, 16, 12, 0.01, 0, 0, 0});
  m.images[1] = look_at(1, "a.png", Eigen::Vector3d(0, 0, -5), Eigen::Vector3d::Zero());
  m.images[2] = look_at(2, "b.png", Eigen::Vector3d(1, 0, -5), Eigen::Vector3d::Zero());
  const fs::path prepared = test::temp_dir("colmap-prepared");
  write_colmap_model(prepared, m, true);
  const fs::path dir = test::temp_dir("colmap-run");
  for (const char* name : {"a.png", "b.png"}) {
    fs::create_directories(dir / "images");
    write_png(dir / "images" / name, Image(32, 24, 3, 0.5f));
  }
  ColmapRunOptions o;
  o.executable = fake_colmap(prepared, "", /*slow=*/true).string();
  std::vector<std::string> seen;
  o.progress = [&](const std::string& step, int done, int total, double eta_s) {
    seen.push_back(fmt::format("{} {}/{} {}", step, done, total, eta_s > 0 ? "eta" : "-"));
  };
  EXPECT_EQ(run_colmap(dir, o), fs::absolute(dir) / "sparse" / "0");
  ASSERT_FALSE(seen.empty());  // polled about once a second while the slow step ran
  EXPECT_EQ(seen.front(), "features 1/2 eta");
  const std::string log = read_file_text(dir / "colmap.log");
  EXPECT_NE(log.find("fake colmap feature_extractor --database_path " + (fs::absolute(dir) / "database.db").string()),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("--ImageReader.camera_model OPENCV --ImageReader.single_camera 1"), std::string::npos) << log;
  EXPECT_NE(log.find("fake colmap exhaustive_matcher"), std::string::npos) << log;
  EXPECT_NE(log.find("fake colmap mapper"), std::string::npos) << log;
  const Scene s = load_scene(dir);
  EXPECT_EQ(s.format, "colmap");
  EXPECT_EQ(s.views.size(), 2u);

  EXPECT_EQ(test::error_message([&] { run_colmap(dir, o); }),
            (fs::absolute(dir) / "sparse").string() + ": already holds a model; move it away to reconstruct again");
  fs::remove_all(dir / "sparse");

  // A failing step names itself and shows the end of its log.
  o.executable = fake_colmap(prepared, "exhaustive_matcher").string();
  EXPECT_EQ(test::error_message([&] { run_colmap(dir, o); }),
            "colmap exhaustive_matcher exited with status 3 (log: " + (fs::absolute(dir) / "colmap.log").string() +
                "); last lines:\nfake colmap feature_extractor --database_path " +
                (fs::absolute(dir) / "database.db").string() + " --image_path " + (fs::absolute(dir) / "images").string() +
                " --ImageReader.camera_model OPENCV --ImageReader.single_camera 1 --SiftExtraction.use_gpu 0"
                " --SiftExtraction.max_num_features 8192\n"
                "fake colmap exhaustive_matcher --database_path " + (fs::absolute(dir) / "database.db").string() +
                " --SiftMatching.use_gpu 0\nboom: no features");
}

// Photos in name order: sequential matching first; when its model leaves an image out, the
// other pairs are matched too and the mapper runs again (here the second model has both).
TEST(ColmapRun, SequentialThenExhaustiveWhenImagesAreLeftOut) {
  ColmapModel both = one_camera("OPENCV", {30, 31, 16, 12, 0.01, 0, 0, 0});
  both.images[1] = look_at(1, "a.png", Eigen::Vector3d(0, 0, -5), Eigen::Vector3d::Zero());
  both.images[2] = look_at(2, "b.png", Eigen::Vector3d(1, 0, -5), Eigen::Vector3d::Zero());
  ColmapModel one = both;
  one.images.erase(2);
  const fs::path models = test::temp_dir("colmap-two-models");
  write_colmap_model(models / "one", one, true);
  write_colmap_model(models / "both", both, true);
  const fs::path dir = test::temp_dir("colmap-fallback");
  for (const char* name : {"a.png", "b.png"}) {
    fs::create_directories(dir / "images");
    write_png(dir / "images" / name, Image(32, 24, 3, 0.5f));
  }
  // The mapper gives `one` until the exhaustive matcher has run, then `both`.
  const fs::path script = test::temp_dir("fake-colmap-fallback") / "colmap";
  const fs::path marker = script.parent_path() / "exhaustive-ran";
  write_file_atomic(script, "#!/bin/sh\n"
                            "echo \"fake colmap $*\"\n"
                            "if [ \"$1\" = exhaustive_matcher ]; then touch '" + marker.string() + "'; fi\n"
                            "prev=\"\"; out=\"\"\n"
                            "for a in \"$@\"; do [ \"$prev\" = \"--output_path\" ] && out=\"$a\"; prev=\"$a\"; done\n"
                            "model='" + (models / "one").string() + "'; [ -e '" + marker.string() + "' ] && model='" +
                                (models / "both").string() + "'\n"
                            "if [ \"$1\" = mapper ]; then mkdir -p \"$out/0\" && cp \"$model\"/* \"$out/0/\"; fi\n");
  fs::permissions(script, fs::perms::owner_all);
  ColmapRunOptions o;
  o.executable = script.string();
  o.matcher = "sequential+exhaustive";
  const ColmapRun run = run_colmap_steps(dir, o);
  EXPECT_EQ(run.registered, 2);
  EXPECT_EQ(run.matchers, (std::vector<std::string>{"sequential", "exhaustive"}));
  EXPECT_EQ(run.model, fs::absolute(dir) / "sparse" / "0");
  const std::string log = read_file_text(dir / "colmap.log");
  const size_t sequential = log.find("fake colmap sequential_matcher"), exhaustive = log.find("fake colmap exhaustive_matcher");
  ASSERT_NE(sequential, std::string::npos) << log;
  EXPECT_NE(log.find("--SiftMatching.use_gpu 0 --SequentialMatching.overlap 10\n", sequential), std::string::npos) << log;
  ASSERT_NE(exhaustive, std::string::npos) << log;
  EXPECT_LT(sequential, exhaustive);
  EXPECT_NE(log.find("fake colmap mapper", exhaustive), std::string::npos) << log;  // mapped again

  // When sequential matching poses them all, nothing more runs.
  fs::remove_all(dir / "sparse");
  fs::remove(marker);
  o.executable = fake_colmap(models / "both").string();
  o.sequential_overlap = 5;
  const ColmapRun direct = run_colmap_steps(dir, o);
  EXPECT_EQ(direct.matchers, std::vector<std::string>{"sequential"});
  EXPECT_EQ(direct.registered, 2);
  EXPECT_NE(read_file_text(dir / "colmap.log").find("sequential_matcher --database_path " +
                                                    (fs::absolute(dir) / "database.db").string() +
                                                    " --SiftMatching.use_gpu 0 --SequentialMatching.overlap 5\n"),
            std::string::npos);
  fs::remove_all(dir / "sparse");
  o.sequential_overlap = 0;
  EXPECT_EQ(test::error_message([&] { run_colmap_steps(dir, o); }), "COLMAP's sequential overlap must be at least 1, got 0");
  o.sequential_overlap = 10;

  o.matcher = "vocab_tree";
  EXPECT_EQ(test::error_message([&] { run_colmap_steps(dir, o); }),
            "unknown COLMAP matcher 'vocab_tree' (expected exhaustive, sequential or sequential+exhaustive)");
}

}  // namespace
}  // namespace ii
