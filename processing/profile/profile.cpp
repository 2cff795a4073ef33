// Orientation, section profile and measurements of one sherd around a known axis.
//
// Everything is done in cylindrical coordinates about the axis: height h along it, radius r and
// azimuth phi around it. A surface of revolution maps every azimuth onto the same (r, h) curve,
// so a thin slab of points around one azimuth is the profile.
#include "processing/profile/profile.h"

#include "core/errors.h"

#include <fmt/format.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <queue>

namespace sherd::profile {
namespace {

constexpr double kDegToRad = M_PI / 180.0;
constexpr double kTwoPi = 2.0 * M_PI;

using Vec2 = Eigen::Vector2d;

struct CylPoint {
  double r, h, phi;
  double n_r, n_h;  // normal components along the point's radial direction and the axis
};

struct Frame {
  Vec3d origin, x, y, z;
};

Frame frame_about(const Vec3d& origin, const Vec3d& z_axis) {
  const Vec3d z = z_axis.normalized();
  const Vec3d helper = std::abs(z.x()) < 0.9 ? Vec3d::UnitX() : Vec3d::UnitY();
  const Vec3d x = z.cross(helper).normalized();
  return {origin, x, z.cross(x), z};
}

std::vector<CylPoint> cylindrical(const Cloud& cloud, const Frame& f) {
  std::vector<CylPoint> out;
  out.reserve(cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Vec3d d = cloud.points[i].cast<double>() - f.origin;
    const Vec3d n = cloud.normals[i].cast<double>();
    const double px = d.dot(f.x), py = d.dot(f.y);
    const double r = std::hypot(px, py);
    const double phi = std::atan2(py, px);
    const Vec3d radial = r > 1e-9 ? Vec3d((px * f.x + py * f.y) / r) : f.x;
    out.push_back({r, d.dot(f.z), phi, n.dot(radial), n.dot(f.z)});
  }
  return out;
}

double wrap_angle(double a) {  // to (-pi, pi]
  a = std::fmod(a + M_PI, kTwoPi);
  if (a < 0) a += kTwoPi;
  return a - M_PI;
}

// How much of the circle a set of azimuths covers. Azimuths are binned; empty runs shorter than
// `fill_gap_mm` at radius `radius` are scan holes and count as covered; the covered extent is
// measured from the first to the last azimuth of each covered run (no bin quantisation).
struct Coverage {
  double degrees = 0.0;
  double middle_rad = 0.0;  // middle of the covered part: opposite the largest empty run
};

Coverage angular_coverage(const std::vector<double>& phis, double radius,
                          double fill_gap_mm = 5.0) {
  Coverage c;
  if (phis.empty()) return c;
  radius = std::max(radius, 1.0);
  const double bin = std::max(1.0 * kDegToRad, 1.5 / radius);
  const int bins = static_cast<int>(std::ceil(kTwoPi / bin));
  std::vector<double> lo(bins, std::numeric_limits<double>::infinity());
  std::vector<double> hi(bins, -std::numeric_limits<double>::infinity());
  for (double phi : phis) {
    const double a = wrap_angle(phi) + M_PI;  // [0, 2pi)
    const int b = std::min(bins - 1, static_cast<int>(a / bin));
    lo[b] = std::min(lo[b], a);
    hi[b] = std::max(hi[b], a);
  }
  auto occupied = [&](int b) { return std::isfinite(lo[((b % bins) + bins) % bins]); };
  // Start just after an empty bin, so that runs do not wrap around the start.
  int start = -1;
  for (int b = 0; b < bins; ++b) {
    if (!occupied(b)) {
      start = b + 1;
      break;
    }
  }
  if (start < 0) return {360.0, 0.0};
  const int fill_bins = std::max(3, static_cast<int>(std::ceil(fill_gap_mm / (radius * bin))));
  // Walk once around: covered runs (holes filled) and the largest true gap.
  double covered = 0.0;
  int largest_gap = 0, largest_gap_end = start;
  int b = start;
  const int stop = start + bins;
  while (b < stop) {
    if (!occupied(b)) {
      int e = b;
      while (e < stop && !occupied(e)) ++e;
      if (e - b > largest_gap) {
        largest_gap = e - b;
        largest_gap_end = e;
      }
      b = e;
      continue;
    }
    // A covered run: occupied bins, bridging gaps shorter than fill_bins.
    const int first = b;
    int last = b;
    int e = b + 1;
    while (e < stop) {
      if (occupied(e)) {
        last = e++;
        continue;
      }
      int g = e;
      while (g < stop && !occupied(g)) ++g;
      if (g - e >= fill_bins || g >= stop) break;
      e = g;
    }
    const double first_angle = lo[first % bins] + (first >= bins ? kTwoPi : 0.0);
    const double last_angle = hi[last % bins] + (last >= bins ? kTwoPi : 0.0);
    covered += last_angle - first_angle;
    b = last + 1;
  }
  c.degrees = std::min(360.0, covered / kDegToRad);
  // The covered part lies between the end of the largest gap and its start (one turn later).
  const double covered_from = largest_gap_end * bin;
  const double covered_to = (largest_gap_end - largest_gap + bins) * bin;
  c.middle_rad = wrap_angle(0.5 * (covered_from + covered_to) - M_PI);
  return c;
}

double median_radius(const std::vector<CylPoint>& pts) {
  std::vector<double> r;
  r.reserve(pts.size());
  for (const auto& p : pts) r.push_back(p.r);
  if (r.empty()) return 1.0;
  std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
  return r[r.size() / 2];
}

// What one axial end of the sherd looks like, seen in the (r, h) half-plane over its whole arc.
struct EndShape {
  bool reaches_axis = false;  // closes towards the axis: the middle of a base
  // The end's height, azimuth by azimuth, less a linear trend (what a slightly tilted axis
  // leaves), varies by less than kFlatEndMm over the middle of the arc: a lip or a resting
  // underside (both perpendicular to the axis), not a wandering break.
  bool level = false;
  // Radial extent of the faces that look out of the sherd along the axis, at the very end
  // (within kEndFaceMm) and near it (within kRecessMm): a lip's rounded top spans less than a
  // wall thickness; a base's underside more; a foot ring about 1.5 walls at the end and, with the
  // underside recessed inside it, much more near it; a break through a near-horizontal wall
  // nothing (its face looks sideways).
  double end_face_span_mm = 0.0;
  double near_face_span_mm = 0.0;
};

constexpr double kFlatEndMm = 1.0;  // a break wanders by 2 mm or more along the arc
constexpr double kEndFaceMm = 1.5;  // deeper than the rounding of a lip's top
constexpr double kRecessMm = 8.0;   // deeper than a foot ring is high (3–7 mm)

EndShape end_shape(const std::vector<CylPoint>& pts, bool top, double max_radius,
                   double arc_middle) {
  const double sign = top ? 1.0 : -1.0;
  EndShape s;
  // Per-azimuth extreme height, in bins of ~2 mm of arc at the median radius.
  const double radius = std::max(median_radius(pts), 1.0);
  const double bin = 2.0 / radius;
  std::vector<std::pair<double, double>> by_phi;  // (phi, sign × h)
  by_phi.reserve(pts.size());
  // Centred on the arc's middle, a sherd's azimuths do not wrap at ±pi.
  for (const auto& p : pts) by_phi.push_back({wrap_angle(p.phi - arc_middle), sign * p.h});
  std::sort(by_phi.begin(), by_phi.end());
  std::vector<Vec2> extremes;  // (phi, extreme sign × h)
  for (std::size_t i = 0; i < by_phi.size();) {
    const double start = by_phi[i].first;
    double extreme = -std::numeric_limits<double>::infinity();
    std::size_t n = 0;
    for (; i < by_phi.size() && by_phi[i].first < start + bin; ++i, ++n)
      extreme = std::max(extreme, by_phi[i].second);
    if (n >= 3) extremes.push_back({start, extreme});
  }
  if (extremes.size() >= 5) {
    // The middle 60 % of the arc: the side breaks (wandering by up to ~12 % of the arc each)
    // round the end off at both sides.
    const std::size_t cut = extremes.size() / 5;
    const std::vector<Vec2> middle(extremes.begin() + cut, extremes.end() - cut);
    Eigen::MatrixXd design(middle.size(), 2);
    Eigen::VectorXd heights(middle.size());
    for (std::size_t k = 0; k < middle.size(); ++k) {
      design.row(k) << 1.0, middle[k].x();
      heights[k] = middle[k].y();
    }
    const Eigen::VectorXd trend = design.colPivHouseholderQr().solve(heights);
    std::vector<double> residual(middle.size());
    for (std::size_t k = 0; k < middle.size(); ++k)
      residual[k] = heights[k] - design.row(k).dot(trend);
    std::sort(residual.begin(), residual.end());
    const double spread = residual[residual.size() * 9 / 10] - residual[residual.size() / 10];
    s.level = spread <= kFlatEndMm;
  }
  double end = -std::numeric_limits<double>::infinity();
  for (const auto& p : pts) end = std::max(end, sign * p.h);
  double min_r = std::numeric_limits<double>::infinity();
  constexpr double kNone = std::numeric_limits<double>::infinity();
  std::array<double, 2> lo{kNone, kNone}, hi{-kNone, -kNone};  // [end, near]
  for (const auto& p : pts) {
    const double depth = end - sign * p.h;
    if (depth > kRecessMm) continue;
    min_r = std::min(min_r, p.r);
    if (sign * p.n_h <= 0.9) continue;
    for (int k = depth <= kEndFaceMm ? 0 : 1; k < 2; ++k) {
      lo[k] = std::min(lo[k], p.r);
      hi[k] = std::max(hi[k], p.r);
    }
  }
  s.reaches_axis = min_r < 0.15 * max_radius;
  s.end_face_span_mm = hi[0] > lo[0] ? hi[0] - lo[0] : 0.0;
  s.near_face_span_mm = hi[1] > lo[1] ? hi[1] - lo[1] : 0.0;
  return s;
}

// What a potter's profile tells about an end (see orient):
//   lip      — rounded (or flat) end where the outer and inner skins meet, level all along the
//              rim, its outward face no wider than the wall;
//   base     — the end closes towards the axis, or a level underside / foot ring wider than the
//              wall faces out of it along the axis;
//   fracture — a break: wanders in height along the arc.
enum class EndKind { Lip, Base, Fracture };

EndKind classify(const EndShape& e, double wall_mm) {
  constexpr double kWiderThanWall = 1.2;  // a foot ring is ≥ 1.3 walls wide, a flat lip 1
  constexpr double kFootRing = 0.9;       // a foot ring's end, allowing for a thick floor's wall
  constexpr double kRecessedUnderside = 2.5;
  constexpr double kLipTop = 0.2;  // a rounded lip's top faces out over ~0.5 wall
  if (e.reaches_axis) return EndKind::Base;
  if (!e.level) return EndKind::Fracture;
  if (e.end_face_span_mm > kWiderThanWall * wall_mm ||
      (e.end_face_span_mm > kFootRing * wall_mm &&
       e.near_face_span_mm > kRecessedUnderside * wall_mm)) {
    return EndKind::Base;
  }
  return e.end_face_span_mm >= kLipTop * wall_mm ? EndKind::Lip : EndKind::Fracture;
}

// Orientation rule: the lip is at the top and the base at the bottom. Certain when the two ends
// say so without contradiction: a lip against a break or a base, or a base against a break.
// Otherwise (two breaks: a body sherd; or two ends of one kind) the wider end is taken as the
// top — most vessels widen from the base upwards — and the orientation is marked uncertain.
// has_rim is claimed only for a lip at the top, has_base only for a base at the bottom: a break
// is never a rim. (README, "sherd.json: the axis, the orientation and the profile", spells the
// rule out with classify's thresholds for the archaeologist.)
struct Orientation {
  bool flip = false;  // the rim is at the provisional -z end
  bool certain = false;
  bool has_rim = false;
  bool has_base = false;
};

Orientation orient(const std::vector<CylPoint>& pts, double wall_mm, double arc_middle) {
  double max_r = 0.0;
  for (const auto& p : pts) max_r = std::max(max_r, p.r);
  const EndShape top_shape = end_shape(pts, true, max_r, arc_middle);
  const EndShape bottom_shape = end_shape(pts, false, max_r, arc_middle);
  const EndKind top = classify(top_shape, wall_mm), bottom = classify(bottom_shape, wall_mm);
  auto mean_radius_near_end = [&](bool at_top) {
    double end =
        at_top ? -std::numeric_limits<double>::infinity() : std::numeric_limits<double>::infinity();
    for (const auto& p : pts) end = at_top ? std::max(end, p.h) : std::min(end, p.h);
    double sum = 0.0;
    int n = 0;
    for (const auto& p : pts) {
      if (std::abs(p.h - end) <= 5.0) sum += p.r, ++n;
    }
    return n ? sum / n : 0.0;
  };
  Orientation o;
  if (top != bottom) {
    // Up is where the lip is; without a lip, away from the base.
    o.flip = bottom == EndKind::Lip || (top == EndKind::Base && bottom == EndKind::Fracture);
    o.certain = true;
  } else {
    o.flip = mean_radius_near_end(false) > mean_radius_near_end(true);
  }
  const EndKind rim_end = o.flip ? bottom : top;
  const EndKind base_end = o.flip ? top : bottom;
  o.has_rim = rim_end == EndKind::Lip;
  o.has_base = base_end == EndKind::Base;
  return o;
}

// Candidate section azimuths, best first: where the sherd's axial extent is largest (the
// best-preserved profile); among nearly equal extents the one nearest the middle of the arc, away
// from the side breaks. Candidates lie at least two slab widths apart, so a later one is a
// different section, not the same slab again.
std::vector<double> section_azimuths(const std::vector<CylPoint>& pts, double half_width_rad,
                                     double arc_middle) {
  const int bins = 720;
  const double bin = kTwoPi / bins;
  std::vector<double> lo(bins, std::numeric_limits<double>::infinity());
  std::vector<double> hi(bins, -std::numeric_limits<double>::infinity());
  for (const auto& p : pts) {
    const int b = std::min(bins - 1, static_cast<int>((wrap_angle(p.phi) + M_PI) / bin));
    lo[b] = std::min(lo[b], p.h);
    hi[b] = std::max(hi[b], p.h);
  }
  const int reach = std::max(1, static_cast<int>(half_width_rad / bin));
  struct Candidate {
    double extent, offset, azimuth;
  };
  std::vector<Candidate> candidates;
  for (int b = 0; b < bins; ++b) {
    double l = std::numeric_limits<double>::infinity(), h = -l;
    for (int k = -reach; k <= reach; ++k) {
      const int j = ((b + k) % bins + bins) % bins;
      l = std::min(l, lo[j]);
      h = std::max(h, hi[j]);
    }
    if (h < l) continue;
    const double centre = (b + 0.5) * bin - M_PI;
    candidates.push_back({h - l, std::abs(wrap_angle(centre - arc_middle)), centre});
  }
  // Extents within kTieMm of each other count as equal: then the one nearer the middle wins.
  constexpr double kTieMm = 0.25;
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    const double ka = std::floor(a.extent / kTieMm), kb = std::floor(b.extent / kTieMm);
    return ka != kb ? ka > kb : a.offset < b.offset;
  });
  std::vector<double> chosen;
  for (const auto& c : candidates) {
    const bool apart = std::all_of(chosen.begin(), chosen.end(), [&](double a) {
      return std::abs(wrap_angle(a - c.azimuth)) >= 2.0 * half_width_rad;
    });
    if (apart) chosen.push_back(c.azimuth);
    if (chosen.size() == 8) break;
  }
  if (chosen.empty()) chosen.push_back(arc_middle);
  return chosen;
}

struct SectionPoint {
  Vec2 rz;
  Vec2 normal;  // unit, in the (r, z) half-plane
};

// The section slab around `azimuth`, without radial fracture faces (normals mostly along the
// circumference, so little of them is left in the (r, z) half-plane).
std::vector<SectionPoint> section_slab(const std::vector<CylPoint>& pts, double azimuth,
                                       double half_width) {
  std::vector<SectionPoint> section;
  for (const auto& p : pts) {
    if (std::abs(wrap_angle(p.phi - azimuth)) > half_width) continue;
    const Vec2 n(p.n_r, p.n_h);
    if (n.norm() < 0.7) continue;
    section.push_back({{p.r, p.h}, n.normalized()});
  }
  return section;
}

// Skin points have a partner on the opposite skin a wall thickness away, straight through the wall
// along -normal. Lip and fracture faces look through the wall lengthwise: their partner (if any)
// is far. Returns each point's distance through the wall (infinity: no partner). Brute force: a
// section holds a few thousand points, and no library ray-casts into unorganised points.
std::vector<double> through_wall(const std::vector<SectionPoint>& section) {
  std::vector<double> through(section.size(), std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < section.size(); ++i) {
    const auto& a = section[i];
    for (const auto& b : section) {
      if (a.normal.dot(b.normal) > -0.7) continue;
      const Vec2 v = b.rz - a.rz;
      const double t = -v.dot(a.normal);
      if (t < 0.3 || t >= through[i]) continue;
      if ((v + t * a.normal).norm() <= std::max(0.5, 0.1 * t)) through[i] = t;
    }
  }
  return through;
}

// The typical wall thickness: the median finite distance through the wall; nullopt if none.
std::optional<double> median_through(const std::vector<double>& through) {
  std::vector<double> finite;
  for (double t : through) {
    if (std::isfinite(t)) finite.push_back(t);
  }
  if (finite.empty()) return std::nullopt;
  std::nth_element(finite.begin(), finite.begin() + finite.size() / 2, finite.end());
  return finite[finite.size() / 2];
}

// The points of the two skins: those with a partner between half and twice the typical wall
// thickness away. The lower bound drops the faces across the wall's ends that happen to look at a
// steep groove flank a few millimetres away (a lip's top, a break's face).
std::vector<SectionPoint> keep_skin_points(const std::vector<SectionPoint>& section) {
  const auto through = through_wall(section);
  const auto wall = median_through(through);
  if (!wall) return {};
  const double low = 0.5 * *wall, high = 2.0 * *wall + 0.5;
  std::vector<SectionPoint> kept;
  for (std::size_t i = 0; i < section.size(); ++i) {
    if (through[i] >= low && through[i] <= high) kept.push_back(section[i]);
  }
  return kept;
}

// Which skin: the normal line of a surface of revolution meets the axis in front of an inner-skin
// point (normal towards the axis, n_r < 0) and behind an outer-skin point. Where the wall is near
// horizontal (|n_r| small) the side is decided by n_z: an upward face is the inside (a floor, the
// top of a flange), a downward face the outside (an underside). A near-horizontal closed shoulder
// is the known exception of this first rule.
bool is_outer(const Vec2& n) { return n.x() > 0.2 || (std::abs(n.x()) <= 0.2 && n.y() < 0.0); }

// Geodesic distances over the graph of points closer than `link_mm`, from `source`.
std::vector<double> geodesic_from(const std::vector<std::vector<std::pair<int, double>>>& graph,
                                  int source) {
  std::vector<double> dist(graph.size(), std::numeric_limits<double>::infinity());
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
  dist[source] = 0.0;
  queue.push({0.0, source});
  while (!queue.empty()) {
    const auto [d, u] = queue.top();
    queue.pop();
    if (d > dist[u]) continue;
    for (const auto& [v, w] : graph[u]) {
      if (d + w < dist[v]) {
        dist[v] = d + w;
        queue.push({dist[v], v});
      }
    }
  }
  return dist;
}

int farthest(const std::vector<double>& dist) {
  int best = -1;
  for (int i = 0; i < static_cast<int>(dist.size()); ++i) {
    if (std::isfinite(dist[i]) && (best < 0 || dist[i] > dist[best])) best = i;
  }
  return best;
}

// Where a skin's curve is followed from: its highest point, the top of the curve's main piece.
// The graph may fall into pieces: a scan hole on either skin leaves a gap in the skin points, and
// stray points of the other faces that pass the skin filter (a lip's top facing a groove's flank
// across the wall) form small pieces of their own. The highest point is therefore taken among the
// pieces with at least kMainPiece of the largest one's points: a stray piece started from would
// draw the skin as a chord of itself; between the substantial pieces of a holed skin, the highest
// is the one that carries the rim.
int sweep_start(const std::vector<Vec2>& pts,
                const std::vector<std::vector<std::pair<int, double>>>& graph) {
  constexpr double kMainPiece = 0.25;
  std::vector<int> piece(graph.size(), -1);
  std::vector<int> size;
  for (int seed = 0; seed < static_cast<int>(graph.size()); ++seed) {
    if (piece[seed] >= 0) continue;
    const int label = static_cast<int>(size.size());
    size.push_back(0);
    std::vector<int> stack{seed};
    piece[seed] = label;
    while (!stack.empty()) {
      const int u = stack.back();
      stack.pop_back();
      ++size[label];
      for (const auto& [v, w] : graph[u]) {
        if (piece[v] < 0) {
          piece[v] = label;
          stack.push_back(v);
        }
      }
    }
  }
  const int largest = *std::max_element(size.begin(), size.end());
  int top = -1;
  for (int i = 0; i < static_cast<int>(pts.size()); ++i) {
    if (size[piece[i]] >= kMainPiece * largest && (top < 0 || pts[i].y() > pts[top].y())) top = i;
  }
  return top;
}

// One skin's points → an ordered polyline from the base end to the rim end. The points lie along a
// curve, so the curve's two ends are found by a double sweep of geodesic distances (the farthest
// point from anywhere is an end; the farthest from that the other end); points are then binned by
// geodesic distance from the lower end and averaged, and the vertices smoothed.
Polyline2 skin_polyline(const std::vector<Vec2>& pts) {
  constexpr double kLinkMm = 2.0, kStepMm = 1.0;
  if (pts.size() < 3) return {};
  pcl::PointCloud<pcl::PointXYZ>::Ptr flat(new pcl::PointCloud<pcl::PointXYZ>);
  for (const auto& p : pts) flat->push_back(pcl::PointXYZ(float(p.x()), float(p.y()), 0.0f));
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  tree.setInputCloud(flat);
  std::vector<std::vector<std::pair<int, double>>> graph(pts.size());
  std::vector<int> found;
  std::vector<float> sq;
  for (int i = 0; i < static_cast<int>(pts.size()); ++i) {
    tree.radiusSearch((*flat)[i], kLinkMm, found, sq);
    for (std::size_t k = 0; k < found.size(); ++k) {
      if (found[k] != i) graph[i].push_back({found[k], std::sqrt(double(sq[k]))});
    }
  }
  const int start = sweep_start(pts, graph);
  const int end_a = farthest(geodesic_from(graph, start));
  std::vector<double> from_a = geodesic_from(graph, end_a);
  const int end_b = farthest(from_a);
  const std::vector<double> s =
      pts[end_a].y() <= pts[end_b].y() ? from_a : geodesic_from(graph, end_b);

  const double length = s[pts[end_a].y() <= pts[end_b].y() ? end_b : end_a];
  const int bins = static_cast<int>(length / kStepMm) + 1;
  std::vector<Vec2> sum(bins, Vec2::Zero());
  std::vector<int> count(bins, 0);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (!std::isfinite(s[i])) continue;
    const int b = std::min(bins - 1, static_cast<int>(s[i] / kStepMm));
    sum[b] += pts[i];
    ++count[b];
  }
  std::vector<Vec2> vertices;
  for (int b = 0; b < bins; ++b) {
    if (count[b] > 0) vertices.push_back(sum[b] / count[b]);
  }
  Polyline2 out;
  for (std::size_t k = 0; k < vertices.size(); ++k) {
    // 3-tap moving average inside; the two ends stay where they are measured.
    const Vec2 v = (k == 0 || k + 1 == vertices.size())
                       ? vertices[k]
                       : Vec2((vertices[k - 1] + 2.0 * vertices[k] + vertices[k + 1]) / 4.0);
    out.push_back({v.x(), v.y()});
  }
  return out;
}

Vec2 as_vec(const std::array<double, 2>& a) { return {a[0], a[1]}; }

// The distance from p to a polyline, and whether its nearest point lies inside the polyline (not
// at one of its two end vertices). Brute force: profiles have a few hundred vertices.
struct Nearest {
  double distance = std::numeric_limits<double>::infinity();
  bool interior = false;
};
Nearest nearest_on(const Polyline2& line, const Vec2& p) {
  Nearest best;
  for (std::size_t k = 0; k + 1 < line.size(); ++k) {
    const Vec2 a = as_vec(line[k]), b = as_vec(line[k + 1]);
    const Vec2 ab = b - a;
    const double t = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-12), 0.0, 1.0);
    const double d = (a + t * ab - p).norm();
    if (d < best.distance) {
      best.distance = d;
      best.interior = !((k == 0 && t == 0.0) || (k + 2 == line.size() && t == 1.0));
    }
  }
  return best;
}

// Distances from the outer curve's vertices to the inner curve, where the perpendicular foot lies
// inside the inner curve (at the broken ends the nearest inner point is an end point, not across
// the wall).
WallThickness wall_thickness(const Polyline2& outer, const Polyline2& inner) {
  WallThickness w;
  if (outer.size() < 2 || inner.size() < 2) return w;
  double sum = 0.0;
  int n = 0;
  w.min = std::numeric_limits<double>::infinity();
  for (const auto& o : outer) {
    const Nearest across = nearest_on(inner, as_vec(o));
    if (!across.interior) continue;
    w.min = std::min(w.min, across.distance);
    w.max = std::max(w.max, across.distance);
    sum += across.distance;
    ++n;
  }
  if (n == 0) return {};
  w.mean = sum / n;
  return w;
}

// The aggregate profile (Profile::aggregate_*): the skin points of all azimuths, mapped into the
// half-plane, through the same skin filter and curve follower as one section. At most
// kAggregatePoints points, evenly strided (the skin filter is quadratic in the points).
void aggregate_profile(const std::vector<CylPoint>& pts, Profile& profile) {
  constexpr std::size_t kAggregatePoints = 4000;
  std::vector<SectionPoint> all;
  const std::size_t stride = std::max<std::size_t>(1, pts.size() / kAggregatePoints);
  for (std::size_t i = 0; i < pts.size(); i += stride) {
    const Vec2 n(pts[i].n_r, pts[i].n_h);
    if (n.norm() >= 0.7) all.push_back({{pts[i].r, pts[i].h}, n.normalized()});
  }
  std::vector<Vec2> outer_pts, inner_pts;
  for (const auto& sp : keep_skin_points(all)) {
    (is_outer(sp.normal) ? outer_pts : inner_pts).push_back(sp.rz);
  }
  profile.aggregate_outer = skin_polyline(outer_pts);
  profile.aggregate_inner = skin_polyline(inner_pts);
  std::vector<double> distances;
  for (const auto& [skin, line] : {std::pair{&outer_pts, &profile.aggregate_outer},
                                   std::pair{&inner_pts, &profile.aggregate_inner}}) {
    if (line->size() < 2) continue;
    for (const Vec2& p : *skin) {
      const Nearest n = nearest_on(*line, p);
      if (n.interior) distances.push_back(n.distance);
    }
  }
  if (distances.empty()) return;
  std::nth_element(distances.begin(), distances.begin() + distances.size() / 2, distances.end());
  profile.aggregate_spread_mm = 1.4826 * distances[distances.size() / 2];
}

// Capacity: the solid of revolution under the inner curve, ∮ π r² dz over the closed loop
// (inner curve up to the rim, across the mouth, down the axis); each segment is a frustum.
double volume_under_inner_mm3(const Polyline2& inner) {
  double v = 0.0;
  for (std::size_t k = 0; k + 1 < inner.size(); ++k) {
    const double r1 = inner[k][0], r2 = inner[k + 1][0];
    v += M_PI / 3.0 * (r1 * r1 + r1 * r2 + r2 * r2) * (inner[k + 1][1] - inner[k][1]);
  }
  return std::abs(v);
}

Analysis analyse_about(const Cloud& sherd, const axis::AxisEstimate& axis, const Params& params,
                       const Orientation* fixed);
MeasurementSds propagate_sds(const Cloud& sherd, const Analysis& base, const Params& params);

}  // namespace

Analysis analyse(const Cloud& sherd, const axis::AxisEstimate& axis, const Params& params) {
  if (!axis.found) {
    throw InputError(
        fmt::format("profile: the sherd has no axis ({}); a profile needs a found "
                    "axis, skip this sherd or estimate its axis first",
                    axis.reason));
  }
  if (!sherd.has_normals()) {
    throw InputError("profile: the sherd has no normals; compute normals before profile analysis");
  }
  for (std::size_t i = 0; i < sherd.size(); ++i) {
    if (!sherd.points[i].allFinite() || !sherd.normals[i].allFinite()) {
      throw InputError(
          fmt::format("profile: point {} of {} has a non-finite coordinate or normal; "
                      "remove invalid points before processing",
                      i, sherd.size()));
    }
  }
  if (sherd.size() < 50) {
    throw ProcessingError(
        fmt::format("profile: only {} points in the sherd, at least 50 needed", sherd.size()));
  }

  Analysis result = analyse_about(sherd, axis, params, nullptr);
  if (params.propagate_sds && (axis.angle_sd_deg > 0.0 || axis.offset_sd_mm > 0.0)) {
    result.measurement_sds = propagate_sds(sherd, result, params);
  }
  return result;
}

namespace {

// The analysis about `axis`: oriented by the ends' shapes, or, with `fixed`, as `fixed` says
// (about a perturbed axis the orientation stays that of the unperturbed one).
Analysis analyse_about(const Cloud& sherd, const axis::AxisEstimate& axis, const Params& params,
                       const Orientation* fixed) {
  // Provisional frame: orientation first, then the final frame with z from base to rim.
  Frame frame = frame_about(axis.point, axis.direction);
  std::vector<CylPoint> pts = cylindrical(sherd, frame);
  auto sherd_arc = [&] {
    std::vector<double> phis;
    for (const auto& p : pts) phis.push_back(p.phi);
    return angular_coverage(phis, median_radius(pts));
  };
  Coverage arc = sherd_arc();
  const double half_width = params.section_half_width_deg * kDegToRad;
  // The wall thickness (orientation-free) sets the scale at which an end's face is a lip or a base:
  // from the first candidate section that shows both skins, as for the profile below (with two
  // level ends every azimuth's extent ties, and the best candidate showed none on a test sherd).
  std::optional<double> provisional_wall;
  for (const double azimuth : section_azimuths(pts, half_width, arc.middle_rad)) {
    provisional_wall = median_through(through_wall(section_slab(pts, azimuth, half_width)));
    if (provisional_wall) break;
  }
  if (!provisional_wall) {
    throw ProcessingError(
        "profile: no two skins a wall apart in the section; the scan shows only one "
        "side of the sherd, scan both faces");
  }
  const Orientation orientation = fixed ? *fixed : orient(pts, *provisional_wall, arc.middle_rad);
  if (orientation.flip) {
    frame = frame_about(axis.point, -axis.direction);
    pts = cylindrical(sherd, frame);
    arc = sherd_arc();
  }

  Analysis result;
  result.axis = axis;
  result.axis.direction = frame.z;
  result.rim_up_certain = orientation.certain;
  result.has_rim = orientation.has_rim;
  result.has_base = orientation.has_base;
  result.arc_deg = arc.degrees;

  // The best-preserved section first; where the scan misses a skin there (a shadowed strip), the
  // next candidate section.
  std::string missing;
  double section_top = -std::numeric_limits<double>::infinity();  // highest point of the section
  for (const double azimuth : section_azimuths(pts, half_width, arc.middle_rad)) {
    const std::vector<SectionPoint> section = section_slab(pts, azimuth, half_width);
    std::vector<Vec2> outer_pts, inner_pts;
    for (const auto& sp : keep_skin_points(section)) {
      (is_outer(sp.normal) ? outer_pts : inner_pts).push_back(sp.rz);
    }
    result.profile.outer = skin_polyline(outer_pts);
    result.profile.inner = skin_polyline(inner_pts);
    if (result.profile.outer.size() >= 2 && result.profile.inner.size() >= 2) {
      result.profile.section = result.profile.outer;
      result.profile.section.insert(result.profile.section.end(), result.profile.inner.rbegin(),
                                    result.profile.inner.rend());
      result.profile.section_angle_rad = wrap_angle(azimuth - arc.middle_rad);
      const Vec3d section_x = std::cos(azimuth) * frame.x + std::sin(azimuth) * frame.y;
      result.sherd_to_world.linear().col(0) = section_x;
      result.sherd_to_world.linear().col(1) = frame.z.cross(section_x);
      result.sherd_to_world.linear().col(2) = frame.z;
      result.sherd_to_world.translation() = frame.origin;
      for (const auto& p : section) section_top = std::max(section_top, p.rz.y());
      missing.clear();
      break;
    }
    if (missing.empty()) {
      missing = fmt::format("the best section (azimuth {:.1f} deg, {} points) shows no {} skin",
                            azimuth / kDegToRad, section.size(),
                            result.profile.outer.size() < 2 ? "outer" : "inner");
    }
  }
  if (!missing.empty()) {
    throw ProcessingError(
        fmt::format("profile: {}, nor does any other candidate section; the scan misses "
                    "one side of the sherd: scan both faces",
                    missing));
  }

  if (!fixed) aggregate_profile(pts, result.profile);

  Measurements& m = result.measurements;
  double h_min = std::numeric_limits<double>::infinity(), h_max = -h_min;
  for (const auto& p : pts) {
    h_min = std::min(h_min, p.h);
    h_max = std::max(h_max, p.h);
  }
  m.height_mm = h_max - h_min;
  const Polyline2& outer = result.profile.outer;
  for (const auto& v : outer) m.max_diameter_mm = std::max(m.max_diameter_mm, 2.0 * v[0]);
  m.wall_thickness_mm = wall_thickness(outer, result.profile.inner);

  if (result.has_rim) {
    // The rim is where the outer wall meets the lip: the widest outer-skin point within
    // rim_band_mm below the highest point of the section (the lip's apex, which the skin filter
    // leaves out of both skins).
    const double top = section_top;
    auto rim = outer.end();
    for (auto it = outer.begin(); it != outer.end(); ++it) {
      if ((*it)[1] >= top - params.rim_band_mm && (rim == outer.end() || (*it)[0] > (*rim)[0]))
        rim = it;
    }
    if (rim == outer.end()) {
      rim = std::max_element(outer.begin(), outer.end(),
                             [](const auto& a, const auto& b) { return a[1] < b[1]; });
    }
    m.rim_diameter_mm = 2.0 * (*rim)[0];
    std::vector<double> rim_phi;
    for (const auto& p : pts) {
      if (p.h >= h_max - params.rim_band_mm) rim_phi.push_back(p.phi);
    }
    m.rim_percent = angular_coverage(rim_phi, (*rim)[0]).degrees / 360.0 * 100.0;
    // Inclination of the outer wall over the last ~10 mm below the rim: 0 = vertical,
    // positive = flaring outwards.
    constexpr double kRimSpanMm = 10.0;
    const Vec2 rim_vertex = as_vec(*rim);
    for (auto it = std::make_reverse_iterator(rim); it != outer.rend(); ++it) {
      const Vec2 below = as_vec(*it);
      if ((rim_vertex - below).norm() >= kRimSpanMm || std::next(it) == outer.rend()) {
        const Vec2 d = rim_vertex - below;
        if (d.norm() > 1.0) m.rim_inclination_deg = std::atan2(d.x(), d.y()) / kDegToRad;
        break;
      }
    }
  }
  if (result.has_base) {
    const double lowest =
        std::min_element(outer.begin(), outer.end(), [](const auto& a, const auto& b) {
          return a[1] < b[1];
        })->at(1);
    double base_r = 0.0;
    for (const auto& v : outer) {
      if (v[1] <= lowest + params.rim_band_mm) base_r = std::max(base_r, v[0]);
    }
    m.base_diameter_mm = 2.0 * base_r;
  }
  constexpr double kCompleteArcDeg = 355.0;
  if (arc.degrees >= kCompleteArcDeg && result.has_base && result.has_rim &&
      result.profile.inner.size() >= 2) {
    m.volume_ml = volume_under_inner_mm3(result.profile.inner) / 1000.0;
  }
  return result;
}

MeasurementSds propagate_sds(const Cloud& sherd, const Analysis& base, const Params& params) {
  const Vec3d d = base.axis.direction.normalized();
  const Vec3d e1 = frame_about(Vec3d::Zero(), d).x, e2 = d.cross(e1);
  const double tilt = std::tan(base.axis.angle_sd_deg * kDegToRad / std::sqrt(2.0));
  const double shift = base.axis.offset_sd_mm / std::sqrt(2.0);
  const Orientation fixed{.flip = false,
                          .certain = base.rim_up_certain,
                          .has_rim = base.has_rim,
                          .has_base = base.has_base};
  const Measurements& m0 = base.measurements;
  double var_rim = 0, var_base = 0, var_percent = 0, var_incl = 0, var_max = 0, var_h = 0,
         var_wall = 0;
  auto add = [](double& var, const std::optional<double>& a, const std::optional<double>& b) {
    if (a && b) var += (*a - *b) * (*a - *b);
  };
  for (int k = 0; k < 4; ++k) {
    axis::AxisEstimate perturbed = base.axis;
    const Vec3d across = k % 2 == 0 ? e1 : e2;
    if (k < 2) {
      perturbed.direction = (d + tilt * across).normalized();
    } else {
      perturbed.point += shift * across;
    }
    Analysis a;
    try {
      a = analyse_about(sherd, perturbed, params, &fixed);
    } catch (const ProcessingError&) {
      continue;  // no section about this axis: the others still tell
    }
    const Measurements& m = a.measurements;
    add(var_rim, m0.rim_diameter_mm, m.rim_diameter_mm);
    add(var_base, m0.base_diameter_mm, m.base_diameter_mm);
    add(var_percent, m0.rim_percent, m.rim_percent);
    add(var_incl, m0.rim_inclination_deg, m.rim_inclination_deg);
    add(var_max, m0.max_diameter_mm, m.max_diameter_mm);
    add(var_h, m0.height_mm, m.height_mm);
    add(var_wall, m0.wall_thickness_mm.mean, m.wall_thickness_mm.mean);
  }
  auto sd_if = [](const std::optional<double>& value, double var) {
    return value ? std::optional<double>(std::sqrt(var)) : std::nullopt;
  };
  MeasurementSds sds;
  sds.rim_diameter_mm = sd_if(m0.rim_diameter_mm, var_rim);
  sds.base_diameter_mm = sd_if(m0.base_diameter_mm, var_base);
  sds.rim_percent = sd_if(m0.rim_percent, var_percent);
  sds.rim_inclination_deg = sd_if(m0.rim_inclination_deg, var_incl);
  sds.max_diameter_mm = std::sqrt(var_max);
  sds.height_mm = std::sqrt(var_h);
  sds.wall_thickness_mean_mm = std::sqrt(var_wall);
  return sds;
}

}  // namespace

}  // namespace sherd::profile
