#include "capture/capture.h"

#include <spdlog/spdlog.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "capture/frames.h"
#include "common/error.h"
#include "common/files.h"
#include "common/process.h"
#include "common/stopwatch.h"
#include "data/colmap_run.h"
#include "data/image_ops.h"
#include "data/scene.h"

namespace ii {

namespace fs = std::filesystem;
using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

constexpr int kStages = 4;
// The largest distance between two cameras after capture: that of the LLFF scenes (statue
// 11.4, fern 10.3 units), for which the official orbit's radius of 4 units was made.
constexpr double kCameraSpread = 10;

Matrix3d rotation_of(const ColmapImage& im) {
  return Eigen::Quaterniond(im.qvec[0], im.qvec[1], im.qvec[2], im.qvec[3]).normalized().toRotationMatrix();
}

Vector3d centre_of(const ColmapImage& im) { return -rotation_of(im).transpose() * im.tvec; }

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// Images of a folder, resized so the long side is at most max_size, as PNGs in `dir`.
int copy_images(const fs::path& folder, const fs::path& dir, int max_size) {
  const std::vector<fs::path> files = list_images(folder);
  if (files.size() < 3)
    fail_file(folder, "holds {} image(s) (png, jpg); posing needs at least 3, better 20 or more with much overlap",
              files.size());
  fs::create_directories(dir);
  for (const fs::path& f : files) {
    Image im = read_image_rgb(f);
    const int long_side = std::max(im.width, im.height);
    if (long_side > max_size) {
      const double s = static_cast<double>(max_size) / long_side;
      im = resize_area(im, std::max(1, static_cast<int>(std::lround(im.width * s))),
                       std::max(1, static_cast<int>(std::lround(im.height * s))));
    }
    write_png(dir / (f.stem().string() + ".png"), im);
  }
  return static_cast<int>(files.size());
}

}  // namespace

SceneFrame sensible_frame(const ColmapModel& model) {
  SceneFrame f;
  if (model.images.empty()) return f;
  std::vector<Vector3d> centres;
  Vector3d up = Vector3d::Zero();
  for (const auto& [id, im] : model.images) {
    centres.push_back(centre_of(im));
    up += -rotation_of(im).transpose() * Vector3d::UnitY();  // a camera's up is its -y axis
  }
  // Centre: the median of the points (what the cameras look at), else of the cameras.
  std::vector<double> xs, ys, zs;
  if (!model.points.empty())
    for (const auto& [id, p] : model.points) xs.push_back(p.xyz.x()), ys.push_back(p.xyz.y()), zs.push_back(p.xyz.z());
  else
    for (const Vector3d& c : centres) xs.push_back(c.x()), ys.push_back(c.y()), zs.push_back(c.z());
  f.centre = Vector3d(median(xs), median(ys), median(zs));
  if (up.norm() > 1e-9) f.rotation = Eigen::Quaterniond::FromTwoVectors(up.normalized(), -Vector3d::UnitY()).toRotationMatrix();
  double spread = 0;
  for (const Vector3d& a : centres)
    for (const Vector3d& b : centres) spread = std::max(spread, (a - b).norm());
  f.scale = spread > 1e-12 ? kCameraSpread / spread : 1;
  return f;
}

void apply_frame(ColmapModel& model, const SceneFrame& f) {
  // x' = s R (x - c): a camera's R_i' = R_i R^T, t_i' = s (R_i c + t_i).
  for (auto& [id, im] : model.images) {
    const Matrix3d r = rotation_of(im);
    const Eigen::Quaterniond q(r * f.rotation.transpose());
    im.qvec = Eigen::Vector4d(q.w(), q.x(), q.y(), q.z());
    im.tvec = f.scale * (r * f.centre + im.tvec);
  }
  for (auto& [id, p] : model.points) p.xyz = f.scale * f.rotation * (p.xyz - f.centre);
}

std::vector<NamedPose> poses_of(const ColmapModel& model) {
  std::vector<NamedPose> out;
  for (const auto& [id, im] : model.images) {
    Eigen::Matrix4d w2c = Eigen::Matrix4d::Identity();
    w2c.topLeftCorner<3, 3>() = rotation_of(im);
    w2c.topRightCorner<3, 1>() = im.tvec;
    out.push_back({fs::path(im.name).stem().string(), w2c});
  }
  return out;
}

std::vector<NamedPose> poses_of_scene(const fs::path& scene_dir) { return poses_of_scene(load_scene(scene_dir)); }

std::vector<NamedPose> poses_of_scene(const Scene& scene) {
  std::vector<NamedPose> out;
  for (const auto* views : {&scene.views, &scene.test_views})
    for (const View& v : *views) out.push_back({v.name, v.camera.w2c_opencv()});
  return out;
}

PoseComparison compare_poses(const std::vector<NamedPose>& posed, const std::vector<NamedPose>& reference) {
  auto by_name = [](const std::vector<NamedPose>& poses) {
    std::map<std::string, const NamedPose*> out;
    for (const NamedPose& p : poses) out[p.name] = &p;
    return out;
  };
  const auto a = by_name(posed), b = by_name(reference);
  std::vector<std::pair<const NamedPose*, const NamedPose*>> pairs;
  for (const auto& [name, p] : a)
    if (b.count(name)) pairs.emplace_back(p, b.at(name));
  if (pairs.empty() && a.size() <= b.size()) {
    auto it = b.begin();
    for (const auto& [name, p] : a) pairs.emplace_back(p, (it++)->second);
  }
  PoseComparison c;
  c.matched = static_cast<int>(pairs.size());
  if (pairs.size() < 3) return c;
  auto centre = [](const NamedPose& p) -> Vector3d {
    return -p.w2c.topLeftCorner<3, 3>().transpose() * p.w2c.topRightCorner<3, 1>();
  };
  Eigen::Matrix3Xd src(3, pairs.size()), dst(3, pairs.size());
  for (size_t i = 0; i < pairs.size(); ++i) {
    src.col(i) = centre(*pairs[i].first);
    dst.col(i) = centre(*pairs[i].second);
  }
  const Eigen::Matrix4d sim = Eigen::umeyama(src, dst, true);
  const Matrix3d sr = sim.topLeftCorner<3, 3>();
  // Orientations are compared after the rotation that best aligns them (the chordal mean of
  // the per-view rotations): the similarity fitted to camera centres alone turns them by up
  // to a degree when the cameras lie on a short arc.
  Matrix3d sum = Matrix3d::Zero();
  for (const auto& [posed_view, ref_view] : pairs)
    sum += ref_view->w2c.topLeftCorner<3, 3>().transpose() * posed_view->w2c.topLeftCorner<3, 3>();
  const Eigen::JacobiSVD<Matrix3d> svd(sum, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Matrix3d align = svd.matrixU() * svd.matrixV().transpose();
  if (align.determinant() < 0) {
    Matrix3d flip = Matrix3d::Identity();
    flip(2, 2) = -1;
    align = svd.matrixU() * flip * svd.matrixV().transpose();
  }
  double spread = 0;
  for (size_t i = 0; i < pairs.size(); ++i)
    for (size_t j = i + 1; j < pairs.size(); ++j) spread = std::max(spread, (dst.col(i) - dst.col(j)).norm());
  std::vector<double> rot, pos;
  for (size_t i = 0; i < pairs.size(); ++i) {
    const Matrix3d c2w_posed = align * pairs[i].first->w2c.topLeftCorner<3, 3>().transpose();
    const Matrix3d c2w_ref = pairs[i].second->w2c.topLeftCorner<3, 3>().transpose();
    rot.push_back(Eigen::AngleAxisd(c2w_ref.transpose() * c2w_posed).angle() * 180 / M_PI);
    const Vector3d moved = sr * src.col(i) + sim.topRightCorner<3, 1>();
    pos.push_back((moved - dst.col(i)).norm() / std::max(spread, 1e-12));
  }
  c.median_rotation_deg = median(rot);
  c.max_rotation_deg = *std::max_element(rot.begin(), rot.end());
  c.median_position = median(pos);
  c.max_position = *std::max_element(pos.begin(), pos.end());
  return c;
}

nlohmann::json comparison_json(const PoseComparison& c, const std::string& scene) {
  return {{"scene", scene},
          {"matched", c.matched},
          {"median_rotation_deg", c.median_rotation_deg},
          {"max_rotation_deg", c.max_rotation_deg},
          {"median_position", c.median_position},
          {"max_position", c.max_position},
          {"position_unit", "largest distance between two reference cameras"}};
}

std::string comparison_line(const nlohmann::json& c) {
  return fmt::format("against {} ({} views matched): rotation median {:.3f} deg (max {:.3f}), position median {:.4f} "
                     "(max {:.4f}) of the camera spread",
                     c["scene"].get<std::string>(), c["matched"].get<int>(), c["median_rotation_deg"].get<double>(),
                     c["max_rotation_deg"].get<double>(), c["median_position"].get<double>(),
                     c["max_position"].get<double>());
}

nlohmann::json capture_scene(const fs::path& input, const fs::path& out, const CaptureOptions& o) {
  Stopwatch total, stage;
  auto begin = [&](int k, const std::string& what) {
    if (o.on_stage) o.on_stage(k, kStages, what);
    stage.lap();
  };
  if (!fs::exists(input)) fail_file(input, "not found (give a video file or a folder of photos)");
  if (o.frames < 3) fail("--frames {}: posing needs at least 3 frames", o.frames);
  if (o.max_size < 64) fail("--max-size {}: too small to pose (at least 64 pixels)", o.max_size);
  const bool video = !fs::is_directory(input);
  // Photos are matched in name order first (cameras and phones number them as taken); only when
  // that leaves some unposed are the other pairs matched too. A video's frames are in order.
  const std::string matcher =
      o.matcher == "auto" ? (video ? "sequential" : "sequential+exhaustive") : o.matcher;
  if (o.matcher != "auto" && matcher != "sequential" && matcher != "exhaustive")
    fail("unknown matcher '{}' (auto, sequential or exhaustive)", o.matcher);
  const fs::path colmap_exe = find_colmap(o.colmap);
  if (colmap_exe.empty())
    fail("COLMAP is not installed ('{}' not found): `apt install colmap` (scripts/install-deps.sh does it) or give "
         "its path with --colmap",
         o.colmap);
  if (fs::exists(out) && !(fs::is_directory(out) && fs::is_empty(out)))
    fail_file(out, "already exists; give a new folder (nothing there is overwritten)");
  const fs::path work = fs::absolute(out) / "colmap";
  fs::create_directories(work);

  nlohmann::json report = {{"input", fs::absolute(input).string()}, {"kind", video ? "video" : "images"},
                           {"matcher", matcher}, {"max_size", o.max_size}};
  nlohmann::json timings;
  begin(1, video ? "picking the sharpest frames" : "reading the images");
  int inputs = 0;
  if (video) {
    const VideoFrames frames = extract_video_frames(input, work / "images", work, o.frames, o.max_size);
    inputs = static_cast<int>(frames.picked.size());
    report["video_frames"] = frames.decoded;
    report["picked_frames"] = frames.picked;
    if (inputs < 3) fail_file(input, "has {} frame(s); posing needs at least 3", inputs);
  } else {
    inputs = copy_images(input, work / "images", o.max_size);
  }
  report["images"] = inputs;
  timings["frames_s"] = stage.ms() / 1000;

  begin(2, fmt::format("posing {} images with COLMAP ({} matching; log: {})", inputs,
                       matcher == "sequential+exhaustive" ? "name-order, then every pair if some are left unposed"
                                                          : matcher,
                       (work / "colmap.log").string()));
  ColmapRunOptions colmap;
  colmap.executable = o.colmap;
  colmap.matcher = matcher;
  // COLMAP's own default camera (focal, centre, one radial term): the 8 numbers of OPENCV made mapping
  // 24 % slower on 60 photos for no better poses (2026-11-27; docs/benchmarks.md, "Not kept"). A global
  // bundle adjustment when the model has grown by 40 % rather than 10 %: most of the mapper's time, for
  // what the local adjustments and the final global one settle anyway.
  colmap.camera_model = "SIMPLE_RADIAL";
  colmap.mapper_options = {"--Mapper.ba_global_images_ratio", "1.4", "--Mapper.ba_global_points_ratio", "1.4"};
  // Each image matched with its next 5 (and 8, 16, 32 on) rather than 10: 40 % less matching for the
  // same poses on 60 frames (2026-11-27, 0cd41cf; docs/benchmarks.md, "Capture from photos or a video
  // (`capture`)"); photos left unposed still get every pair.
  colmap.sequential_overlap = 5;
  colmap.progress = o.on_colmap_progress;
  const ColmapRun run = run_colmap_steps(work, colmap);
  const fs::path& model_dir = run.model;
  const int registered = run.registered;
  report["registered"] = registered;
  std::string matchers;
  for (const std::string& m : run.matchers) matchers += (matchers.empty() ? "" : ", then ") + m;
  report["matcher"] = matchers;
  timings["colmap_s"] = stage.ms() / 1000;
  timings["colmap_features_s"] = run.features_s;
  timings["colmap_matching_s"] = run.matching_s;
  timings["colmap_mapping_s"] = run.mapping_s;
  if (registered < 3 || 2 * registered < inputs)
    fail("COLMAP registered {} of {} images (log: {}): too few to trust. Try more overlap between neighbouring "
         "frames, slower motion, more texture in view, or --matcher exhaustive",
         registered, inputs, (work / "colmap.log").string());
  if (registered < inputs)
    spdlog::warn("COLMAP registered {} of {} images; the others are left out", registered, inputs);

  begin(3, "undistorting to pinhole cameras");
  const fs::path undistorted = work / "undistorted";
  run_logged(colmap_exe,
             {"image_undistorter", "--image_path", (work / "images").string(), "--input_path", model_dir.string(),
              "--output_path", undistorted.string(), "--output_type", "COLMAP"},
             work / "colmap.log", "colmap image_undistorter");
  timings["undistort_s"] = stage.ms() / 1000;

  begin(4, "centring the scene and writing it");
  ColmapModel model = read_colmap_model(undistorted / "sparse");
  const SceneFrame frame = sensible_frame(model);
  apply_frame(model, frame);
  write_colmap_model(out / "sparse" / "0", model, true);
  fs::rename(undistorted / "images", out / "images");
  fs::remove_all(undistorted);
  report["transform"] = {{"centre", {frame.centre.x(), frame.centre.y(), frame.centre.z()}},
                         {"scale", frame.scale},
                         {"note", "x_scene = scale * rotation * (x_colmap - centre); up is -y"}};
  std::vector<std::vector<double>> rot;
  for (int r = 0; r < 3; ++r) rot.push_back({frame.rotation(r, 0), frame.rotation(r, 1), frame.rotation(r, 2)});
  report["transform"]["rotation"] = rot;
  report["points"] = model.points.size();
  if (!o.compare.empty()) {
    report["compared_with"] =
        comparison_json(compare_poses(poses_of(model), poses_of_scene(o.compare)), o.compare.string());
  }
  timings["write_s"] = stage.ms() / 1000;
  timings["total_s"] = total.ms() / 1000;
  report["timings"] = timings;
  write_file_atomic(out / "capture.json", report.dump(2) + "\n");
  return report;
}

}  // namespace ii
