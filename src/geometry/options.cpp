#include "geometry/options.h"

#include "common/error.h"
#include "geometry/settings.h"

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
  for (const GeometrySetting& s : geometry_settings())
    if (s.off_for_insertion) s.put(insertion, s.off);
  return insertion;
}

GeometryOptions GeometryOptions::papers() {
  GeometryOptions none;
  for (const GeometrySetting& s : geometry_settings())
    if (!s.off.empty()) s.put(none, s.off);
  return none;
}

}  // namespace ii
