#include "geometry/options.h"

#include "common/error.h"

namespace ii {

const char* depth_points_name(DepthPoints points) {
  switch (points) {
    case DepthPoints::none: return "none";
    case DepthPoints::depth_maps: return "depth-maps";
    case DepthPoints::photos: return "photos";
    case DepthPoints::any: return "any";
  }
  return "?";
}

DepthPoints parse_depth_points(const std::string& name) {
  for (DepthPoints p : {DepthPoints::none, DepthPoints::depth_maps, DepthPoints::photos, DepthPoints::any})
    if (name == depth_points_name(p)) return p;
  fail("--align-depth '{}': none, depth-maps, photos or any", name);
}

GeometryOptions GeometryOptions::for_insertion() const {
  GeometryOptions insertion = *this;
  insertion.region_surface.opacity = 0;
  return insertion;
}

GeometryOptions GeometryOptions::papers() {
  GeometryOptions none;
  none.align_depth = DepthPoints::none;
  none.floaters.fade = 1;
  none.measured_surface.opacity = 0;
  none.frame_margin.fraction = 0;
  none.behind_edges.fraction = 0;
  none.region_cover.opacity = 0;
  none.region_surface.opacity = 0;
  return none;
}

}  // namespace ii
