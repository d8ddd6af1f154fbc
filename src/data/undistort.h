#pragma once
// Removal of lens distortion (OpenCV model k1, k2, p1, p2, k3), keeping the same pinhole
// intrinsics, so that undistorted images fit the plain pinhole cameras used everywhere else.
#include "camera/camera.h"
#include "io/image.h"

namespace ii {

Image undistort_image(const Image& image, const Intrinsics& K, const Distortion& distortion);
// Nearest-neighbour variant for binary masks.
Image undistort_mask(const Image& mask, const Intrinsics& K, const Distortion& distortion);

}  // namespace ii
