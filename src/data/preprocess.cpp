#include "data/preprocess.h"

#include <algorithm>

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

Camera WorkingSize::working_camera(const Camera& source) const {
  return source.resized(resized_width, resized_height).cropped(crop_x, crop_y, width, height);
}

WorkingSize covering_size(int source_width, int source_height, int width, int height, double crop_fx, double crop_fy) {
  const int64_t W = source_width, H = source_height;
  if (W <= 0 || H <= 0) fail("cannot crop {}x{} from an empty image", width, height);
  int64_t h = std::max<int64_t>(height, (static_cast<int64_t>(width) * H + W - 1) / W);
  while (W * h / H < width) ++h;
  WorkingSize s;
  s.resized_height = static_cast<int>(h);
  s.resized_width = static_cast<int>(W * h / H);
  s.width = width;
  s.height = height;
  const int free_x = s.resized_width - width, free_y = s.resized_height - height;
  s.crop_x = std::min(free_x, static_cast<int>(crop_fx * (free_x + 1)));
  s.crop_y = std::min(free_y, static_cast<int>(crop_fy * (free_y + 1)));
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
  out.camera = size.working_camera(view.camera);
  return out;
}

std::optional<Image> view_picture_at_working_size(const Image& picture, int photo_width, int photo_height,
                                                  const WorkingSize& target, int patch) {
  if (picture.width == target.width && picture.height == target.height) return picture;
  if (picture.width == photo_width && picture.height == photo_height) return to_working_size(picture, target);
  if (picture.height < patch) return std::nullopt;
  const WorkingSize own = working_size(photo_width, photo_height, {picture.height, patch});
  if (own.width != picture.width || own.height != picture.height) return std::nullopt;
  Image uncropped(own.resized_width, own.resized_height, picture.channels);
  for (int y = 0; y < uncropped.height; ++y)
    for (int x = 0; x < uncropped.width; ++x) {
      const int sy = std::clamp(y - own.crop_y, 0, picture.height - 1), sx = std::clamp(x - own.crop_x, 0, picture.width - 1);
      for (int c = 0; c < picture.channels; ++c) uncropped.at(y, x, c) = picture.at(sy, sx, c);
    }
  return to_working_size(uncropped, target);
}

PreparedView PreparedViewCache::get(const View& view, const PreprocessOptions& options) {
  const auto key = std::make_tuple(view.name, options.height, options.patch);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto found = views_.find(key);
    if (found != views_.end()) return found->second;
  }
  PreparedView prepared = prepare_view(view, options);  // unlocked: views are prepared side by side
  std::lock_guard<std::mutex> lock(mutex_);
  return views_.emplace(key, std::move(prepared)).first->second;
}

void PreparedViewCache::put(const View& view, const PreprocessOptions& options, PreparedView prepared) {
  std::lock_guard<std::mutex> lock(mutex_);
  views_[std::make_tuple(view.name, options.height, options.patch)] = std::move(prepared);
}

}  // namespace ii
