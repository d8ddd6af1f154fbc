#pragma once
// Resampling and cropping of Images (OpenCV underneath, same filters as the official code).
#include <cstdint>
#include <vector>

#include "io/image.h"

namespace ii {

// Area-averaging resize (OpenCV INTER_AREA), the official filter for downscaling photos.
Image resize_area(const Image& image, int width, int height);
// Nearest-neighbour resize (OpenCV INTER_NEAREST), for masks.
Image resize_nearest(const Image& image, int width, int height);
// Bicubic resize (OpenCV INTER_CUBIC), for a picture painted small brought back up.
Image resize_cubic(const Image& image, int width, int height);
// Sub-image with top-left (x0, y0).
Image crop(const Image& image, int x0, int y0, int width, int height);

// The INFERNO colour map (OpenCV's, black through red to yellow) of 8-bit levels, row-major
// `width` x `height`: RGB in [0,1]. Depth maps and error maps are shown with it.
Image inferno_colours(const std::vector<uint8_t>& levels, int width, int height);

}  // namespace ii
