#include "geometry/settings.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <type_traits>

#include <fmt/format.h>

#include "common/error.h"

namespace ii {

namespace {

std::string number_text(double v) { return fmt::format("{}", v); }

// A yes or no as the commands have always taken it.
std::optional<bool> bool_from_text(const std::string& text) {
  if (text == "true" || text == "1" || text == "yes" || text == "on") return true;
  if (text == "false" || text == "0" || text == "no" || text == "off") return false;
  return std::nullopt;
}

GeometrySetting row(std::string name, std::string help, std::string kind, double min = 0, double max = 0,
                    std::vector<std::string> choices = {}, std::string off = "", bool off_for_insertion = false) {
  GeometrySetting s;
  s.name = std::move(name);
  s.help = std::move(help);
  s.kind = std::move(kind);
  s.min = min;
  s.max = max;
  s.choices = std::move(choices);
  s.off = std::move(off);
  s.off_for_insertion = off_for_insertion;
  return s;
}

template <typename Field>
GeometrySetting number(std::string name, double min, double max, std::string help, Field field,
                       std::string off = "", bool off_for_insertion = false) {
  GeometrySetting s = row(std::move(name), std::move(help), "number", min, max, {}, std::move(off), off_for_insertion);
  s.get = [field](const GeometryOptions& o) { return number_text(field(o)); };
  s.put = [field](GeometryOptions& o, const std::string& text) { field(o) = std::strtod(text.c_str(), nullptr); };
  return s;
}

template <typename Field>
GeometrySetting integer(std::string name, int64_t min, int64_t max, std::string help, Field field) {
  GeometrySetting s = row(std::move(name), std::move(help), "integer", double(min), double(max));
  s.get = [field](const GeometryOptions& o) { return fmt::format("{}", field(o)); };
  s.put = [field](GeometryOptions& o, const std::string& text) {
    // Read as check_geometry_setting read it ("1e2" is 100).
    field(o) = static_cast<std::remove_reference_t<decltype(field(o))>>(std::llround(std::strtod(text.c_str(), nullptr)));
  };
  return s;
}

template <typename Field>
GeometrySetting boolean(std::string name, std::string help, Field field) {
  GeometrySetting s = row(std::move(name), std::move(help), "bool", 0, 0, {"true", "false"});
  s.get = [field](const GeometryOptions& o) -> std::string {
    return field(o) ? "true" : "false";
  };
  s.put = [field](GeometryOptions& o, const std::string& text) { field(o) = bool_from_text(text).value_or(false); };
  return s;
}

std::vector<GeometrySetting> make_settings() {
  std::vector<GeometrySetting> t;
  GeometrySetting align = row("align-depth",
                        "Scale each context view's predicted depth to the scene's own 3D points: depth-maps (a "
                        "synthetic scene's depth/), photos (those, else points triangulated from the context views' "
                        "photos and their neighbours with the scene's cameras), any (depth maps, else COLMAP's sparse "
                        "points, else the photos'), none (the network's depth as it is, the paper's; the measured "
                        "surface and the region surface need it). One-mask propagation reads photos as depth-maps "
                        "(the statue's masks lost precision with the photos' points)",
                        "choice", 0, 0, {"none", "depth-maps", "photos", "any"}, "none");
  align.get = [](const GeometryOptions& o) { return std::string(depth_points_name(o.align_depth)); };
  align.put = [](GeometryOptions& o, const std::string& text) { o.align_depth = parse_depth_points(text); };
  t.push_back(align);
  t.push_back(number("depth-detail", 0, 64,
                     "With --align-depth: how closely each view's depth follows the points beyond one scale per "
                     "view, as the width of its local correction in point spacings (the network often draws a "
                     "table at the floor's depth); 0 = one scale per view",
                     [](auto& o) -> auto& { return o.depth_detail.detail; }));
  t.push_back(number("measured-surface", 0, 1,
                     "Where a context view has its own depth map (<scene>/depth/<view>.npy: a depth camera's, a "
                     "synthetic scene's) or, without one, a depth its context photos measure (--stereo-depth), put "
                     "its Gaussians outside its mask on that depth as flat splats along the measured surface, at "
                     "least this opaque, and inside its mask what lies outside the reference's mask from the "
                     "reference's camera (the scene beside the object); 0 = none (the network's Gaussians, aligned "
                     "as --align-depth says)",
                     [](auto& o) -> auto& { return o.measured_surface.opacity; }, "0"));
  GeometrySetting flying = row("flying-pixels",
                         "A depth map's pixels that straddle an edge (a depth between the near and the far side, as "
                         "depth cameras and supersampled synthetic depth give), and the reference's region pixels "
                         "whose depth from the surface around them falls between two surfaces: far = moved to the "
                         "far side (a depth map's in its colour), so that they do not float as specks between the "
                         "two; keep = where they were measured",
                         "choice", 0, 0, {"far", "keep"});
  flying.get = [](const GeometryOptions& o) { return std::string(o.measured_surface.far_side ? "far" : "keep"); };
  flying.put = [](GeometryOptions& o, const std::string& text) {
    o.measured_surface.far_side = o.region_surface.far_side = text == "far";
  };
  t.push_back(flying);
  t.push_back(boolean("stereo-depth",
                      "Where no context view has a depth map, measure each one's depth from the context photos "
                      "themselves (a plane sweep between them about the network's aligned depth) and use it as the "
                      "measured surface where the photos are textured and agree (false: the network's Gaussians "
                      "there)",
                      [](auto& o) -> auto& { return o.measured_surface.from_photos; }));
  t.push_back(integer("stereo-planes", 3, 1024, "Depths the stereo sweep tries per pixel",
                      [](auto& o) -> auto& { return o.measured_surface.stereo.planes; }));
  t.push_back(number("stereo-spread", 1.01, 100, "The stereo sweep tries depths from the network's / N to its x N",
                     [](auto& o) -> auto& { return o.measured_surface.stereo.spread; }));
  t.push_back(integer("stereo-rows", 16, 4096, "The stereo sweep matches the pictures at about this many rows",
                      [](auto& o) -> auto& { return o.measured_surface.stereo.rows; }));
  t.push_back(number("stereo-min-ncc", -1, 1,
                     "A stereo depth whose best match correlates less (normalised cross-correlation) is unknown",
                     [](auto& o) -> auto& { return o.measured_surface.stereo.min_ncc; }));
  t.push_back(number("stereo-consistency", 0, 10,
                     "Another view's stereo depth must agree within this relative difference",
                     [](auto& o) -> auto& { return o.measured_surface.stereo.consistency; }));
  t.push_back(number("fade-floaters", 0, 1,
                     "Gaussians on a depth edge of their view (a blend of the near and the far surface) that lie in "
                     "front of another context view's depth there keep this fraction of their opacity, so that "
                     "they do not smear across other views; 1 = none faded (the paper's)",
                     [](auto& o) -> auto& { return o.floaters.fade; }, "1"));
  t.push_back(number("frame-margin", 0, 1,
                     "Continue each context view's Gaussians past the edges of its picture by this fraction of its "
                     "height (its border pixels repeated outward along their rays), so that views a little beside "
                     "the context cameras show the scene's edge instead of the background; 0 = none (the paper's)",
                     [](auto& o) -> auto& { return o.frame_margin.fraction; }, "0"));
  t.push_back(number("frame-margin-outer", 0, 1,
                     "Past --frame-margin, continue the margin out to this fraction of the height more sparsely: "
                     "one Gaussian per --frame-margin-stride pixels square, as wide as that square (no more than "
                     "--frame-margin: none)",
                     [](auto& o) -> auto& { return o.frame_margin.outer_fraction; }));
  t.push_back(integer("frame-margin-stride", 1, 16, "The outer frame margin's pixels per Gaussian along each side",
                      [](auto& o) -> auto& { return o.frame_margin.outer_stride; }));
  t.push_back(boolean("frame-margin-drop-seen",
                      "Drop the frame margin's Gaussians that another context view sees through (they lie in front "
                      "of the depth it saw there), so that a repeated border does not stand in front of what the "
                      "other views saw (false: keep the whole margin)",
                      [](auto& o) -> auto& { return o.frame_margin.drop_seen_through; }));
  t.push_back(number("behind-edges", 0, 1,
                     "Continue the far side of each context view's depth edges under the near side by this fraction "
                     "of its height (those another context view sees through dropped), so that a camera beside it "
                     "sees the ground behind an object's edge instead of the background; twice as far where the "
                     "depth is the views' depth maps; 0 = none (the paper's)",
                     [](auto& o) -> auto& { return o.behind_edges.fraction; }, "0"));
  t.push_back(number("behind-edges-jump", 0.001, 10,
                     "A depth edge for --behind-edges: the far side more than this fraction farther than its "
                     "neighbour",
                     [](auto& o) -> auto& { return o.behind_edges.jump; }));
  t.push_back(number("region-surface", 0, 1,
                     "With --measured-surface: put the reference's region on the measured depth around it (each "
                     "pixel on the surrounding surface its colour resembles: the hedge's green on the hedge, the "
                     "bench's grey on the bench) as flat splats at least this opaque, in the reference's colours; "
                     "0 = none (the network's depth there); off for --mode insert",
                     [](auto& o) -> auto& { return o.region_surface.opacity; }, "0",
                     /*off_for_insertion=*/true));
  t.push_back(number("region-surface-colour", 0.001, 2,
                     "With --region-surface: how far (RGB distance, 0-1) a surrounding pixel's colour may be from a "
                     "region pixel's and still lend it its depth",
                     [](auto& o) -> auto& { return o.region_surface.colour; }));
  t.push_back(number("region-cover", 0, 1,
                     "Cover the reference's region with flat splats of this opacity on its depth, beside the "
                     "network's Gaussians, so that views from elsewhere show no background between them where the "
                     "object stood; 0 = none (the paper's)",
                     [](auto& o) -> auto& { return o.region_cover.opacity; }, "0"));
  return t;
}

std::string python_name(std::string name) {
  std::replace(name.begin(), name.end(), '-', '_');
  return name;
}

}  // namespace

const std::vector<GeometrySetting>& geometry_settings() {
  static const std::vector<GeometrySetting> table = make_settings();
  return table;
}

const GeometrySetting& geometry_setting(const std::string& name) {
  std::string names;
  for (const GeometrySetting& s : geometry_settings()) {
    if (s.name == name || python_name(s.name) == name) return s;
    names += (names.empty() ? "" : ", ") + s.name;
  }
  fail("geometry: no setting '{}' (the settings: {})", name, names);
}

std::string check_geometry_setting(const GeometrySetting& s, const std::string& text) {
  if (s.kind == "choice" || s.kind == "bool") {
    if (s.kind == "bool" ? bool_from_text(text).has_value()
                         : std::find(s.choices.begin(), s.choices.end(), text) != s.choices.end())
      return "";
    std::string list;
    for (size_t i = 0; i < s.choices.size(); ++i)
      list += (i == 0 ? "" : i + 1 == s.choices.size() ? " or " : ", ") + s.choices[i];
    return list;
  }
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  const bool whole = s.kind == "integer";
  const bool parsed = !text.empty() && end && *end == '\0' && std::isfinite(v) && (!whole || v == std::floor(v));
  if (!parsed || v < s.min || v > s.max)
    return fmt::format("{} from {} to {}", whole ? "a whole number" : "a number", number_text(s.min), number_text(s.max));
  return "";
}

void set_geometry_setting(GeometryOptions& options, const std::string& name, const std::string& text) {
  const GeometrySetting& s = geometry_setting(name);
  const std::string takes = check_geometry_setting(s, text);
  if (!takes.empty()) fail("--{} '{}': {}", s.name, text, takes);
  s.put(options, text);
}

}  // namespace ii
