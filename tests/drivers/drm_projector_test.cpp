// The DRM/KMS projector where no display can be driven (CI: no /dev/dri; a file that is no KMS
// device): one clear DeviceError naming the device and what to do.
#include <gtest/gtest.h>

#include <string>

#include "core/errors.h"
#include "drivers/drm_projector.h"

namespace {

std::string failure(const std::string& device) {
  try {
    sherd::drivers::DrmProjector projector({device, ""});
  } catch (const sherd::DeviceError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(DrmProjector, AMissingDeviceIsNoDisplay) {
  const std::string message = failure("/nonexistent/dri/card7");
  EXPECT_NE(message.find("/nonexistent/dri/card7"), std::string::npos) << message;
  EXPECT_NE(message.find("no display device"), std::string::npos) << message;
}

TEST(DrmProjector, ADeviceThatDrivesNoOutputsIsNotKms) {
  const std::string message = failure("/dev/null");
  EXPECT_NE(message.find("/dev/null is not a KMS display device"), std::string::npos) << message;
}
