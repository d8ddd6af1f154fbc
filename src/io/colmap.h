#pragma once
// COLMAP sparse models, binary (cameras.bin, images.bin, points3D.bin) and text
// (cameras.txt, images.txt, points3D.txt): reader and writer. Parsing only: turning a model
// into posed views is data/colmap_scene.cpp's job.
#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace ii {

struct ColmapCamera {
  int id = 0;
  std::string model;  // e.g. "PINHOLE"; always one of the models COLMAP defines
  int width = 0, height = 0;
  std::vector<double> params;  // as many as the model has (colmap_model_params)
};

struct ColmapImage {
  int id = 0;
  Eigen::Vector4d qvec{1, 0, 0, 0};  // w x y z, world-to-camera rotation (OpenCV axes)
  Eigen::Vector3d tvec = Eigen::Vector3d::Zero();  // world-to-camera translation
  int camera_id = 0;
  std::string name;  // relative to the image folder, '/'-separated
  std::vector<Eigen::Vector2d> xys;
  std::vector<int64_t> point3d_ids;  // one per xy, -1 = no 3D point
};

struct ColmapPoint {
  int64_t id = 0;
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
  std::array<uint8_t, 3> rgb{};
  double error = 0;
  std::vector<std::pair<int, int>> track;  // (image id, point2D index)
};

struct ColmapModel {
  std::map<int, ColmapCamera> cameras;
  std::map<int, ColmapImage> images;
  std::map<int64_t, ColmapPoint> points;
};

// Number of parameters of a COLMAP camera model name, or -1 when the model is unknown.
int colmap_model_params(const std::string& model);
// COLMAP's numeric id of a model name (0 SIMPLE_PINHOLE ... 11), or -1 when unknown.
int colmap_model_id(const std::string& model);

// Reads the model in `dir`. The binary set is preferred when cameras.bin exists; otherwise
// the text set. images and points files may be absent: their maps stay empty and the caller
// decides. Throws Error naming the file and the problem on anything malformed.
ColmapModel read_colmap_model(const std::filesystem::path& dir);
// One cameras file, binary or text by its extension (.txt = text, anything else binary).
std::map<int, ColmapCamera> read_colmap_cameras(const std::filesystem::path& file);

// Writes cameras, images and points3D (.bin when `binary`, else .txt) into `dir`, creating
// it; each file is written atomically. Text keeps every double exact (shortest round-trip
// form), so both formats round-trip bit for bit.
void write_colmap_model(const std::filesystem::path& dir, const ColmapModel& model, bool binary);

}  // namespace ii
