// The scanner's projector: shows one 8-bit grey pattern at a time, full screen.
//
// Implementations: SimulatedProjector (below, for tests and the simulated station) and
// DrmProjector (drm_projector.h: a projector attached as a display, through DRM/KMS).
#pragma once

#include <cstdint>
#include <mutex>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace sherd::drivers {

class Projector {
 public:
  virtual ~Projector() = default;
  virtual std::string describe() const = 0;
  virtual int width() const = 0;
  virtual int height() const = 0;
  // Shows `pixels` (width() × height(), row-major) and returns once it is on screen.
  virtual void show(std::span<const std::uint8_t> pixels) = 0;
};

// Holds the pattern being shown, for a simulated camera to look at (from any thread).
class SimulatedProjector : public Projector {
 public:
  SimulatedProjector(int width, int height)
      : width_(width), height_(height), shown_(std::size_t(width) * height, 0) {}
  std::string describe() const override { return "simulated projector"; }
  int width() const override { return width_; }
  int height() const override { return height_; }
  void show(std::span<const std::uint8_t> pixels) override {
    if (pixels.size() != shown_.size())
      throw std::invalid_argument("simulated projector: pattern size does not match the projector");
    std::lock_guard lock(mutex_);
    shown_.assign(pixels.begin(), pixels.end());
  }
  // The whole pattern shown now (a copy: the camera thread reads while the scanner shows).
  std::vector<std::uint8_t> shown() const {
    std::lock_guard lock(mutex_);
    return shown_;
  }
  // The projector pixel (x, y) as lit now.
  std::uint8_t lit(int x, int y) const {
    std::lock_guard lock(mutex_);
    return shown_[std::size_t(y) * width_ + x];
  }

 private:
  int width_, height_;
  mutable std::mutex mutex_;
  std::vector<std::uint8_t> shown_;
};

}  // namespace sherd::drivers
