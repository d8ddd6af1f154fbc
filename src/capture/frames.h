#pragma once
// Frames for posing: the sharpest frame of each stretch of a video, and images resized for
// COLMAP. Videos are read by the ffmpeg tool (no shell; any format it reads).
#include <filesystem>
#include <string>
#include <vector>

#include "io/image.h"

namespace ii {

// Variance of the Laplacian of the grey levels (in 0..255 units): larger is sharper.
double sharpness(const Image& image);

// Indices of `count` items, one per equal stretch of `scores`, the largest score of each (the
// first of equal ones); all of them when there are no more than `count`.
std::vector<int> pick_sharpest(const std::vector<double>& scores, int count);

struct VideoFrames {
  int decoded = 0;              // frames in the video
  std::vector<int> picked;      // their indices, in order
  std::vector<double> scores;   // sharpness of every decoded frame (at scan resolution)
};

// Writes `count` frames of `video` (the sharpest of each equal stretch of time, long side at
// most `max_size`) as frame_0001.png, ... in `out_dir`; `work_dir` holds the scan and
// ffmpeg.log. Throws when ffmpeg is missing or the input holds no readable video stream.
VideoFrames extract_video_frames(const std::filesystem::path& video, const std::filesystem::path& out_dir,
                                 const std::filesystem::path& work_dir, int count, int max_size);

// The image files of a folder (png, jpg, jpeg in any case), sorted by name.
std::vector<std::filesystem::path> list_images(const std::filesystem::path& folder);

}  // namespace ii
