// The stepper's trapezoidal speed profile: accelerate, cruise, brake (or, when the way is too
// short to reach full speed, a triangle). Shared by the driver (how long to wait for a move) and
// the simulators (how long a move takes). Any consistent unit of angle and time.
#pragma once

#include <algorithm>
#include <cmath>

namespace sherd::drivers {

// Time to travel `d` (≥ 0) with speed limit v and acceleration a.
inline double trapezoid_seconds(double d, double v, double a) {
  return d >= v * v / a ? d / v + v / a : 2.0 * std::sqrt(d / a);
}

// Distance covered `t` seconds into that motion.
inline double trapezoid_distance(double t, double d, double v, double a) {
  const double T = trapezoid_seconds(d, v, a);
  if (t <= 0) return 0.0;
  if (t >= T) return d;
  const double ramp = std::min(v / a, T / 2.0);
  const double peak = a * ramp;
  if (t < ramp) return 0.5 * a * t * t;
  if (t > T - ramp) return d - 0.5 * a * (T - t) * (T - t);
  return 0.5 * peak * ramp + peak * (t - ramp);
}

}  // namespace sherd::drivers
