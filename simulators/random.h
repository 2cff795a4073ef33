// Deterministic random numbers for the simulators. The std:: distributions are implementation-
// defined (their output differs between libstdc++ versions), so a seed must give the same scene
// everywhere: only the engine (std::mt19937_64, fully specified by the standard) is used, and the
// few distributions we need are written here.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>

namespace sherd::sim {

class Rng {
 public:
  explicit Rng(std::uint64_t seed) : engine_(seed) {}

  // Uniform in [0, 1), 53 random bits.
  double uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  // Uniform integer in [lo, hi].
  int integer(int lo, int hi) {
    return lo + static_cast<int>(uniform() * (hi - lo + 1));
  }
  bool chance(double p) { return uniform() < p; }
  // Standard normal by Box–Muller.
  double normal() {
    const double u1 = 1.0 - uniform();  // (0, 1]: log is finite
    const double u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
  }
  // A child generator with its own stream, so that adding draws in one part of a scene does not
  // shift every later part.
  Rng fork() { return Rng(engine_()); }

 private:
  std::mt19937_64 engine_;
};

}  // namespace sherd::sim
