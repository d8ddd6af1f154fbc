#include "geometry/options.h"

#include <gtest/gtest.h>

#include <algorithm>

#include <fmt/format.h>

#include "common/error.h"
#include "geometry/settings.h"

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

namespace ii {

// The paper's preset is every step's switch at its `off` value, as it was written out before the
// table; everything else keeps the default.
TEST(GeometrySettings, ThePapersPresetTurnsEveryStepOff) {
  const GeometryOptions papers = GeometryOptions::papers(), defaults;
  EXPECT_EQ(papers.align_depth, DepthPoints::none);
  EXPECT_EQ(papers.floaters.fade, 1);
  EXPECT_EQ(papers.measured_surface.opacity, 0);
  EXPECT_EQ(papers.frame_margin.fraction, 0);
  EXPECT_EQ(papers.behind_edges.fraction, 0);
  EXPECT_EQ(papers.region_cover.opacity, 0);
  EXPECT_EQ(papers.region_surface.opacity, 0);
  EXPECT_EQ(papers.depth_detail.detail, defaults.depth_detail.detail);
  EXPECT_EQ(papers.measured_surface.stereo.planes, defaults.measured_surface.stereo.planes);
}

// Each row reads and writes its own field: a value set by name comes back from get, and no other
// row's value changes (flying-pixels sets the measured surface's and the region surface's alike).
TEST(GeometrySettings, EachRowSetsItsOwnFieldByName) {
  const std::vector<GeometrySetting>& table = geometry_settings();
  ASSERT_GE(table.size(), 20u);
  for (const GeometrySetting& row : table) {
    GeometryOptions o;
    const std::string value = row.kind == "choice" ? row.choices.back()
                              : row.kind == "bool" ? (row.get(o) == "true" ? "false" : "true")
                              : row.kind == "integer" ? fmt::format("{}", int64_t(row.min) + 1)
                                                      : fmt::format("{}", (row.min + row.max) / 3);
    std::string python = row.name;
    std::replace(python.begin(), python.end(), '-', '_');
    set_geometry_setting(o, python, value);
    EXPECT_EQ(row.get(o), value) << row.name;
    for (const GeometrySetting& other : table) {
      if (other.name == row.name) continue;
      EXPECT_EQ(other.get(o), other.get(GeometryOptions())) << row.name << " changed " << other.name;
    }
  }
  GeometryOptions keep;
  set_geometry_setting(keep, "flying-pixels", "keep");
  EXPECT_FALSE(keep.measured_surface.far_side);
  EXPECT_FALSE(keep.region_surface.far_side);
}

TEST(GeometrySettings, BadValuesAndNamesAreClearErrors) {
  GeometryOptions o;
  auto message = [&](const std::string& name, const std::string& text) {
    try {
      set_geometry_setting(o, name, text);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message("frame-margin", "2"), "--frame-margin '2': a number from 0 to 1");
  EXPECT_EQ(message("frame_margin", "x"), "--frame-margin 'x': a number from 0 to 1");
  EXPECT_EQ(message("frame-margin", ""), "--frame-margin '': a number from 0 to 1");
  EXPECT_EQ(message("stereo-planes", "2.5"), "--stereo-planes '2.5': a whole number from 3 to 1024");
  EXPECT_EQ(message("stereo-depth", "maybe"), "--stereo-depth 'maybe': true or false");
  EXPECT_EQ(message("align-depth", "colmap"), "--align-depth 'colmap': none, depth-maps, photos or any");
  EXPECT_EQ(message("fade-floaters", "nan"), "--fade-floaters 'nan': a number from 0 to 1");
  EXPECT_EQ(message("frame-margins", "0").rfind("geometry: no setting 'frame-margins' (the settings: align-depth, ", 0), 0u);
  EXPECT_EQ(o.frame_margin.fraction, GeometryOptions().frame_margin.fraction);  // nothing was set
  set_geometry_setting(o, "stereo-planes", "1e2");  // an integer read as the check read it
  EXPECT_EQ(o.measured_surface.stereo.planes, 100);
}

}  // namespace ii
