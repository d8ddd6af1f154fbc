#pragma once
// COLMAP sparse models, binary (cameras.bin, images.bin, points3D.bin) and text
// (cameras.txt, images.txt, points3D.txt): reader and writer.
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
  std::string model;  // e.g. "PINHOLE"
  int width = 0, height = 0;
  std::vector<double> params;
};

struct ColmapImage {
  int id = 0;
  Eigen::Vector4d qvec{1, 0, 0, 0};  // w x y z, world-to-camera rotation
  Eigen::Vector3d tvec = Eigen::Vector3d::Zero();
  int camera_id = 0;
  std::string name;
  std::vector<Eigen::Vector2d> xys;
  std::vector<int64_t> point3d_ids;
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

// Number of parameters of a COLMAP camera model, or -1 when unknown.
int colmap_model_params(const std::string& model);

// Reads the model in `dir` (binary preferred when both exist). images/points files may be
// absent: their maps stay empty. cameras must exist.
ColmapModel read_colmap_model(const std::filesystem::path& dir);
std::map<int, ColmapCamera> read_colmap_cameras(const std::filesystem::path& file);  // .bin or .txt
void write_colmap_model(const std::filesystem::path& dir, const ColmapModel& model, bool binary);

}  // namespace ii
