// What the two axis fits of sherd_axis share (axis.cpp: normal lines, refined on line-to-line
// distances; refine.cpp: profile consistency): the random subsample they work on, the axis as a
// line, its four degrees of freedom about a start line and the Levenberg-Marquardt call over them.
// Internal to sherd_axis: not part of its public header axis.h.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <random>
#include <unsupported/Eigen/NonLinearOptimization>
#include <unsupported/Eigen/NumericalDiff>
#include <vector>

#include "core/types.h"

namespace sherd::axis::detail {

// At most `most` of the sherd's points (a random choice when it has more) and their centroid.
struct Subsample {
  std::vector<std::uint32_t> chosen;
  Vec3d centroid = Vec3d::Zero();
};
inline Subsample subsample(const Cloud& sherd, std::size_t most, std::mt19937_64& rng) {
  Subsample s;
  s.chosen.resize(sherd.size());
  std::iota(s.chosen.begin(), s.chosen.end(), 0u);
  if (s.chosen.size() > most) {
    std::shuffle(s.chosen.begin(), s.chosen.end(), rng);
    s.chosen.resize(most);
  }
  for (auto i : s.chosen) s.centroid += sherd.points[i].cast<double>();
  s.centroid /= static_cast<double>(s.chosen.size());
  return s;
}

struct Line {
  Vec3d point;      // any point on the line
  Vec3d direction;  // unit
};

// Any unit vector perpendicular to `v` (unit).
inline Vec3d any_perpendicular(const Vec3d& v) {
  const Vec3d helper = std::abs(v.x()) < 0.9 ? Vec3d::UnitX() : Vec3d::UnitY();
  return v.cross(helper).normalized();
}

// x = (two tilts of the direction, two shifts of the point), both along e1, e2 in the plane
// perpendicular to the start direction; x = 0 is the start line.
class LineAboutStart {
 public:
  explicit LineAboutStart(const Line& start)
      : start_(start), e1_(any_perpendicular(start.direction)), e2_(start.direction.cross(e1_)) {}
  Line at(const Eigen::VectorXd& x) const {
    return {start_.point + x[2] * e1_ + x[3] * e2_,
            (start_.direction + x[0] * e1_ + x[1] * e2_).normalized()};
  }

 private:
  Line start_;
  Vec3d e1_, e2_;
};

// Levenberg-Marquardt with a numerical Jacobian over the 4 parameters, from x = 0 (the start
// line) or from `x` as given; returns the minimum (not finite when the fit broke down).
template <class Functor>
Eigen::VectorXd minimise_line(const Functor& functor, int max_evaluations,
                              Eigen::VectorXd x = Eigen::VectorXd::Zero(4)) {
  Eigen::NumericalDiff<Functor> numeric(functor);
  Eigen::LevenbergMarquardt<Eigen::NumericalDiff<Functor>> solver(numeric);
  solver.parameters.maxfev = max_evaluations;
  solver.minimize(x);
  return x;
}

}  // namespace sherd::axis::detail
