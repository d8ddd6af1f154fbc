#pragma once
// Resampling and cropping of Images (OpenCV underneath, same filters as the official code).
#include "io/image.h"

namespace ii {

// Area-averaging resize (OpenCV INTER_AREA), the official filter for downscaling photos.
Image resize_area(const Image& image, int width, int height);
// Nearest-neighbour resize (OpenCV INTER_NEAREST), for masks.
Image resize_nearest(const Image& image, int width, int height);
// Sub-image with top-left (x0, y0).
Image crop(const Image& image, int x0, int y0, int width, int height);

}  // namespace ii
