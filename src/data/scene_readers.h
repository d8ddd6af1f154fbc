#pragma once
// One reader per scene format; each ends in the common Scene. Use load_scene() (scene.h)
// to pick the reader from the folder's contents.
#include <filesystem>

#include "data/scene.h"

namespace ii {

// LLFF / SPIn-NeRF: poses_bounds.npy, images in images/ or images_K/, object masks in
// images_K/label/, object-free test views masked by images_K/test_label/.
Scene load_llff_scene(const std::filesystem::path& dir, const SceneOptions& options);

// nerfstudio / instant-ngp transforms.json.
Scene load_nerfstudio_scene(const std::filesystem::path& dir, const SceneOptions& options);

// COLMAP sparse model (binary or text) plus an image folder.
Scene load_colmap_scene(const std::filesystem::path& dir, const SceneOptions& options);

}  // namespace ii
