#include "tensor/image_tensor.h"

#include <fmt/ranges.h>

#include "common/error.h"

namespace ii {

torch::Tensor image_to_tensor(const Image& image) {
  if (image.empty()) fail("cannot convert an empty image to a tensor");
  return torch::from_blob(const_cast<float*>(image.pixels.data()), {image.height, image.width, image.channels},
                          torch::kFloat32)
      .permute({2, 0, 1})
      .unsqueeze(0)
      .clone();
}

torch::Tensor image_to_device(const Image& image, const torch::Device& device) {
  if (device.is_cpu()) return image_to_tensor(image);
  if (image.empty()) fail("cannot convert an empty image to a tensor");
  return torch::from_blob(const_cast<float*>(image.pixels.data()), {image.height, image.width, image.channels},
                          torch::kFloat32)
      .to(device)
      .permute({2, 0, 1})
      .unsqueeze(0)
      .contiguous();
}

Image image_from_hwc(const torch::Tensor& hwc) {
  if (hwc.dim() != 3) fail("image_from_hwc: expected (H, W, C), got shape [{}]", fmt::join(hwc.sizes(), ", "));
  const torch::Tensor x = hwc.detach().to(torch::kFloat32).contiguous().to(torch::kCPU);
  Image image(static_cast<int>(x.size(1)), static_cast<int>(x.size(0)), static_cast<int>(x.size(2)));
  std::copy(x.data_ptr<float>(), x.data_ptr<float>() + x.numel(), image.pixels.begin());
  return image;
}

Image tensor_to_image(const torch::Tensor& t) {
  torch::Tensor x = t;
  if (x.dim() == 4) {
    if (x.size(0) != 1) fail("tensor_to_image: expected one image, got a batch of {}", x.size(0));
    x = x[0];
  }
  if (x.dim() != 3) fail("tensor_to_image: expected (C, H, W), got shape [{}]", fmt::join(t.sizes(), ", "));
  return image_from_hwc(x.permute({1, 2, 0}));
}

}  // namespace ii
