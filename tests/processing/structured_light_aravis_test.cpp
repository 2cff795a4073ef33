// The Gray-code sequence through the real transport: the simulated projector shows each pattern,
// Aravis's simulated GigE camera (127.0.0.1, UDP 3956) films it, the Aravis driver receives it and
// the decoder decodes it. The camera looks straight at the projector's image at half its
// resolution, so camera pixel (u, v) sees projector pixel (2u, 2v): that is the truth.
#include <arv.h>
#include <gtest/gtest.h>

#include "drivers/aravis_camera.h"
#include "drivers/projector.h"
#include "processing/structured_light/gray_code.h"

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

}  // namespace

TEST(StructuredLightThroughAravis, EveryCameraPixelDecodesToTheProjectorPixelItSees) {
  sherd::drivers::SimulatedProjector projector(1024, 768);
  ArvGvFakeCamera* fake = arv_gv_fake_camera_new("127.0.0.1", "SHERDSL");
  ASSERT_TRUE(arv_gv_fake_camera_is_running(fake)) << "cannot bind 127.0.0.1:3956";
  arv_fake_camera_set_fill_pattern(arv_gv_fake_camera_get_fake_camera(fake), film_projector,
                                   &projector);
  {
    sherd::drivers::AravisCameraSettings settings;
    settings.id = "127.0.0.1";
    settings.width = 512;
    settings.height = 384;
    sherd::drivers::AravisCamera camera(settings);
    const sl::GrayCodePatterns patterns{1024, 768};
    std::vector<sl::GreyImage> frames;
    for (int f = 0; f < patterns.frame_count(); ++f) {
      projector.show(patterns.frame(f).pixels);
      auto frame = camera.capture();
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
  g_object_unref(fake);
  arv_shutdown();
}
