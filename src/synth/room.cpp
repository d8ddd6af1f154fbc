// The background of a synthetic scene: a closed room (floor, four walls, ceiling) with wall
// decorations, a rug, furniture along the walls and the object's support in the middle.
#include <algorithm>
#include <cmath>
#include <limits>

#include "synth/scene_parts.h"

namespace ii::synth {

namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

Material material(Pattern pattern, const Rgb& base, const Rgb& accent, double scale, double variation, SynthRng& rng) {
  Material m;
  m.pattern = pattern;
  m.base = base;
  m.accent = accent;
  m.scale = scale;
  m.variation = variation;
  m.seed = static_cast<uint32_t>(rng.bits());
  return m;
}

Rgb wood_colour(SynthRng& rng) { return hsv(rng.uniform(0.05, 0.11), rng.uniform(0.35, 0.7), rng.uniform(0.3, 0.8)); }

Material wood(SynthRng& rng, double plank = 0.12) {
  const Rgb base = wood_colour(rng);
  return material(Pattern::wood, base, base * 0.6f, plank, 0.06, rng);
}

Material painted(SynthRng& rng) {
  const double v = rng.uniform(0.25, 0.95);
  const Rgb base = hsv(rng.uniform(), rng.uniform(0.05, 0.6), v);
  const Pattern p = rng.chance(0.3) ? Pattern::panels : Pattern::solid;
  return material(p, base, base * 0.55f, rng.uniform(0.12, 0.3), 0.04, rng);
}

Material fabric(SynthRng& rng) {
  const Rgb base = hsv(rng.uniform(), rng.uniform(0.15, 0.65), rng.uniform(0.25, 0.85));
  const Rgb accent = rng.chance(0.3) ? hsv(rng.uniform(), 0.5, 0.7) : Rgb(base * 0.7f);
  const Pattern p = rng.chance(0.25) ? Pattern::stripes : (rng.chance(0.2) ? Pattern::checker : Pattern::fabric);
  return material(p, base, accent, p == Pattern::fabric ? 0.02 : rng.uniform(0.05, 0.15), 0.05, rng);
}

Material floor_material(SynthRng& rng, std::string& kind) {
  switch (rng.weighted({0.35, 0.18, 0.1, 0.1, 0.15, 0.12})) {
    case 0:
      kind = "wood";
      return wood(rng, rng.uniform(0.1, 0.22));
    case 1: {
      kind = "tiles";
      const Rgb base = hsv(rng.uniform(), rng.uniform(0.0, 0.3), rng.uniform(0.45, 0.9));
      return material(Pattern::tiles, base, base * 0.6f, rng.uniform(0.25, 0.6), 0.05, rng);
    }
    case 2: {
      kind = "checker";
      const Rgb a = hsv(rng.uniform(), rng.uniform(0, 0.25), rng.uniform(0.75, 0.95));
      const Rgb b = hsv(rng.uniform(), rng.uniform(0, 0.5), rng.uniform(0.1, 0.4));
      return material(Pattern::checker, a, b, rng.uniform(0.25, 0.5), 0.04, rng);
    }
    case 3: {
      kind = "marble";
      const Rgb base = hsv(rng.uniform(), rng.uniform(0, 0.12), rng.uniform(0.7, 0.95));
      return material(Pattern::marble, base, base * 0.55f, rng.uniform(0.3, 0.8), 0.03, rng);
    }
    case 4: {
      kind = "carpet";
      const Rgb base = hsv(rng.uniform(), rng.uniform(0.1, 0.5), rng.uniform(0.3, 0.75));
      return material(Pattern::noise, base, base * 0.75f, rng.uniform(0.1, 0.3), 0.12, rng);
    }
    default: {
      kind = "concrete";
      const Rgb base = hsv(rng.uniform(), rng.uniform(0, 0.08), rng.uniform(0.45, 0.75));
      return material(Pattern::noise, base, base * 0.85f, rng.uniform(0.2, 0.6), 0.15, rng);
    }
  }
}

Material wall_material(SynthRng& rng, std::string& kind) {
  const Rgb paint = hsv(rng.uniform(), rng.uniform(0.03, 0.35), rng.uniform(0.6, 0.93));
  switch (rng.weighted({0.45, 0.15, 0.15, 0.1, 0.15})) {
    case 0:
      kind = "paint";
      return material(Pattern::solid, paint, paint, 1.0, 0.05, rng);
    case 1:
      kind = "stripes";
      return material(Pattern::stripes, paint, hsv(rng.uniform(), rng.uniform(0.1, 0.4), rng.uniform(0.5, 0.9)),
                      rng.uniform(0.08, 0.3), 0.04, rng);
    case 2: {
      kind = "bricks";
      const Rgb brick =
          rng.chance(0.6) ? hsv(rng.uniform(0.0, 0.06), rng.uniform(0.4, 0.7), rng.uniform(0.4, 0.7)) : paint;
      return material(Pattern::bricks, brick, hsv(0.1, 0.1, rng.uniform(0.6, 0.85)), rng.uniform(0.18, 0.28), 0.08,
                      rng);
    }
    case 3:
      kind = "dots";
      return material(Pattern::dots, paint, hsv(rng.uniform(), rng.uniform(0.2, 0.6), rng.uniform(0.3, 0.8)),
                      rng.uniform(0.08, 0.2), 0.03, rng);
    default:
      kind = "plaster";
      return material(Pattern::noise, paint, paint * 0.85f, rng.uniform(0.1, 0.4), 0.08, rng);
  }
}

// Samples spread over a rectangle (3 x 3), for the detail map.
std::vector<Vector3d> rect_samples(const Vector3d& origin, const Vector3d& u, const Vector3d& v, double lu, double lv) {
  std::vector<Vector3d> s;
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) s.push_back(origin + u * (lu * i / 2.0) + v * (lv * j / 2.0));
  return s;
}

// A rectangle covered as densely as the cameras need: split in four while its parts need
// very different densities (near and far, seen and unseen), down to ~0.12 m; texture
// coordinates continue across tiles.
void adaptive_rect(SurfelSampler& sampler, const DetailMap& detail, const Vector3d& origin, const Vector3d& u,
                   const Vector3d& v, double lu, double lv, const Material& m, const Vector2d& uv_offset) {
  double finest = std::numeric_limits<double>::infinity(), coarsest = 0;
  const double reach = 0.25 * std::hypot(lu, lv);  // each of the 3 x 3 samples stands for its neighbourhood
  for (const Vector3d& p : rect_samples(origin, u, v, lu, lv)) {
    const double s = detail.spacing_sphere(p, reach);
    finest = std::min(finest, s);
    coarsest = std::max(coarsest, s);
  }
  const double size = std::max(lu, lv);
  if (size > 0.12 && size > 4 * finest && coarsest > 1.5 * finest) {
    const int su = lu > size / 2 ? 2 : 1, sv = lv > size / 2 ? 2 : 1;  // long strips split along their length
    const double hu = lu / su, hv = lv / sv;
    for (int j = 0; j < sv; ++j)
      for (int i = 0; i < su; ++i)
        adaptive_rect(sampler, detail, origin + u * (i * hu) + v * (j * hv), u, v, hu, hv, m,
                      uv_offset + Vector2d(i * hu, j * hv));
    return;
  }
  sampler.rect(origin, u, v, lu, lv, m, finest, uv_offset);
}

// A large rectangle in tiles of at most `tile` metres, each refined as needed.
void tiled_rect(SurfelSampler& sampler, const DetailMap& detail, const Vector3d& origin, const Vector3d& u,
                const Vector3d& v, double lu, double lv, const Material& m, double tile = 1.0) {
  const int nu = std::max(1, static_cast<int>(std::ceil(lu / tile)));
  const int nv = std::max(1, static_cast<int>(std::ceil(lv / tile)));
  const double tu = lu / nu, tv = lv / nv;
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i)
      adaptive_rect(sampler, detail, origin + u * (i * tu) + v * (j * tv), u, v, tu, tv, m, Vector2d(i * tu, j * tv));
}

// A piece's local frame: origin on the floor, local x along its wall, local z towards the room.
struct Frame {
  Vector3d origin;
  double yaw = 0;
  Vector3d world(const Vector3d& local) const {
    return origin + Eigen::AngleAxisd(yaw, Vector3d::UnitY()).toRotationMatrix() * local;
  }
};

struct Builder {
  SurfelSampler& sampler;
  const DetailMap& detail;
  SynthRng& rng;

  void box(const Frame& f, const Vector3d& local_centre, const Vector3d& half, const Material& m) {
    const Vector3d c = f.world(local_centre);
    sampler.box(c, half, f.yaw, m, detail.spacing_sphere(c, half.norm()));
  }
  void lathe(const Vector3d& base, double height, const std::function<double(double)>& radius, const Material& m,
             double max_radius, bool bottom, bool top) {
    const double s = detail.spacing_sphere(base + Vector3d(0, height / 2, 0), std::hypot(height / 2, max_radius));
    sampler.lathe(base, height, radius, m, s, bottom, top);
  }
  void ellipsoid(const Vector3d& c, const Vector3d& radii, const Eigen::Matrix3d& rot, const Material& m) {
    sampler.ellipsoid(c, radii, rot, m, detail.spacing_sphere(c, radii.maxCoeff()));
  }
};

struct Piece {
  std::string kind;
  double half_w = 0.3, half_d = 0.2, height = 0.8;
  // World axis-aligned footprint once placed (pieces stand square to their wall).
  Vector2d lo, hi;
  Frame frame;
  int wall = 0;
};

void build_cabinet(Builder& b, const Piece& p) {
  const Material body = b.rng.chance(0.5) ? wood(b.rng) : painted(b.rng);
  const Material top = b.rng.chance(0.5) ? wood(b.rng) : body;
  const double top_h = 0.025;
  b.box(p.frame, {0, (p.height - top_h) / 2, 0}, {p.half_w, (p.height - top_h) / 2, p.half_d}, body);
  b.box(p.frame, {0, p.height - top_h / 2, 0.01}, {p.half_w + 0.015, top_h / 2, p.half_d + 0.015}, top);
  Material knob = material(Pattern::solid, hsv(0.1, 0.2, b.rng.uniform(0.2, 0.9)), Rgb::Zero(), 1, 0.02, b.rng);
  const int knobs = b.rng.integer(1, 3);
  for (int k = 0; k < knobs; ++k) {
    const double y = p.height * (k + 0.5) / knobs;
    b.ellipsoid(p.frame.world({0, y, p.half_d + 0.012}), Vector3d::Constant(0.015), Eigen::Matrix3d::Identity(), knob);
  }
}

void build_bookshelf(Builder& b, const Piece& p) {
  const Material board = b.rng.chance(0.6) ? wood(b.rng) : painted(b.rng);
  const double t = 0.012;
  b.box(p.frame, {0, p.height / 2, -p.half_d + t}, {p.half_w, p.height / 2, t}, board);  // back
  b.box(p.frame, {-p.half_w + t, p.height / 2, 0}, {t, p.height / 2, p.half_d}, board);
  b.box(p.frame, {p.half_w - t, p.height / 2, 0}, {t, p.height / 2, p.half_d}, board);
  const int shelves = std::max(2, static_cast<int>(p.height / b.rng.uniform(0.3, 0.42)));
  const double gap = p.height / shelves;
  for (int s = 0; s <= shelves; ++s) {
    const double y = std::min(p.height - t, std::max(t, s * gap));
    b.box(p.frame, {0, y, 0}, {p.half_w - 2 * t, t, p.half_d}, board);
    if (s == shelves) break;
    // Books along the shelf, with gaps.
    double x = -p.half_w + 3 * t;
    while (x < p.half_w - 3 * t - 0.02) {
      const double w = b.rng.uniform(0.015, 0.045);
      if (x + 2 * w > p.half_w - 3 * t) break;
      if (b.rng.chance(0.12)) {
        x += b.rng.uniform(0.03, 0.12);
        continue;
      }
      const double h = gap * b.rng.uniform(0.55, 0.85);
      const double d = p.half_d * b.rng.uniform(0.7, 0.9);
      const Rgb c = hsv(b.rng.uniform(), b.rng.uniform(0.3, 0.9), b.rng.uniform(0.2, 0.9));
      const Material cover =
          material(b.rng.chance(0.2) ? Pattern::stripes : Pattern::solid, c, c * 0.5f, h * 0.3, 0.03, b.rng);
      b.box(p.frame, {x + w, y + t + h / 2, -p.half_d + 2 * t + d}, {w, h / 2, d}, cover);
      x += 2 * w + 0.002;
    }
  }
}

void build_table(Builder& b, const Piece& p) {
  const Material top = b.rng.chance(0.6) ? wood(b.rng) : painted(b.rng);
  const Material legs = b.rng.chance(0.5) ? top : painted(b.rng);
  const double th = 0.02, leg = b.rng.uniform(0.015, 0.03);
  b.box(p.frame, {0, p.height - th, 0}, {p.half_w, th, p.half_d}, top);
  for (int sx : {-1, 1})
    for (int sz : {-1, 1})
      b.box(p.frame, {sx * (p.half_w - 2 * leg), (p.height - 2 * th) / 2, sz * (p.half_d - 2 * leg)},
            {leg, (p.height - 2 * th) / 2, leg}, legs);
  // Something on the table, sometimes.
  if (b.rng.chance(0.6)) {
    const Rgb c = hsv(b.rng.uniform(), b.rng.uniform(0.3, 0.8), b.rng.uniform(0.4, 0.9));
    const Material m = material(b.rng.chance(0.5) ? Pattern::solid : Pattern::stripes, c, c * 0.6f, 0.04, 0.03, b.rng);
    const Vector3d at =
        p.frame.world({b.rng.uniform(-0.5, 0.5) * p.half_w, p.height, b.rng.uniform(-0.4, 0.4) * p.half_d});
    const double r = b.rng.uniform(0.04, 0.08), h = b.rng.uniform(0.08, 0.25);
    if (b.rng.chance(0.5))
      b.lathe(
          at, h, [r](double t) { return r * (0.7 + 0.5 * std::sin(M_PI * t)); }, m, 1.2 * r, false, true);
    else
      b.ellipsoid(at + Vector3d(0, r, 0), Vector3d::Constant(r), Eigen::Matrix3d::Identity(), m);
  }
}

void build_chair(Builder& b, const Piece& p) {
  const Material m = b.rng.chance(0.5) ? wood(b.rng) : painted(b.rng);
  const Material seat = b.rng.chance(0.5) ? fabric(b.rng) : m;
  const double seat_h = 0.45, leg = 0.018, th = 0.025;
  b.box(p.frame, {0, seat_h, 0}, {p.half_w, th, p.half_d}, seat);
  for (int sx : {-1, 1})
    for (int sz : {-1, 1})
      b.box(p.frame, {sx * (p.half_w - leg), (seat_h - th) / 2, sz * (p.half_d - leg)}, {leg, (seat_h - th) / 2, leg},
            m);
  b.box(p.frame, {0, (seat_h + p.height) / 2, -p.half_d + leg}, {p.half_w, (p.height - seat_h) / 2, leg}, m);
}

void build_sofa(Builder& b, const Piece& p) {
  const Material cloth = fabric(b.rng);
  const double seat_h = 0.42, arm = 0.1, back = 0.16;
  b.box(p.frame, {0, seat_h / 2, back / 2}, {p.half_w - arm, seat_h / 2, p.half_d - back / 2}, cloth);
  b.box(p.frame, {0, p.height / 2, -p.half_d + back / 2}, {p.half_w, p.height / 2, back / 2}, cloth);
  for (int s : {-1, 1})
    b.box(p.frame, {s * (p.half_w - arm / 2), 0.31, back / 2}, {arm / 2, 0.31, p.half_d - back / 2}, cloth);
  // Cushions.
  const Material pillow = b.rng.chance(0.5) ? fabric(b.rng) : cloth;
  for (int s : {-1, 1})
    if (b.rng.chance(0.7)) {
      const Eigen::Matrix3d tilt = Eigen::AngleAxisd(p.frame.yaw, Vector3d::UnitY()).toRotationMatrix() *
                                   Eigen::AngleAxisd(-0.3, Vector3d::UnitX()).toRotationMatrix();
      b.ellipsoid(p.frame.world({s * (p.half_w - arm - 0.2), seat_h + 0.17, -p.half_d + back + 0.06}),
                  {0.17, 0.15, 0.05}, tilt, pillow);
    }
}

void build_plant(Builder& b, const Piece& p) {
  const Rgb pot_colour = hsv(b.rng.uniform(), b.rng.uniform(0.1, 0.7), b.rng.uniform(0.3, 0.9));
  const Material pot =
      material(b.rng.chance(0.3) ? Pattern::stripes : Pattern::solid, pot_colour, pot_colour * 0.7f, 0.05, 0.04, b.rng);
  const double r = p.half_w * 0.75, h = b.rng.uniform(0.2, 0.4);
  const Vector3d base = p.frame.world({0, 0, 0});
  b.lathe(
      base, h, [r](double t) { return r * (0.75 + 0.25 * t); }, pot, r, false, true);
  const Rgb leaf = hsv(b.rng.uniform(0.22, 0.4), b.rng.uniform(0.4, 0.8), b.rng.uniform(0.2, 0.55));
  const Material foliage = material(Pattern::noise, leaf, leaf * 0.55f, 0.05, 0.1, b.rng);
  const int blobs = b.rng.integer(3, 6);
  const double top = p.height - h;
  for (int k = 0; k < blobs; ++k) {
    const double a = b.rng.uniform(0, 2 * M_PI), d = b.rng.uniform(0, 0.5) * p.half_w;
    const double rr = p.half_w * b.rng.uniform(0.45, 0.8);
    const double y = h + top * b.rng.uniform(0.3, 0.75);
    const Eigen::Matrix3d rot = Eigen::AngleAxisd(b.rng.uniform(0, M_PI), Vector3d::UnitY()).toRotationMatrix();
    b.ellipsoid(base + Vector3d(d * std::cos(a), y, d * std::sin(a)), {rr, top * 0.35, rr * 0.8}, rot, foliage);
  }
}

void build_lamp(Builder& b, const Piece& p) {
  const Material metal = material(Pattern::solid, hsv(0.1, 0.1, b.rng.uniform(0.1, 0.8)), Rgb::Zero(), 1, 0.02, b.rng);
  Material shade = material(b.rng.chance(0.3) ? Pattern::fabric : Pattern::solid,
                            hsv(b.rng.uniform(0.05, 0.15), b.rng.uniform(0.05, 0.4), b.rng.uniform(0.8, 1.0)),
                            Rgb(0.8f, 0.75f, 0.6f), 0.02, 0.02, b.rng);
  shade.lit = false;  // it glows
  const Vector3d base = p.frame.world({0, 0, 0});
  b.lathe(
      base, 0.03, [&](double) { return p.half_w * 0.8; }, metal, p.half_w, false, true);
  const double pole_h = p.height - 0.3;
  b.lathe(
      base, pole_h, [](double) { return 0.012; }, metal, 0.02, false, false);
  const double r0 = p.half_w, r1 = p.half_w * b.rng.uniform(0.5, 0.8);
  b.lathe(
      base + Vector3d(0, pole_h, 0), 0.3, [=](double t) { return r0 + (r1 - r0) * t; }, shade, r0, false, true);
}

void build_boxes(Builder& b, const Piece& p) {
  const Rgb card = hsv(b.rng.uniform(0.07, 0.1), b.rng.uniform(0.3, 0.55), b.rng.uniform(0.45, 0.75));
  double y = 0;
  const int n = b.rng.integer(1, 3);
  for (int k = 0; k < n && y < p.height - 0.1; ++k) {
    const double hw = p.half_w * b.rng.uniform(0.6, 1.0), hd = p.half_d * b.rng.uniform(0.6, 1.0);
    const double hh = std::min(b.rng.uniform(0.1, 0.25), (p.height - y) / 2);
    const Material m =
        material(Pattern::noise, card * static_cast<float>(b.rng.uniform(0.85, 1.1)), card * 0.8f, 0.1, 0.05, b.rng);
    const Vector3d c = p.frame.world({b.rng.uniform(-0.05, 0.05), y + hh, b.rng.uniform(-0.05, 0.05)});
    b.sampler.box(c, {hw, hh, hd}, p.frame.yaw + b.rng.uniform(-0.25, 0.25), m,
                  b.detail.spacing_sphere(c, hw + hh + hd));
    y += 2 * hh;
  }
}

void build_ball(Builder& b, const Piece& p) {
  const Rgb c = hsv(b.rng.uniform(), b.rng.uniform(0.4, 0.9), b.rng.uniform(0.5, 0.95));
  const Material m = material(b.rng.chance(0.5) ? Pattern::stripes : Pattern::solid, c, hsv(b.rng.uniform(), 0.2, 0.95),
                              p.half_w * 0.5, 0.03, b.rng);
  b.ellipsoid(p.frame.world({0, p.half_w, 0}), Vector3d::Constant(p.half_w),
              Eigen::AngleAxisd(b.rng.uniform(0, M_PI), Vector3d::UnitX()).toRotationMatrix(), m);
}

// Piece kinds, how often each is drawn, and their size ranges. A footprint without a depth
// range is square; a height range of {0, 0} makes the piece as tall as it is wide (a ball).
struct PieceKind {
  const char* kind;
  double weight;
  double half_w[2], half_d[2], height[2];
};
constexpr PieceKind kPieceKinds[] = {
    {"cabinet", 0.18, {0.25, 0.55}, {0.18, 0.28}, {0.5, 1.1}},
    {"bookshelf", 0.14, {0.25, 0.5}, {0.13, 0.2}, {1.1, 2.0}},
    {"table", 0.14, {0.3, 0.6}, {0.25, 0.4}, {0.65, 0.8}},
    {"chair", 0.1, {0.19, 0.24}, {0.19, 0.24}, {0.8, 1.0}},
    {"sofa", 0.1, {0.7, 1.1}, {0.38, 0.46}, {0.75, 0.9}},
    {"plant", 0.12, {0.16, 0.32}, {0, 0}, {0.6, 1.4}},
    {"lamp", 0.08, {0.15, 0.22}, {0, 0}, {1.3, 1.7}},
    {"boxes", 0.08, {0.15, 0.3}, {0.15, 0.3}, {0.3, 0.8}},
    {"ball", 0.06, {0.1, 0.25}, {0, 0}, {0, 0}},
};

// Piece dimensions by kind (the draws in the order width, depth, height).
Piece draw_piece(SynthRng& rng) {
  std::vector<double> weights;
  for (const PieceKind& k : kPieceKinds) weights.push_back(k.weight);
  const PieceKind& k = kPieceKinds[rng.weighted(weights)];
  Piece p;
  p.kind = k.kind;
  p.half_w = rng.uniform(k.half_w[0], k.half_w[1]);
  p.half_d = k.half_d[1] > 0 ? rng.uniform(k.half_d[0], k.half_d[1]) : p.half_w;
  p.height = k.height[1] > 0 ? rng.uniform(k.height[0], k.height[1]) : 2 * p.half_w;
  return p;
}

// Distance in the floor plane from (0, 0) to an axis-aligned rectangle.
double distance_to_rect(const Vector2d& point, const Vector2d& lo, const Vector2d& hi) {
  const double dx = std::max({lo.x() - point.x(), 0.0, point.x() - hi.x()});
  const double dz = std::max({lo.y() - point.y(), 0.0, point.y() - hi.y()});
  return std::hypot(dx, dz);
}

// Places a piece against a random wall; false when it does not fit.
bool place_piece(Piece& p, const RoomPlan& plan, const std::vector<Piece>& placed, SynthRng& rng) {
  const Vector2d object(plan.object_base.x(), plan.object_base.z());
  for (int attempt = 0; attempt < 30; ++attempt) {
    p.wall = rng.integer(0, 3);
    const bool along_x = p.wall >= 2;  // walls at z = min / max run along x
    const double lo = along_x ? plan.room_min.x() : plan.room_min.z();
    const double hi = along_x ? plan.room_max.x() : plan.room_max.z();
    if (hi - lo < 2 * p.half_w + 0.1) continue;
    const double s = rng.uniform(lo + p.half_w + 0.03, hi - p.half_w - 0.03);
    const double gap = rng.uniform(0.02, 0.08);
    Vector3d origin;
    switch (p.wall) {
      case 0:
        origin = {plan.room_min.x() + gap + p.half_d, 0, s};
        p.frame.yaw = M_PI / 2;
        break;
      case 1:
        origin = {plan.room_max.x() - gap - p.half_d, 0, s};
        p.frame.yaw = -M_PI / 2;
        break;
      case 2:
        origin = {s, 0, plan.room_min.z() + gap + p.half_d};
        p.frame.yaw = 0;
        break;
      default:
        origin = {s, 0, plan.room_max.z() - gap - p.half_d};
        p.frame.yaw = M_PI;
        break;
    }
    p.frame.origin = origin;
    const Vector2d half = along_x ? Vector2d(p.half_w, p.half_d) : Vector2d(p.half_d, p.half_w);
    p.lo = Vector2d(origin.x(), origin.z()) - half;
    p.hi = Vector2d(origin.x(), origin.z()) + half;
    if (distance_to_rect(object, p.lo, p.hi) < plan.keep_out) continue;
    bool overlaps = false;
    for (const Piece& q : placed)
      overlaps |= p.lo.x() < q.hi.x() + 0.05 && q.lo.x() < p.hi.x() + 0.05 && p.lo.y() < q.hi.y() + 0.05 &&
                  q.lo.y() < p.hi.y() + 0.05;
    if (!overlaps) return true;
  }
  return false;
}

void build_piece(Builder& b, const Piece& p) {
  if (p.kind == "cabinet")
    build_cabinet(b, p);
  else if (p.kind == "bookshelf")
    build_bookshelf(b, p);
  else if (p.kind == "table")
    build_table(b, p);
  else if (p.kind == "chair")
    build_chair(b, p);
  else if (p.kind == "sofa")
    build_sofa(b, p);
  else if (p.kind == "plant")
    build_plant(b, p);
  else if (p.kind == "lamp")
    build_lamp(b, p);
  else if (p.kind == "boxes")
    build_boxes(b, p);
  else
    build_ball(b, p);
}

// Walls as (corner, u along the wall, length), v = +y, normal u x y into the room.
struct Wall {
  Vector3d corner, u;
  double length;
};

std::array<Wall, 4> walls_of(const RoomPlan& plan) {
  const Vector3d& a = plan.room_min;
  const Vector3d& b = plan.room_max;
  const double wx = b.x() - a.x(), wz = b.z() - a.z();
  return {Wall{{a.x(), 0, b.z()}, -Vector3d::UnitZ(), wz},   // x = min
          Wall{{b.x(), 0, a.z()}, Vector3d::UnitZ(), wz},    // x = max
          Wall{{a.x(), 0, a.z()}, Vector3d::UnitX(), wx},    // z = min
          Wall{{b.x(), 0, b.z()}, -Vector3d::UnitX(), wx}};  // z = max
}

// Paintings, windows and doors on a wall, kept clear of the furniture standing against it.
void decorate_wall(Builder& b, const Wall& wall, int index, const std::vector<Piece>& pieces, double room_height,
                   nlohmann::json& out) {
  const Vector3d normal = wall.u.cross(Vector3d::UnitY());
  const int count = b.rng.integer(0, 2);
  std::vector<std::pair<double, double>> used;  // intervals along the wall
  for (int k = 0; k < count; ++k) {
    const int kind = b.rng.weighted({0.55, 0.3, 0.15});  // painting, window, door
    const double w = kind == 0   ? b.rng.uniform(0.3, 0.9)
                     : kind == 1 ? b.rng.uniform(0.6, 1.3)
                                 : b.rng.uniform(0.75, 0.9);
    const double h = kind == 0   ? b.rng.uniform(0.3, 0.7)
                     : kind == 1 ? b.rng.uniform(0.8, 1.3)
                                 : std::min(2.05, room_height - 0.2);
    if (wall.length < w + 0.3) continue;
    const double s = b.rng.uniform(0.15, wall.length - w - 0.15);
    bool clash = false;
    for (const auto& [a0, a1] : used) clash |= s < a1 + 0.1 && a0 < s + w + 0.1;
    // Furniture in front: a door needs the floor free, a painting or window must hang above.
    double highest = 0;
    for (const Piece& p : pieces) {
      if (p.wall != index) continue;
      const Vector3d c0 = wall.corner + wall.u * s, c1 = wall.corner + wall.u * (s + w);
      const Vector2d lo(std::min(c0.x(), c1.x()) - 0.02, std::min(c0.z(), c1.z()) - 0.02);
      const Vector2d hi(std::max(c0.x(), c1.x()) + 0.02, std::max(c0.z(), c1.z()) + 0.02);
      const bool along = p.lo.x() < hi.x() && lo.x() < p.hi.x() && p.lo.y() < hi.y() + 1.0 && lo.y() - 1.0 < p.hi.y();
      if (along) highest = std::max(highest, p.height);
    }
    if (kind == 2 && highest > 0) clash = true;
    double bottom = kind == 2 ? 0.0 : std::max(highest + 0.1, b.rng.uniform(0.9, 1.4) - (kind == 1 ? 0.2 : 0.0));
    if (bottom + h > room_height - 0.1) clash = true;
    if (clash) continue;
    used.push_back({s, s + w});
    const Vector3d corner = wall.corner + wall.u * s + Vector3d(0, bottom, 0) + normal * 0.012;
    const Material frame = b.rng.chance(0.5) ? wood(b.rng) : painted(b.rng);
    const double border = kind == 0 ? b.rng.uniform(0.02, 0.05) : 0.05;
    const double spacing = b.detail.spacing(rect_samples(corner, wall.u, Vector3d::UnitY(), w, h));
    b.sampler.rect(corner, wall.u, Vector3d::UnitY(), w, h, frame, spacing);
    const Vector3d inner = corner + wall.u * border + Vector3d(0, border, 0) + normal * 0.006;
    const double iw = w - 2 * border, ih = h - (kind == 2 ? border : 2 * border);
    Material face;
    std::string name;
    if (kind == 0) {
      name = "painting";
      face = material(Pattern::canvas, hsv(b.rng.uniform(), b.rng.uniform(0.3, 0.9), b.rng.uniform(0.3, 0.95)),
                      hsv(b.rng.uniform(), b.rng.uniform(0.3, 0.9), b.rng.uniform(0.3, 0.95)), b.rng.uniform(0.1, 0.3),
                      0.03, b.rng);
    } else if (kind == 1) {
      name = "window";
      face = material(Pattern::sky, hsv(b.rng.uniform(0.55, 0.62), b.rng.uniform(0.25, 0.6), b.rng.uniform(0.85, 1.0)),
                      hsv(0.58, 0.1, 1.0), ih, 0.0, b.rng);
      face.lit = false;
    } else {
      name = "door";
      face = b.rng.chance(0.5) ? wood(b.rng, 0.25) : painted(b.rng);
    }
    b.sampler.rect(inner, wall.u, Vector3d::UnitY(), iw, ih, face, spacing);
    if (kind == 1) {  // window bars
      const Vector3d front = normal * 0.004;
      b.sampler.rect(inner + wall.u * (iw / 2 - 0.02) + front, wall.u, Vector3d::UnitY(), 0.04, ih, frame, spacing);
      b.sampler.rect(inner + Vector3d(0, ih / 2 - 0.02, 0) + front, wall.u, Vector3d::UnitY(), iw, 0.04, frame,
                     spacing);
    }
    if (kind == 2) {
      const Material knob = material(Pattern::solid, hsv(0.12, 0.3, 0.8), Rgb::Zero(), 1, 0.02, b.rng);
      b.ellipsoid(inner + wall.u * (iw * 0.85) + Vector3d(0, 1.0, 0) + normal * 0.03, Vector3d::Constant(0.025),
                  Eigen::Matrix3d::Identity(), knob);
    }
    out.push_back({{"kind", name}, {"wall", index}, {"width", w}, {"height", h}});
  }
}

void build_support(Builder& b, const RoomPlan& plan, Lighting& lighting, nlohmann::json& out) {
  if (plan.support == 0) return;
  const Vector3d base(plan.object_base.x(), 0, plan.object_base.z());
  const double top = plan.object_base.y(), r = plan.support_size;
  const Material m = b.rng.chance(0.6) ? wood(b.rng) : (b.rng.chance(0.5) ? painted(b.rng) : [&] {
    const Rgb c = hsv(b.rng.uniform(), 0.05, b.rng.uniform(0.7, 0.95));
    return material(Pattern::marble, c, c * 0.5f, 0.3, 0.03, b.rng);
  }());
  std::string kind;
  if (plan.support == 1) {
    kind = "round table";
    b.lathe(
        base + Vector3d(0, top - 0.03, 0), 0.03, [r](double) { return r; }, m, r, true, true);
    const double pole = b.rng.uniform(0.03, 0.06);
    b.lathe(
        base, top - 0.03, [pole](double t) { return pole * (1.0 + 0.5 * (1 - t) * (1 - t)); }, m, pole * 1.5, false,
        false);
    b.lathe(
        base, 0.03, [r](double) { return r * 0.55; }, m, r, false, true);
    lighting.contacts.push_back({Vector2d(base.x(), base.z()), Vector2d(r * 0.55, r * 0.55), 0, 0.3});
  } else if (plan.support == 2) {
    kind = "square table";
    const double yaw = b.rng.uniform(0, M_PI / 2), th = 0.02, leg = 0.025;
    b.sampler.box(base + Vector3d(0, top - th, 0), {r, th, r}, yaw, m,
                  b.detail.spacing_sphere(base + Vector3d(0, top, 0), r * 1.5));
    const Frame f{base, yaw};
    for (int sx : {-1, 1})
      for (int sz : {-1, 1})
        b.box(f, {sx * (r - 2 * leg), (top - 2 * th) / 2, sz * (r - 2 * leg)}, {leg, (top - 2 * th) / 2, leg}, m);
    lighting.contacts.push_back({Vector2d(base.x(), base.z()), Vector2d(r, r), yaw, 0.25});
  } else {
    kind = "pedestal";
    const double yaw = b.rng.uniform(0, M_PI / 2);
    b.sampler.box(base + Vector3d(0, top / 2, 0), {r, top / 2, r}, yaw, m,
                  b.detail.spacing_sphere(base + Vector3d(0, top / 2, 0), std::hypot(r * 1.5, top / 2)));
    lighting.contacts.push_back({Vector2d(base.x(), base.z()), Vector2d(r, r), yaw, 0.45});
  }
  out = {{"kind", kind}, {"top", top}, {"half_size", r}};
}

}  // namespace

void build_room(const RoomPlan& plan, const DetailMap& detail, Lighting& lighting, SynthRng& rng, GaussianBuilder& out,
                nlohmann::json& description) {
  SurfelSampler sampler(out, lighting, rng);
  Builder b{sampler, detail, rng};
  const Vector3d& lo = plan.room_min;
  const Vector3d& hi = plan.room_max;
  const double height = hi.y() - lo.y();

  // Furniture is planned first: its contact shadows shade the floor.
  std::vector<Piece> pieces;
  const int wanted = rng.integer(3, 8);
  for (int k = 0; k < wanted; ++k) {
    Piece p = draw_piece(rng);
    if (place_piece(p, plan, pieces, rng)) pieces.push_back(p);
  }
  for (const Piece& p : pieces)
    lighting.contacts.push_back({(p.lo + p.hi) / 2, (p.hi - p.lo) / 2, 0, p.kind == "ball" ? 0.3 : 0.4});
  nlohmann::json counts;
  size_t before = out.size();
  auto count = [&](const char* part) {
    counts[part] = out.size() - before;
    before = out.size();
  };
  nlohmann::json support;
  build_support(b, plan, lighting, support);
  count("support");

  std::string floor_kind, wall_kind, accent_kind;
  const Material floor = floor_material(rng, floor_kind);
  tiled_rect(sampler, detail, {lo.x(), 0, hi.z()}, Vector3d::UnitX(), -Vector3d::UnitZ(), hi.x() - lo.x(),
             hi.z() - lo.z(), floor);
  count("floor");
  const Material walls = wall_material(rng, wall_kind);
  const int accent_wall = rng.chance(0.35) ? rng.integer(0, 3) : -1;
  const Material accent = wall_material(rng, accent_kind);
  const auto room_walls = walls_of(plan);
  const Material baseboard = rng.chance(0.5) ? painted(rng) : wood(rng);
  for (int w = 0; w < 4; ++w) {
    const Wall& wall = room_walls[w];
    tiled_rect(sampler, detail, wall.corner, wall.u, Vector3d::UnitY(), wall.length, height,
               w == accent_wall ? accent : walls);
    const Vector3d normal = wall.u.cross(Vector3d::UnitY());
    const Vector3d board = wall.corner + normal * 0.012;
    tiled_rect(sampler, detail, board, wall.u, Vector3d::UnitY(), wall.length, 0.08, baseboard, 1.0);
    tiled_rect(sampler, detail, board + Vector3d(0, 0.08, 0), wall.u, -normal, wall.length, 0.012, baseboard, 1.0);
  }
  count("walls");
  std::string ceiling_kind;
  Material ceiling = material(Pattern::solid, hsv(rng.uniform(), rng.uniform(0, 0.08), rng.uniform(0.8, 0.95)),
                              Rgb::Zero(), 1, 0.03, rng);
  tiled_rect(sampler, detail, {lo.x(), hi.y(), lo.z()}, Vector3d::UnitX(), Vector3d::UnitZ(), hi.x() - lo.x(),
             hi.z() - lo.z(), ceiling, 1.0);
  Material fixture = material(Pattern::solid, Rgb(1.f, 0.97f, 0.9f), Rgb::Zero(), 1, 0.0, rng);
  fixture.lit = false;
  sampler.disc(lighting.lamp + Vector3d(0, -0.01, 0), rng.uniform(0.12, 0.25), false, fixture,
               detail.spacing_sphere(lighting.lamp, 0.3));
  count("ceiling");

  nlohmann::json decorations = nlohmann::json::array();
  for (int w = 0; w < 4; ++w) decorate_wall(b, room_walls[w], w, pieces, height, decorations);
  count("decorations");

  nlohmann::json rug_json = nullptr;
  if (rng.chance(0.45)) {
    const double rw = rng.uniform(0.6, 1.3), rd = rng.uniform(0.5, 1.1);
    const Rgb c = hsv(rng.uniform(), rng.uniform(0.2, 0.7), rng.uniform(0.25, 0.8));
    const Pattern p = rng.pick(std::vector<Pattern>{Pattern::stripes, Pattern::checker, Pattern::noise, Pattern::fabric,
                                                    Pattern::dots, Pattern::canvas});
    const Material rug = material(p, c, hsv(rng.uniform(), rng.uniform(0.2, 0.7), rng.uniform(0.3, 0.9)),
                                  rng.uniform(0.08, 0.25), 0.08, rng);
    const Vector3d corner(plan.object_base.x() - rw + rng.uniform(-0.2, 0.2), 0.008,
                          plan.object_base.z() + rd + rng.uniform(-0.2, 0.2));
    tiled_rect(sampler, detail, corner, Vector3d::UnitX(), -Vector3d::UnitZ(), 2 * rw, 2 * rd, rug);
    rug_json = {{"pattern", static_cast<int>(p)}, {"size", {2 * rw, 2 * rd}}};
  }
  count("rug");

  nlohmann::json furniture = nlohmann::json::array();
  for (const Piece& p : pieces) {
    build_piece(b, p);
    furniture.push_back({{"kind", p.kind},
                         {"wall", p.wall},
                         {"footprint", {p.lo.x(), p.lo.y(), p.hi.x(), p.hi.y()}},
                         {"height", p.height}});
  }
  count("furniture");

  description["room"] = {{"min", {lo.x(), lo.y(), lo.z()}},
                         {"max", {hi.x(), hi.y(), hi.z()}},
                         {"floor", floor_kind},
                         {"walls", wall_kind},
                         {"accent_wall", accent_wall >= 0 ? nlohmann::json(accent_kind) : nullptr}};
  description["furniture"] = furniture;
  description["decorations"] = decorations;
  description["rug"] = rug_json;
  description["support"] = plan.support == 0 ? nlohmann::json("floor") : support;
  description["gaussians"] = counts;
}

}  // namespace ii::synth
