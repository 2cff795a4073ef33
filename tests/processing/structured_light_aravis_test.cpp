// The Gray-code sequence through the real transport: the simulated projector shows each pattern,
// Aravis's simulated GigE camera (127.0.0.1, UDP 3956) films it, the Aravis driver receives it and
// the decoder decodes it. The camera looks straight at the projector's image at half its
// resolution, so camera pixel (u, v) sees projector pixel (2u, 2v): that is the truth.
#include <arv.h>
#include <gtest/gtest.h>

#include <memory>

#include "drivers/aravis_camera.h"
#include "drivers/projector.h"
#include "processing/structured_light/gray_code.h"
#include "processing/structured_light/scanner.h"

namespace sl = sherd::structured_light;

namespace {

void film_projector(ArvBuffer* buffer, void* data, guint32, guint32, ArvPixelFormat) {
  const auto* projector = static_cast<const sherd::drivers::SimulatedProjector*>(data);
  auto* pixels =
      static_cast<std::uint8_t*>(const_cast<void*>(arv_buffer_get_data(buffer, nullptr)));
  const int width = arv_buffer_get_image_width(buffer),
            height = arv_buffer_get_image_height(buffer);
  for (int v = 0; v < height; ++v)
    for (int u = 0; u < width; ++u)
      pixels[std::size_t(v) * width + u] = projector->lit(2 * u, 2 * v);
}

// Aravis's fake GigE camera filming the simulated 1024×768 projector, and the Aravis driver
// opened on it at 512×384 (closed before the fake camera goes).
class StructuredLightThroughAravis : public ::testing::Test {
 protected:
  void SetUp() override {
    fake_ = arv_gv_fake_camera_new("127.0.0.1", "SHERDSL");
    ASSERT_TRUE(arv_gv_fake_camera_is_running(fake_)) << "cannot bind 127.0.0.1:3956";
    arv_fake_camera_set_fill_pattern(arv_gv_fake_camera_get_fake_camera(fake_), film_projector,
                                     &projector);
    sherd::drivers::AravisCameraSettings settings;
    settings.id = "127.0.0.1";
    settings.width = 512;
    settings.height = 384;
    camera = std::make_unique<sherd::drivers::AravisCamera>(settings);
  }
  void TearDown() override {
    camera.reset();
    g_object_unref(fake_);
    arv_shutdown();
  }

  sherd::drivers::SimulatedProjector projector{1024, 768};
  std::unique_ptr<sherd::drivers::AravisCamera> camera;

 private:
  ArvGvFakeCamera* fake_ = nullptr;
};

}  // namespace

TEST_F(StructuredLightThroughAravis, EveryCameraPixelDecodesToTheProjectorPixelItSees) {
  const sl::GrayCodePatterns patterns{1024, 768};
  std::vector<sl::GreyImage> frames;
  for (int f = 0; f < patterns.frame_count(); ++f) {
    projector.show(patterns.frame(f).pixels);
    auto frame = camera->capture();
    frames.push_back({frame.width, frame.height, std::move(frame.pixels)});
  }
  const sl::DecodedMap map = sl::decode(patterns, frames, {});
  ASSERT_EQ(map.decoded_count(), 512u * 384u);
  std::size_t wrong = 0;
  for (int v = 0; v < 384; ++v)
    for (int u = 0; u < 512; ++u) {
      const std::size_t i = std::size_t(v) * 512 + u;
      wrong += map.column[i] != 2 * u || map.row[i] != 2 * v;
    }
  EXPECT_EQ(wrong, 0u);
}

// The whole scanner through the real transport. The calibration below makes the filmed image a
// plane: camera f 500 px, principal point (256, 192); projector f 1000 px, principal point
// (612, 384), 100 mm to the camera's right (X_p = X_c − 100). A point of the plane Z = 1000 mm
// seen by camera pixel u lands on projector column 1000·((u − 256)·2 − 100)/1000 + 612 = 2u (and
// row 2v): exactly what the fake camera films. Truth: every pixel at Z = 1000 mm,
// X = (u − 256)·2 mm, Y = (v − 192)·2 mm.
TEST_F(StructuredLightThroughAravis, TheScannerSeesThePlaneTheCalibrationImplies) {
  sl::ProCamCalibration calibration;
  calibration.camera.width = 512;
  calibration.camera.height = 384;
  calibration.camera.matrix << 500, 0, 256, 0, 500, 192, 0, 0, 1;
  calibration.projector.width = 1024;
  calibration.projector.height = 768;
  calibration.projector.matrix << 1000, 0, 612, 0, 1000, 384, 0, 0, 1;
  calibration.translation_mm = Eigen::Vector3d(-100, 0, 0);
  sl::StructuredLightScanner scanner(*camera, projector, calibration);
  EXPECT_NE(scanner.describe().find("SHERDSL"), std::string::npos) << scanner.describe();
  const sherd::OrganisedView view = scanner.capture();
  ASSERT_EQ(view.width, 512);
  ASSERT_EQ(view.height, 384);
  view.check("structured light", 0);
  double worst = 0;
  std::size_t valid = 0;
  for (int v = 0; v < 384; ++v)
    for (int u = 0; u < 512; ++u) {
      const std::size_t i = std::size_t(v) * 512 + u;
      if (!view.valid[i]) continue;
      ++valid;
      const Eigen::Vector3d truth((u - 256) * 2.0, (v - 192) * 2.0, 1000.0);
      worst = std::max(worst, (view.points[i].cast<double>() - truth).norm());
    }
  EXPECT_EQ(valid, 512u * 384u);
  EXPECT_LT(worst, 0.01);  // float arithmetic only
}
