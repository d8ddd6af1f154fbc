#include "capture/frames.h"

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cctype>

#include "common/error.h"
#include "common/process.h"

namespace ii {

namespace fs = std::filesystem;

namespace {
constexpr int kScanSize = 320;  // long side of the frames scored for sharpness
}  // namespace

double sharpness(const Image& image) {
  if (image.empty()) return 0;
  cv::Mat grey(image.height, image.width, CV_32F);
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      float v = 0;
      for (int c = 0; c < image.channels; ++c) v += image.at(y, x, c);
      grey.at<float>(y, x) = 255.f * v / static_cast<float>(image.channels);
    }
  cv::Mat laplacian;
  cv::Laplacian(grey, laplacian, CV_32F);
  cv::Scalar mean, deviation;
  cv::meanStdDev(laplacian, mean, deviation);
  return deviation[0] * deviation[0];
}

std::vector<int> pick_sharpest(const std::vector<double>& scores, int count) {
  const int n = static_cast<int>(scores.size());
  std::vector<int> picked;
  if (count <= 0 || n == 0) return picked;
  if (n <= count) {
    for (int i = 0; i < n; ++i) picked.push_back(i);
    return picked;
  }
  for (int k = 0; k < count; ++k) {
    const int begin = static_cast<int>(static_cast<int64_t>(n) * k / count);
    const int end = static_cast<int>(static_cast<int64_t>(n) * (k + 1) / count);
    int best = begin;
    for (int i = begin + 1; i < end; ++i)
      if (scores[i] > scores[best]) best = i;
    picked.push_back(best);
  }
  return picked;
}

VideoFrames extract_video_frames(const fs::path& video, const fs::path& out_dir, const fs::path& work_dir, int count,
                                 int max_size) {
  const fs::path ffmpeg = find_executable("ffmpeg");
  if (ffmpeg.empty())
    fail_file(video, "cannot read the video: ffmpeg is not installed (scripts/install-deps.sh installs it, or "
                     "`apt install ffmpeg`)");
  const fs::path scan = work_dir / "scan", log = work_dir / "ffmpeg.log";
  fs::create_directories(scan);
  fs::create_directories(out_dir);
  const std::string input = fs::absolute(video).string();
  // Pass 1: every frame, small and grey, to score.
  try {
    run_logged(ffmpeg,
               {"-nostdin", "-hide_banner", "-loglevel", "error", "-i", input, "-map", "0:v:0", "-fps_mode",
                "passthrough", "-vf",
                fmt::format("scale=w={0}:h={0}:force_original_aspect_ratio=decrease,format=gray", kScanSize),
                (scan / "%06d.png").string()},
               log, "ffmpeg");
  } catch (const Error&) {
    fail_file(video, "no video stream that ffmpeg can read ({})", log_tail(log, 3));
  }
  VideoFrames result;
  for (int i = 1;; ++i) {
    const fs::path f = scan / fmt::format("{:06d}.png", i);
    if (!fs::exists(f)) break;
    result.scores.push_back(sharpness(read_image_rgb(f)));
  }
  result.decoded = static_cast<int>(result.scores.size());
  if (result.decoded == 0) fail_file(video, "ffmpeg decoded no frames from it (log: {})", log.string());
  fs::remove_all(scan);
  result.picked = pick_sharpest(result.scores, count);

  // Pass 2: the picked frames at full size (long side at most max_size).
  std::string select;
  for (int i : result.picked) select += fmt::format("{}eq(n\\,{})", select.empty() ? "" : "+", i);
  run_logged(ffmpeg,
             {"-nostdin", "-hide_banner", "-loglevel", "error", "-i", input, "-map", "0:v:0", "-fps_mode",
              "passthrough", "-vf",
              fmt::format("select='{}',scale=w='min({},iw)':h='min({},ih)':force_original_aspect_ratio=decrease", select,
                          max_size, max_size),
              (out_dir / "frame_%04d.png").string()},
             log, "ffmpeg");
  return result;
}

std::vector<fs::path> list_images(const fs::path& folder) {
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(folder)) {
    if (!e.is_regular_file()) continue;
    std::string ext = e.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    if (ext == ".png" || ext == ".jpg" || ext == ".jpeg") out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace ii
