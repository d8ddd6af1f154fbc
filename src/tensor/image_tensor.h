#pragma once
// Images (io/image.h: HWC floats in [0,1]) as LibTorch tensors and back: the one conversion
// every torch concern uses.
#include "common/torch.h"

#include "io/image.h"

namespace ii {

// (1, C, H, W) float32 on the CPU.
torch::Tensor image_to_tensor(const Image& image);
// (1, C, H, W) float32 on `device`: the pixels travel as stored (H, W, C) and are reordered
// there (on a GPU in microseconds, where the CPU's reorder was most of an upload).
torch::Tensor image_to_device(const Image& image, const torch::Device& device);
// From (C, H, W) or (1, C, H, W), any device and dtype.
Image tensor_to_image(const torch::Tensor& t);
// From (H, W, C), any device and dtype: what the renderer returns. Made contiguous on its
// device before it travels.
Image image_from_hwc(const torch::Tensor& hwc);

}  // namespace ii
