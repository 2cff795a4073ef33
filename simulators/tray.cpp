// Trays for the segmentation benchmark. Every sherd is rasterised once into a height map on the
// tray's grid (its highest and lowest surface over each cell); placing it moves that map by whole
// cells, so overlap, contact and resting heights are exact cell operations. The final cloud is the
// topmost surface per cell: what a scanner above the tray records.
#include "simulators/tray.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "core/errors.h"
#include "simulators/random.h"
#include "simulators/vessel.h"

namespace sherd::sim {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kRimMarginMm = 3.0;  // sherds stay this far inside the plate's edge
constexpr double kFreeGapMm = 4.0;    // a sherd laid "free" keeps this gap to all others
constexpr float kNoFloor = std::numeric_limits<float>::infinity();

// A sherd's height map on the tray grid, positioned with its footprint centred on the plate
// centre: cell (i0 + a, j0 + b) for a < w, b < h.
struct HeightMap {
  int i0 = 0, j0 = 0, w = 0, h = 0;
  std::vector<float> top, bottom;  // −inf / +inf where the sherd does not cover the cell
  std::vector<Rgb8> colour;        // of the top surface
  bool covers(int k) const { return bottom[k] != kNoFloor; }
};

class Grid {
 public:
  explicit Grid(double step)
      : step_(step), n_(static_cast<int>(std::ceil(2 * kPlateRadiusMm / step))) {}
  int size() const { return n_; }
  double step() const { return step_; }
  double centre(int i) const { return -kPlateRadiusMm + (i + 0.5) * step_; }
  // First and last cell whose centre lies in [lo, hi].
  int first(double lo) const {
    return static_cast<int>(std::ceil((lo + kPlateRadiusMm) / step_ - 0.5));
  }
  int last(double hi) const {
    return static_cast<int>(std::floor((hi + kPlateRadiusMm) / step_ - 0.5));
  }
  bool on_plate(int i, int j, double margin) const {
    if (i < 0 || j < 0 || i >= n_ || j >= n_) return false;
    const double r = kPlateRadiusMm - margin;
    return centre(i) * centre(i) + centre(j) * centre(j) <= r * r;
  }

 private:
  double step_;
  int n_;
};

// Light from above and a little aside: a face's brightness is 0.35 + 0.65 |n·l|, so the same
// clay shows from dark to bright, as under the station's lamps.
double shading(const Vec3d& normal) {
  static const Vec3d light = Vec3d(0.4, 0.3, 1.0).normalized();
  return 0.35 + 0.65 * std::abs(normal.dot(light));
}

Rgb8 scaled(const Vec3d& rgb, double factor, Rng& rng) {
  auto channel = [&](double v) {
    return static_cast<std::uint8_t>(
        std::clamp(std::lround(v * factor + rng.uniform(-4.0, 4.0)), 0L, 255L));
  };
  return {channel(rgb.x()), channel(rgb.y()), channel(rgb.z())};
}

// Height map of `mesh` (world orientation, any position): re-centred so that its footprint's
// box centre sits on the plate centre and its lowest point at z = 0.
HeightMap rasterise(Mesh mesh, const Grid& grid) {
  const Box3 box = Box3::of(mesh.vertices);
  const Vec3f shift(-0.5f * static_cast<float>(box.min.x() + box.max.x()),
                    -0.5f * static_cast<float>(box.min.y() + box.max.y()),
                    -static_cast<float>(box.min.z()));
  for (auto& p : mesh.vertices.points) p += shift;
  const Vec3d half = 0.5 * box.extent();

  HeightMap map;
  map.i0 = grid.first(-half.x());
  map.j0 = grid.first(-half.y());
  map.w = std::max(0, grid.last(half.x()) - map.i0 + 1);
  map.h = std::max(0, grid.last(half.y()) - map.j0 + 1);
  const std::size_t cells = static_cast<std::size_t>(map.w) * map.h;
  map.top.assign(cells, -kNoFloor);
  map.bottom.assign(cells, kNoFloor);
  map.colour.assign(cells, Rgb8{0, 0, 0});
  const auto& pts = mesh.vertices.points;
  const auto& col = mesh.vertices.colours;
  for (const auto& t : mesh.triangles) {
    const Vec3d a = pts[t[0]].cast<double>(), b = pts[t[1]].cast<double>(),
                c = pts[t[2]].cast<double>();
    const Vec3d normal = (b - a).cross(c - a);
    const double area2 = normal.z();        // twice the signed area of the footprint
    if (std::abs(area2) < 1e-12) continue;  // seen edge-on from above
    const double shade = shading(normal.normalized());
    const int i_lo = std::max(grid.first(std::min({a.x(), b.x(), c.x()})), map.i0);
    const int i_hi = std::min(grid.last(std::max({a.x(), b.x(), c.x()})), map.i0 + map.w - 1);
    const int j_lo = std::max(grid.first(std::min({a.y(), b.y(), c.y()})), map.j0);
    const int j_hi = std::min(grid.last(std::max({a.y(), b.y(), c.y()})), map.j0 + map.h - 1);
    for (int j = j_lo; j <= j_hi; ++j) {
      for (int i = i_lo; i <= i_hi; ++i) {
        const double x = grid.centre(i), y = grid.centre(j);
        // Barycentric weights of the cell centre in the footprint triangle.
        const double wa = ((b.x() - x) * (c.y() - y) - (c.x() - x) * (b.y() - y)) / area2;
        const double wb = ((c.x() - x) * (a.y() - y) - (a.x() - x) * (c.y() - y)) / area2;
        const double wc = 1.0 - wa - wb;
        if (wa < 0 || wb < 0 || wc < 0) continue;
        const float z = static_cast<float>(wa * a.z() + wb * b.z() + wc * c.z());
        const std::size_t k = static_cast<std::size_t>(j - map.j0) * map.w + (i - map.i0);
        map.bottom[k] = std::min(map.bottom[k], z);
        if (z > map.top[k]) {
          map.top[k] = z;
          auto rgb = [&](std::uint32_t v) { return Vec3d(col[v].r, col[v].g, col[v].b); };
          const Vec3d mixed = wa * rgb(t[0]) + wb * rgb(t[1]) + wc * rgb(t[2]);
          map.colour[k] = {static_cast<std::uint8_t>(std::lround(mixed.x() * shade)),
                           static_cast<std::uint8_t>(std::lround(mixed.y() * shade)),
                           static_cast<std::uint8_t>(std::lround(mixed.z() * shade))};
        }
      }
    }
  }
  return map;
}

// The tray being filled: which sherd's surface is on top in each cell, and how high.
class Layout {
 public:
  Layout(const Grid& grid)
      : grid_(grid), cells_(static_cast<std::size_t>(grid.size()) * grid.size()) {
    owner_.assign(cells_, 0);
    blocked_.assign(cells_, 0);
    top_.assign(cells_, 0.0f);
    colour_.assign(cells_, Rgb8{0, 0, 0});
  }
  int owner(int i, int j) const { return owner_[index(i, j)]; }
  float top(int i, int j) const { return top_[index(i, j)]; }
  Rgb8 colour(int i, int j) const { return colour_[index(i, j)]; }
  std::size_t index(int i, int j) const { return static_cast<std::size_t>(j) * grid_.size() + i; }

  // Calls f(global i, global j, map cell k) for every covered cell of `map` moved by (di, dj).
  template <typename F>
  bool each_cell(const HeightMap& map, int di, int dj, F&& f) const {
    for (int b = 0; b < map.h; ++b) {
      for (int a = 0; a < map.w; ++a) {
        const std::size_t k = static_cast<std::size_t>(b) * map.w + a;
        if (map.covers(k) && !f(map.i0 + a + di, map.j0 + b + dj, k)) return false;
      }
    }
    return true;
  }
  bool on_plate(const HeightMap& map, int di, int dj) const {
    return each_cell(map, di, dj,
                     [&](int i, int j, std::size_t) { return grid_.on_plate(i, j, kRimMarginMm); });
  }
  // On the plate and clear of every sherd and of the gap around each.
  bool free_at(const HeightMap& map, int di, int dj) const {
    return each_cell(map, di, dj, [&](int i, int j, std::size_t) {
      return grid_.on_plate(i, j, kRimMarginMm) && !blocked_[index(i, j)];
    });
  }
  // Labels of the sherds under the moved map, and how many of its cells they cover.
  std::vector<std::pair<int, int>> overlaps(const HeightMap& map, int di, int dj) const {
    std::vector<std::pair<int, int>> found;
    each_cell(map, di, dj, [&](int i, int j, std::size_t) {
      if (!grid_.on_plate(i, j, 0.0)) return true;
      const int o = owner_[index(i, j)];
      if (o == 0) return true;
      auto it = std::find_if(found.begin(), found.end(), [&](auto& e) { return e.first == o; });
      if (it == found.end())
        found.emplace_back(o, 1);
      else
        ++it->second;
      return true;
    });
    return found;
  }
  bool touches_another(const HeightMap& map, int di, int dj) const {
    return !each_cell(map, di, dj, [&](int i, int j, std::size_t) {
      for (int dj2 = -1; dj2 <= 1; ++dj2) {
        for (int di2 = -1; di2 <= 1; ++di2) {
          if (grid_.on_plate(i + di2, j + dj2, 0.0) && owner_[index(i + di2, j + dj2)] != 0)
            return false;
        }
      }
      return true;
    });
  }
  // Lowest lift that keeps the moved map above the plate and above whatever it overlaps.
  float resting_lift(const HeightMap& map, int di, int dj) const {
    float lift = 0.0f;
    each_cell(map, di, dj, [&](int i, int j, std::size_t k) {
      lift = std::max(lift, top_[index(i, j)] - map.bottom[k]);
      return true;
    });
    return lift;
  }
  void put(const HeightMap& map, int di, int dj, float lift, int label) {
    const int gap = static_cast<int>(std::ceil(kFreeGapMm / grid_.step()));
    each_cell(map, di, dj, [&](int i, int j, std::size_t k) {
      const std::size_t at = index(i, j);
      if (map.top[k] + lift > top_[at]) {
        top_[at] = map.top[k] + lift;
        owner_[at] = label;
        colour_[at] = map.colour[k];
      }
      for (int b = std::max(0, j - gap); b <= std::min(grid_.size() - 1, j + gap); ++b) {
        for (int a = std::max(0, i - gap); a <= std::min(grid_.size() - 1, i + gap); ++a)
          blocked_[index(a, b)] = 1;
      }
      return true;
    });
  }

 private:
  const Grid& grid_;
  std::size_t cells_;
  std::vector<int> owner_;  // 0 = plate, k = sherd k on top
  std::vector<std::uint8_t> blocked_;
  std::vector<float> top_;
  std::vector<Rgb8> colour_;
};

// Rotation laying a piece on the plate: its outer face up or down, turned by `yaw` about z.
Eigen::Matrix3d lying(const Point2& centre_normal, bool outer_up, double yaw) {
  const Vec3d n(centre_normal.x(), 0.0, centre_normal.y());
  const Eigen::Matrix3d flat =
      Eigen::Quaterniond::FromTwoVectors(n.normalized(),
                                         outer_up ? Vec3d::UnitZ() : Vec3d(-Vec3d::UnitZ()))
          .toRotationMatrix();
  return Eigen::AngleAxisd(yaw, Vec3d::UnitZ()).toRotationMatrix() * flat;
}

Mesh rotated(const Mesh& mesh, const Eigen::Matrix3d& rotation) {
  Mesh out = mesh;
  Pose pose = Pose::Identity();
  pose.linear() = rotation;
  out.vertices.transform(pose);
  return out;
}

struct Placement {
  int di = 0, dj = 0;
  float lift = 0.0f;
};

// Cells from the map's (centred) footprint to a point at distance t cells along `dir` from the
// centre of sherd `target`'s placement.
Placement along(const Placement& target, const Eigen::Vector2d& dir, int t) {
  return {target.di + static_cast<int>(std::lround(t * dir.x())),
          target.dj + static_cast<int>(std::lround(t * dir.y())), 0.0f};
}

}  // namespace

Tray make_tray(const TraySpec& spec) {
  if (spec.sherds < 1 || spec.sherds > kMaxTraySherds) {
    throw InputError(fmt::format("tray simulator: {} sherds requested: a tray holds 1 to {}",
                                 spec.sherds, kMaxTraySherds));
  }
  if (!(spec.grid_mm >= 0.1 && spec.grid_mm <= 2.0)) {
    throw InputError(fmt::format("tray simulator: grid step {} mm: use 0.1 to 2 mm", spec.grid_mm));
  }
  Tray tray;
  tray.spec = spec;
  tray.sherds = spec.sherds;
  Rng master(spec.seed);
  const Grid grid(spec.grid_mm);
  Layout layout(grid);
  Rng order = master.fork();
  const std::vector<SherdKind> kinds = tray_kinds(spec.sherds, order);
  // About a third of the plate covered.
  const double plate_area = kPi * (kPlateRadiusMm - kRimMarginMm) * (kPlateRadiusMm - kRimMarginMm);
  const double first_extent = std::clamp(std::sqrt(0.33 * plate_area / spec.sherds), 38.0, 100.0);
  std::vector<Placement> placed;

  for (int s = 0; s < spec.sherds; ++s) {
    Rng rng = master.fork();
    const double mode_draw = rng.uniform();
    enum class Mode { Free, Touching, Leaning } mode = Mode::Free;
    if (s > 0 && mode_draw < spec.leaning_share)
      mode = Mode::Leaning;
    else if (s > 0 && mode_draw < spec.leaning_share + spec.touching_share)
      mode = Mode::Touching;

    bool done = false;
    for (double max_extent = first_extent;; max_extent = std::max(30.0, 0.8 * max_extent)) {
      const BrokenVessel broken = break_random_vessel(kinds[s], max_extent, rng);
      const bool outer_up = rng.chance(0.5);
      Eigen::Matrix3d rotation =
          lying(broken.piece.centre_normal, outer_up, rng.uniform(0.0, 2 * kPi));
      for (int attempt = 0; attempt < 60 && !done; ++attempt) {
        if (mode == Mode::Free) {
          const HeightMap map = rasterise(rotated(broken.piece.mesh, rotation), grid);
          const int reach = grid.size() / 2;
          for (int k = 0; k < 3000 && !done; ++k) {
            const Placement p{rng.integer(-reach, reach), rng.integer(-reach, reach), 0.0f};
            if (!layout.free_at(map, p.di, p.dj)) continue;
            layout.put(map, p.di, p.dj, 0.0f, s + 1);
            placed.push_back(p);
            done = true;
          }
          break;
        }
        // Against (or onto) an earlier sherd, coming from a random direction.
        const int target = rng.integer(0, static_cast<int>(placed.size()) - 1);
        const double psi = rng.uniform(0.0, 2 * kPi);
        const Eigen::Vector2d dir(std::cos(psi), std::sin(psi));
        Eigen::Matrix3d tilt = Eigen::Matrix3d::Identity();
        if (mode == Mode::Leaning) {  // the side facing the target raised by 10–25°
          const Vec3d axis = Vec3d::UnitZ().cross(Vec3d(dir.x(), dir.y(), 0.0));
          tilt = Eigen::AngleAxisd(rng.uniform(10.0, 25.0) * kPi / 180.0, axis).toRotationMatrix();
        }
        const HeightMap map = rasterise(rotated(broken.piece.mesh, tilt * rotation), grid);
        int covered = 0;
        for (std::size_t k = 0; k < map.bottom.size(); ++k) covered += map.covers(k);
        for (int t = 0; t < 2 * grid.size(); ++t) {
          Placement p = along(placed[target], dir, t);
          const auto under = layout.overlaps(map, p.di, p.dj);
          if (mode == Mode::Touching) {
            if (!under.empty()) continue;
            if (layout.on_plate(map, p.di, p.dj) && layout.touches_another(map, p.di, p.dj)) {
              layout.put(map, p.di, p.dj, 0.0f, s + 1);
              placed.push_back(p);
              ++tray.touching;
              done = true;
            }
            break;
          }
          // Leaning: a small part of it over the target alone, resting on the target's surface.
          if (under.size() > 1 || (under.size() == 1 && under[0].first != target + 1)) continue;
          if (under.empty()) break;  // slid off without finding a rest
          if (under[0].second > 0.15 * covered) continue;
          if (!layout.on_plate(map, p.di, p.dj)) break;
          p.lift = layout.resting_lift(map, p.di, p.dj);
          layout.put(map, p.di, p.dj, p.lift, s + 1);
          placed.push_back(p);
          ++tray.leaning;
          done = true;
          break;
        }
      }
      if (done) break;
      if (mode != Mode::Free) {
        mode = Mode::Free;  // no room beside a neighbour: anywhere free, a smaller piece if need be
      } else if (max_extent <= 30.0) {
        throw InputError(
            fmt::format("tray simulator: no room for {} sherds (seed {}): use fewer sherds",
                        spec.sherds, spec.seed));
      }
    }
  }

  // The scan: one point per plate cell on the topmost surface, then dust and strays.
  Rng noise = master.fork();
  const Rgb8 bg = background_colour(spec.background);
  const Vec3d bg_rgb(bg.r, bg.g, bg.b);
  std::vector<float> dust(static_cast<std::size_t>(grid.size()) * grid.size(), 0.0f);
  std::vector<Rgb8> dust_colour(dust.size());
  for (int d = 0; d < spec.dust_specks; ++d) {
    const double cx = noise.uniform(-kPlateRadiusMm, kPlateRadiusMm),
                 cy = noise.uniform(-kPlateRadiusMm, kPlateRadiusMm);
    const double radius = noise.uniform(0.3, 2.0), height = noise.uniform(0.2, 2.5);
    const Vec3d rgb =
        noise.chance(0.5) ? Vec3d(160, 100, 60) : Vec3d(120, 118, 110);  // clay crumb or grit
    for (int j = grid.first(cy - radius); j <= grid.last(cy + radius); ++j) {
      for (int i = grid.first(cx - radius); i <= grid.last(cx + radius); ++i) {
        if (!grid.on_plate(i, j, 0.0) || layout.owner(i, j) != 0) continue;
        const double r2 = (std::pow(grid.centre(i) - cx, 2) + std::pow(grid.centre(j) - cy, 2)) /
                          (radius * radius);
        if (r2 > 1.0) continue;
        dust[layout.index(i, j)] = static_cast<float>(height * std::sqrt(1.0 - r2));
        dust_colour[layout.index(i, j)] = scaled(rgb, 1.0, noise);
      }
    }
  }
  auto& points = tray.cloud.vertices.points;
  auto& colours = tray.cloud.vertices.colours;
  for (int j = 0; j < grid.size(); ++j) {
    for (int i = 0; i < grid.size(); ++i) {
      if (!grid.on_plate(i, j, 0.0)) continue;
      const std::size_t at = layout.index(i, j);
      const int label = layout.owner(i, j);
      const double x = grid.centre(i), y = grid.centre(j);
      float z = label != 0 ? layout.top(i, j) : dust[at];
      Rgb8 colour;
      if (label != 0) {
        const Rgb8 c = layout.colour(i, j);
        colour = scaled(Vec3d(c.r, c.g, c.b), 1.0, noise);
      } else if (dust[at] > 0.0f) {
        colour = dust_colour[at];
      } else {  // the plate: brighter at the centre, darker at the rim, as under a lamp above
        colour = scaled(bg_rgb, 0.75 + 0.25 * (1.0 - std::hypot(x, y) / kPlateRadiusMm), noise);
      }
      // Scanner noise: 0.05 mm along the view, 0.03 mm across.
      points.emplace_back(static_cast<float>(x + 0.03 * noise.normal()),
                          static_cast<float>(y + 0.03 * noise.normal()),
                          static_cast<float>(z + 0.05 * noise.normal()));
      colours.push_back(colour);
      tray.labels.push_back(label);
    }
  }
  for (int k = 0; k < spec.stray_points; ++k) {
    const double angle = noise.uniform(0.0, 2 * kPi),
                 r = kPlateRadiusMm * std::sqrt(noise.uniform());
    points.emplace_back(static_cast<float>(r * std::cos(angle)),
                        static_cast<float>(r * std::sin(angle)),
                        static_cast<float>(noise.uniform(1.0, 80.0)));
    colours.push_back(scaled(
        Vec3d(noise.uniform(0, 255), noise.uniform(0, 255), noise.uniform(0, 255)), 1.0, noise));
    tray.labels.push_back(0);
  }
  return tray;
}

}  // namespace sherd::sim
