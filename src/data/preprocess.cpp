#include "data/preprocess.h"

#include "common/error.h"
#include "data/image_ops.h"

namespace ii {

WorkingSize working_size(int source_width, int source_height, const PreprocessOptions& options) {
  if (options.height <= 0 || options.patch <= 0)
    fail("working height ({}) and patch size ({}) must be positive", options.height, options.patch);
  if (source_width <= 0 || source_height <= 0) fail("cannot preprocess an empty image");
  WorkingSize s;
  s.resized_height = options.height;
  s.resized_width = static_cast<int>(static_cast<long>(source_width) * options.height / source_height);
  s.width = s.resized_width / options.patch * options.patch;
  s.height = s.resized_height / options.patch * options.patch;
  if (s.width == 0 || s.height == 0)
    fail("a {}x{} image is too small for height {} and patch {}", source_width, source_height,
         options.height, options.patch);
  s.crop_x = (s.resized_width - s.width) / 2;
  s.crop_y = (s.resized_height - s.height) / 2;
  return s;
}

Image to_working_size(const Image& image, const WorkingSize& size, bool is_mask) {
  const Image resized = is_mask ? resize_nearest(image, size.resized_width, size.resized_height)
                                : resize_area(image, size.resized_width, size.resized_height);
  return crop(resized, size.crop_x, size.crop_y, size.width, size.height);
}

PreparedView prepare_view(const View& view, const PreprocessOptions& options) {
  PreparedView out;
  out.name = view.name;
  const Image image = load_view_image(view);
  const WorkingSize size = working_size(image.width, image.height, options);
  out.rgb = to_working_size(image, size);
  if (auto mask = load_view_mask(view)) out.mask = to_working_size(*mask, size, /*is_mask=*/true);
  out.camera = view.camera.resized(size.resized_width, size.resized_height)
                   .cropped(size.crop_x, size.crop_y, size.width, size.height);
  return out;
}

}  // namespace ii
