#pragma once
// One reader per scene format; each ends in the common Scene. Use load_scene() (scene.h)
// to pick the reader from the folder's contents.
#include <filesystem>
#include <vector>

#include "data/scene.h"

namespace ii {

// The image folder of a scene: options.image_folder, else images/, else the least
// downscaled images_K/. `next_to` names the camera file for the error message.
std::filesystem::path choose_image_folder(const std::filesystem::path& dir, const SceneOptions& options,
                                          const std::string& next_to);

// LLFF / SPIn-NeRF: poses_bounds.npy, images in images/ or images_K/, object masks in
// images_K/label/, object-free test views masked by images_K/test_label/.
Scene load_llff_scene(const std::filesystem::path& dir, const SceneOptions& options);

// nerfstudio / instant-ngp transforms.json: frames in file order, c2w already OpenGL,
// global or per-frame intrinsics and OpenCV distortion. Frames whose image file is missing
// are skipped with a warning; none present is an error.
Scene load_nerfstudio_scene(const std::filesystem::path& dir, const SceneOptions& options);

// COLMAP sparse model (binary or text) in sparse/0/, sparse/ or `dir` itself, plus an image
// folder (options.image_folder, else images/, else the least downscaled images_K/). Views
// sorted by image name; intrinsics scaled to the image files' size; depth bounds from the
// 3D points when the model has them. A listed image file that is missing is an error.
Scene load_colmap_scene(const std::filesystem::path& dir, const SceneOptions& options);

// Helper for the readers: names every view by its file stem, or, where stems collide
// (rig folders cam0/0001.png, cam1/0001.png), by its path relative to `base` without the
// extension, '/' replaced by '_'. Fails when even those collide.
void assign_view_names(std::vector<View>& views, const std::filesystem::path& base);

}  // namespace ii
