#include "cli/commands.h"

namespace ii::cli {

void add_scene_options(CLI::App* cmd, std::string& scene_dir, SceneOptions& options) {
  cmd->add_option("--scene", scene_dir,
                  "Scene folder: LLFF/SPIn-NeRF (poses_bounds.npy), nerfstudio (transforms.json) "
                  "or COLMAP (sparse/0 + images/)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--format", options.format, "Scene format")
      ->check(CLI::IsMember({"auto", "llff", "nerfstudio", "colmap"}))
      ->capture_default_str();
  cmd->add_option("--images", options.image_folder,
                  "Image sub-folder to read (e.g. images_4); default: the format's usual one");
  cmd->add_option("--masks", options.mask_dir,
                  "Folder of object masks matched to images by stem or '<image name>.png' "
                  "(white/1 = object)")
      ->check(CLI::ExistingDirectory);
  cmd->add_flag("--alpha-masks", options.alpha_masks,
                "Take each view's object mask from its image's alpha channel (alpha 0 = object)");
  cmd->add_option("--hold-out-every", options.hold_out_every,
                  "Hold out input views 0, N, 2N, ... as test views that show the object (compared outside their "
                  "masks; never given to the network or to --refine); for scenes without object-free test views")
      ->check(CLI::Range(1, 1000));
}

}  // namespace ii::cli
