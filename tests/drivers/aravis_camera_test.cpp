// The Aravis camera driver against Aravis's own simulated GigE Vision camera on 127.0.0.1: the
// real GVCP control channel and GVSP stream. The fake camera's fill callback writes a known image
// (the truth) into each frame. Binds UDP 3956: the tests run serially (RESOURCE_LOCK).
#include <arv.h>
#include <gtest/gtest.h>

#include <atomic>

#include "core/errors.h"
#include "drivers/aravis_camera.h"

namespace {

using sherd::drivers::AravisCamera;
using sherd::drivers::AravisCameraSettings;

// Pixel (x, y) of frame n.
std::uint8_t truth(int x, int y, unsigned n) {
  return static_cast<std::uint8_t>(x * 3 + y * 7 + n * 11);
}

struct Fill {
  std::atomic<unsigned> frames{0};
};

void fill(ArvBuffer* buffer, void* data, guint32, guint32, ArvPixelFormat) {
  auto* f = static_cast<Fill*>(data);
  const unsigned n = f->frames++;
  // The fake camera allocates the payload for the current region (Mono8: width × height bytes);
  // the size it reports here is what was received so far (0), so it is not a bound.
  auto* pixels =
      static_cast<std::uint8_t*>(const_cast<void*>(arv_buffer_get_data(buffer, nullptr)));
  const int width = arv_buffer_get_image_width(buffer),
            height = arv_buffer_get_image_height(buffer);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) pixels[size_t(y) * width + x] = truth(x, y, n);
}

class FakeGigECamera : public ::testing::Test {
 protected:
  void SetUp() override {
    fake_ = arv_gv_fake_camera_new("127.0.0.1", "SHERD0");
    ASSERT_NE(fake_, nullptr);
    ASSERT_TRUE(arv_gv_fake_camera_is_running(fake_)) << "cannot bind 127.0.0.1:3956";
    arv_fake_camera_set_fill_pattern(arv_gv_fake_camera_get_fake_camera(fake_), fill, &fill_);
  }
  void TearDown() override {
    if (fake_) g_object_unref(fake_);
    arv_shutdown();
  }
  ArvGvFakeCamera* fake_ = nullptr;
  Fill fill_;
};

TEST_F(FakeGigECamera, TriggeredFramesCarryExactlyTheFilledImage) {
  AravisCameraSettings settings;
  settings.id = "127.0.0.1";
  settings.width = 320;
  settings.height = 240;
  AravisCamera camera(settings);
  EXPECT_NE(camera.describe().find("SHERD0"), std::string::npos) << camera.describe();
  for (int i = 0; i < 5; ++i) {
    const auto frame = camera.capture();
    ASSERT_EQ(frame.width, 320);
    ASSERT_EQ(frame.height, 240);
    ASSERT_EQ(frame.pixels.size(), 320u * 240u);
    // Which fill produced it: the frame's own pixel (0, 0) names n; every other pixel must agree.
    unsigned n = 0;
    while (truth(0, 0, n) != frame.pixels[0]) ++n;
    std::size_t wrong = 0;
    for (int y = 0; y < 240; ++y)
      for (int x = 0; x < 320; ++x) wrong += frame.pixels[size_t(y) * 320 + x] != truth(x, y, n);
    EXPECT_EQ(wrong, 0u) << "frame " << i;
  }
  EXPECT_EQ(camera.incomplete_frames(), 0);
}

// The camera goes away mid-scan (cable pulled): the next capture fails with a DeviceError naming
// the camera, never a stale frame.
TEST_F(FakeGigECamera, ACameraThatGoesAwayFailsTheCaptureCleanly) {
  AravisCameraSettings settings;
  settings.id = "127.0.0.1";
  settings.width = 64;
  settings.height = 48;
  settings.timeout_ms = 500;
  AravisCamera camera(settings);
  EXPECT_EQ(camera.capture().pixels.size(), 64u * 48u);
  g_object_unref(fake_);
  fake_ = nullptr;
  try {
    camera.capture();
    FAIL() << "a frame from a camera that is gone";
  } catch (const sherd::DeviceError& e) {
    EXPECT_NE(std::string(e.what()).find("SHERD0"), std::string::npos) << e.what();
  }
}

TEST_F(FakeGigECamera, AnUnknownCameraIsAClearDeviceError) {
  AravisCameraSettings settings;
  settings.id = "Nobody-NoModel-000";
  try {
    AravisCamera camera(settings);
    FAIL() << "opened";
  } catch (const sherd::DeviceError& e) {
    EXPECT_NE(std::string(e.what()).find("camera not found: Nobody-NoModel-000"), std::string::npos)
        << e.what();
  }
}

}  // namespace

// Hardware trigger: the features land on the camera as asked (read back over GenICam). Nothing
// pulses the fake camera's line, so it sends no frame: the capture fails naming the line.
TEST_F(FakeGigECamera, LineTriggerSetsTheCameraFeaturesAsRequested) {
  AravisCameraSettings settings;
  settings.id = "127.0.0.1";
  settings.width = 64;
  settings.height = 48;
  settings.timeout_ms = 300;
  settings.trigger = AravisCameraSettings::Trigger::kLine;
  settings.trigger_line = "Line0";  // the fake camera's only line
  AravisCamera camera(settings);
  EXPECT_EQ(camera.feature("TriggerMode"), "On");
  EXPECT_EQ(camera.feature("TriggerSource"), "Line0");
  EXPECT_EQ(camera.feature("TriggerActivation"), "RisingEdge");
  EXPECT_EQ(fill_.frames.load(), 0u);
  camera.arm();
  try {
    camera.capture();
    FAIL() << "a frame without a line pulse";
  } catch (const sherd::DeviceError& e) {
    EXPECT_NE(std::string(e.what()).find("no RisingEdge edge came on Line0"), std::string::npos)
        << e.what();
  }
}

TEST_F(FakeGigECamera, ALineTheCameraLacksIsAClearDeviceError) {
  AravisCameraSettings settings;
  settings.id = "127.0.0.1";
  settings.trigger = AravisCameraSettings::Trigger::kLine;
  settings.trigger_line = "Line1";
  try {
    AravisCamera camera(settings);
    FAIL() << "Line1 accepted on a camera without it";
  } catch (const sherd::DeviceError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("no trigger source \"Line1\""), std::string::npos) << message;
    EXPECT_NE(message.find("Line0"), std::string::npos) << message;  // what it has instead
    EXPECT_NE(message.find("trigger_line"), std::string::npos) << message;
  }
}

TEST_F(FakeGigECamera, AnEdgeTheCameraLacksIsAClearDeviceError) {
  AravisCameraSettings settings;
  settings.id = "127.0.0.1";
  settings.trigger = AravisCameraSettings::Trigger::kLine;
  settings.trigger_line = "Line0";
  settings.trigger_activation = "FallingEdge";  // the fake camera knows only RisingEdge
  EXPECT_THROW(AravisCamera camera(settings), sherd::DeviceError);
}
