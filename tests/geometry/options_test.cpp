#include "geometry/options.h"

#include <gtest/gtest.h>

#include "common/error.h"

namespace ii {

TEST(GeometryOptions, AnInsertionTurnsOffTheRegionSurfaceAndNothingElse) {
  GeometryOptions given;
  given.align_depth = DepthPoints::any;
  given.floaters.fade = 0.5;
  given.frame_margin.fraction = 0.2;
  given.region_cover.opacity = 0.4;
  given.region_surface.opacity = 0.9;
  const GeometryOptions insertion = given.for_insertion();
  EXPECT_EQ(insertion.region_surface.opacity, 0);
  EXPECT_EQ(insertion.align_depth, DepthPoints::any);
  EXPECT_EQ(insertion.floaters.fade, 0.5);
  EXPECT_EQ(insertion.frame_margin.fraction, 0.2);
  EXPECT_EQ(insertion.region_cover.opacity, 0.4);
  EXPECT_EQ(given.region_surface.opacity, 0.9);  // the given options are left as they were
}

TEST(GeometryOptions, DepthPointsByName) {
  for (DepthPoints p : {DepthPoints::none, DepthPoints::depth_maps, DepthPoints::photos, DepthPoints::any})
    EXPECT_EQ(parse_depth_points(depth_points_name(p)), p);
  try {
    parse_depth_points("colmap");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "--align-depth 'colmap': none, depth-maps, photos or any");
  }
}

}  // namespace ii
