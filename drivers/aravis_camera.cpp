#include "drivers/aravis_camera.h"

#include <arv.h>
#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <cstring>

#include "core/errors.h"

namespace sherd::drivers {

struct AravisCamera::State {
  AravisCameraSettings settings;
  ArvCamera* camera = nullptr;
  ArvStream* stream = nullptr;
  std::string name;
  std::atomic<bool> control_lost{false};
  int incomplete = 0;
};

namespace {

// Takes ownership of a GError: its message, or `fallback`.
std::string take_message(GError* error, const char* fallback) {
  if (!error) return fallback;
  std::string message = error->message;
  g_error_free(error);
  return message;
}

void on_control_lost(ArvGvDevice*, gpointer data) {
  static_cast<std::atomic<bool>*>(data)->store(true);
}

}  // namespace

AravisCamera::AravisCamera(const AravisCameraSettings& settings) : state_(new State) {
  State& s = *state_;
  s.settings = settings;
  const std::string label = settings.id.empty() ? "the first camera found" : settings.id;
  GError* error = nullptr;
  s.camera = arv_camera_new(settings.id.empty() ? nullptr : settings.id.c_str(), &error);
  if (!s.camera)
    throw DeviceError(
        fmt::format("camera not found: {} ({}); check the cable, its IP address "
                    "and `arv-tool-0.8` on this machine",
                    label, take_message(error, "no such device")));
  auto check = [&](const char* what) {
    if (error)
      throw DeviceError(
          fmt::format("camera {}: cannot set {}: {}", label, what, take_message(error, "")));
  };
  arv_camera_set_pixel_format(s.camera, ARV_PIXEL_FORMAT_MONO_8, &error);
  check("pixel format Mono8");
  if (settings.width > 0 && settings.height > 0) {
    arv_camera_set_region(s.camera, settings.offset_x, settings.offset_y, settings.width,
                          settings.height, &error);
    check("region");
  }
  arv_camera_set_exposure_time(s.camera, settings.exposure_us, &error);
  check("exposure");
  if (arv_camera_is_gain_available(s.camera, nullptr)) {
    arv_camera_set_gain(s.camera, settings.gain_db, &error);
    check("gain");
  }
  arv_camera_set_acquisition_mode(s.camera, ARV_ACQUISITION_MODE_CONTINUOUS, &error);
  check("acquisition mode");
  if (settings.trigger == AravisCameraSettings::Trigger::kSoftware) {
    arv_camera_set_trigger(s.camera, "Software", &error);
    check("software trigger");
  } else {
    guint count = 0;
    const char** sources = arv_camera_dup_available_trigger_sources(s.camera, &count, &error);
    check("trigger source (cannot list them)");
    std::string names;
    bool found = false;
    for (guint i = 0; i < count; ++i) {
      names += (i ? ", " : "") + std::string(sources[i]);
      found |= settings.trigger_line == sources[i];
    }
    g_free(sources);
    if (!found)
      throw DeviceError(fmt::format(
          "camera {}: no trigger source \"{}\" (it has: {}); set [scanner] trigger_line to one "
          "of them, or trigger = \"software\"",
          label, settings.trigger_line, names.empty() ? "none" : names));
    arv_camera_set_trigger(s.camera, settings.trigger_line.c_str(), &error);
    check("hardware trigger");
    if (!arv_camera_is_feature_available(s.camera, "TriggerActivation", nullptr))
      throw DeviceError(fmt::format(
          "camera {}: no TriggerActivation feature, so the edge of {} that starts a frame cannot "
          "be chosen; use trigger = \"software\"",
          label, settings.trigger_line));
    arv_camera_set_string(s.camera, "TriggerActivation", settings.trigger_activation.c_str(),
                          &error);
    check(("TriggerActivation " + settings.trigger_activation).c_str());
  }

  s.stream = arv_camera_create_stream(s.camera, nullptr, nullptr, &error);
  if (!s.stream)
    throw DeviceError(fmt::format("camera {}: cannot open its stream: {}", label,
                                  take_message(error, "unknown error")));
  if (ARV_IS_GV_STREAM(s.stream)) {
    g_object_set(s.stream, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_AUTO, "packet-resend",
                 ARV_GV_STREAM_PACKET_RESEND_ALWAYS, nullptr);
    g_signal_connect(arv_camera_get_device(s.camera), "control-lost", G_CALLBACK(on_control_lost),
                     &s.control_lost);
  }
  const gint payload = arv_camera_get_payload(s.camera, &error);
  check("payload size");
  for (int i = 0; i < std::max(2, settings.buffers); ++i)
    arv_stream_push_buffer(s.stream, arv_buffer_new(payload, nullptr));
  arv_camera_start_acquisition(s.camera, &error);
  check("acquisition start");
  const char* vendor = arv_camera_get_vendor_name(s.camera, nullptr);
  const char* model = arv_camera_get_model_name(s.camera, nullptr);
  const char* serial = arv_camera_get_device_serial_number(s.camera, nullptr);
  s.name =
      fmt::format("{} {} ({})", vendor ? vendor : "?", model ? model : "?", serial ? serial : "?");
}

AravisCamera::~AravisCamera() {
  if (state_->camera) arv_camera_stop_acquisition(state_->camera, nullptr);
  if (state_->stream) g_object_unref(state_->stream);
  if (state_->camera) g_object_unref(state_->camera);
}

std::string AravisCamera::describe() const { return state_->name; }

int AravisCamera::incomplete_frames() const { return state_->incomplete; }

std::string AravisCamera::feature(const std::string& name) const {
  GError* error = nullptr;
  const char* value = arv_camera_get_string(state_->camera, name.c_str(), &error);
  if (error || !value)
    throw DeviceError(fmt::format("camera {}: no feature {}: {}", state_->name, name,
                                  take_message(error, "no value")));
  return value;
}

void AravisCamera::arm() {
  // A frame left over from an earlier trigger would be stale: drop whatever is queued.
  while (ArvBuffer* old = arv_stream_try_pop_buffer(state_->stream))
    arv_stream_push_buffer(state_->stream, old);
}

CameraFrame AravisCamera::capture() {
  State& s = *state_;
  const bool software = s.settings.trigger == AravisCameraSettings::Trigger::kSoftware;
  if (software) arm();  // under a line trigger the wanted frame may already be queued
  for (int attempt = 0; attempt <= s.settings.max_recaptures; ++attempt) {
    if (s.control_lost)
      throw DeviceError(fmt::format("camera {}: link lost; check the cable and power", s.name));
    GError* error = nullptr;
    if (software) arv_camera_software_trigger(s.camera, &error);
    if (error)
      throw DeviceError(
          fmt::format("camera {}: trigger failed: {}", s.name, take_message(error, "")));
    ArvBuffer* buffer =
        arv_stream_timeout_pop_buffer(s.stream, static_cast<guint64>(s.settings.timeout_ms) * 1000);
    if (!buffer) {
      if (s.control_lost)
        throw DeviceError(fmt::format("camera {}: link lost; check the cable and power", s.name));
      if (!software)
        throw DeviceError(fmt::format(
            "camera {}: no frame within {} ms (timeout); no {} edge came on {}: check the "
            "projector's sync cable and output",
            s.name, s.settings.timeout_ms, s.settings.trigger_activation, s.settings.trigger_line));
      throw DeviceError(fmt::format("camera {}: no frame within {} ms of the trigger (timeout)",
                                    s.name, s.settings.timeout_ms));
    }
    if (arv_buffer_get_status(buffer) != ARV_BUFFER_STATUS_SUCCESS) {
      ++s.incomplete;  // missing packets even after resend: trigger again
      arv_stream_push_buffer(s.stream, buffer);
      if (!software)
        throw DeviceError(fmt::format(
            "camera {}: incomplete frame (missing packets) under the hardware trigger, which "
            "cannot be repeated from here; check the network link and the packet size",
            s.name));
      continue;
    }
    CameraFrame frame;
    frame.width = arv_buffer_get_image_width(buffer);
    frame.height = arv_buffer_get_image_height(buffer);
    size_t size = 0;
    const auto* data = static_cast<const std::uint8_t*>(arv_buffer_get_image_data(buffer, &size));
    frame.pixels.assign(data, data + std::min<size_t>(size, size_t(frame.width) * frame.height));
    frame.frame_id = arv_buffer_get_frame_id(buffer);
    frame.timestamp_ns = arv_buffer_get_timestamp(buffer);
    arv_stream_push_buffer(s.stream, buffer);
    return frame;
  }
  throw DeviceError(
      fmt::format("camera {}: {} incomplete frames in a row (missing packets); "
                  "check the network link and the packet size",
                  s.name, s.settings.max_recaptures + 1));
}

}  // namespace sherd::drivers
