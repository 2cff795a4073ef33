#include "drivers/drm_projector.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <poll.h>
#include <sys/mman.h>
#include <unistd.h>
#include <xf86drm.h>
#include <xf86drmMode.h>

#include <cerrno>
#include <cstring>

#include "core/errors.h"

namespace sherd::drivers {

struct DrmProjector::State {
  struct Buffer {
    std::uint32_t handle = 0, framebuffer = 0, pitch = 0;
    std::uint64_t size = 0;
    std::uint8_t* map = nullptr;
  };
  std::string device, name;
  int fd = -1;
  std::uint32_t connector = 0, crtc = 0;
  drmModeModeInfo mode{};
  drmModeCrtc* saved = nullptr;  // the CRTC as found, restored at the end
  Buffer buffers[2];
  int front = 0;
  bool flipped = false;

  ~State() {
    if (saved) {
      drmModeSetCrtc(fd, saved->crtc_id, saved->buffer_id, saved->x, saved->y, &connector, 1,
                     &saved->mode);
      drmModeFreeCrtc(saved);
    }
    for (Buffer& b : buffers) {
      if (b.map) munmap(b.map, b.size);
      if (b.framebuffer) drmModeRmFB(fd, b.framebuffer);
      if (b.handle) {
        drm_mode_destroy_dumb destroy{};
        destroy.handle = b.handle;
        drmIoctl(fd, DRM_IOCTL_MODE_DESTROY_DUMB, &destroy);
      }
    }
    if (fd >= 0) close(fd);
  }
};

namespace {

std::string connector_name(const drmModeConnector& c) {
  const char* type = drmModeGetConnectorTypeName(c.connector_type);
  return fmt::format("{}-{}", type ? type : "Unknown", c.connector_type_id);
}

}  // namespace

DrmProjector::DrmProjector(const DrmProjectorSettings& settings) : state_(new State) {
  State& s = *state_;
  s.device = settings.device;
  s.fd = open(settings.device.c_str(), O_RDWR | O_CLOEXEC);
  if (s.fd < 0)
    throw DeviceError(fmt::format(
        "projector: cannot open {} ({}): no display device; connect the projector and check "
        "that its graphics driver is loaded (ls /dev/dri)",
        settings.device, std::strerror(errno)));
  drmModeRes* resources = drmModeGetResources(s.fd);
  if (!resources)
    throw DeviceError(
        fmt::format("projector: {} is not a KMS display device; use a "
                    "/dev/dri/cardN that drives outputs",
                    settings.device));
  std::string connected;
  drmModeConnector* chosen = nullptr;
  for (int i = 0; i < resources->count_connectors && !chosen; ++i) {
    drmModeConnector* c = drmModeGetConnector(s.fd, resources->connectors[i]);
    if (!c) continue;
    const std::string name = connector_name(*c);
    if (c->connection == DRM_MODE_CONNECTED && c->count_modes > 0) {
      connected += (connected.empty() ? "" : ", ") + name;
      if (settings.connector.empty() || settings.connector == name) {
        chosen = c;
        s.name = name;
        continue;
      }
    }
    drmModeFreeConnector(c);
  }
  if (!chosen) {
    drmModeFreeResources(resources);
    throw DeviceError(fmt::format(
        "projector: no connected display {}on {} (connected: {}); connect and switch on the "
        "projector, or set the connector to one of those",
        settings.connector.empty() ? "" : "connector " + settings.connector + " ", settings.device,
        connected.empty() ? "none" : connected));
  }
  s.connector = chosen->connector_id;
  s.mode = chosen->modes[0];
  for (int m = 0; m < chosen->count_modes; ++m)
    if (chosen->modes[m].type & DRM_MODE_TYPE_PREFERRED) s.mode = chosen->modes[m];
  // A CRTC: the one the connector's encoder drives now, else the first its encoders can use.
  for (int e = -1; e < chosen->count_encoders && !s.crtc; ++e) {
    drmModeEncoder* encoder =
        drmModeGetEncoder(s.fd, e < 0 ? chosen->encoder_id : chosen->encoders[e]);
    if (!encoder) continue;
    if (e < 0) {
      s.crtc = encoder->crtc_id;
    } else {
      for (int k = 0; k < resources->count_crtcs && !s.crtc; ++k)
        if (encoder->possible_crtcs & (1u << k)) s.crtc = resources->crtcs[k];
    }
    drmModeFreeEncoder(encoder);
  }
  drmModeFreeConnector(chosen);
  drmModeFreeResources(resources);
  if (!s.crtc)
    throw DeviceError(
        fmt::format("projector: no display controller (CRTC) free for {} on {}", s.name, s.device));

  for (State::Buffer& b : s.buffers) {
    drm_mode_create_dumb create{};
    create.width = s.mode.hdisplay;
    create.height = s.mode.vdisplay;
    create.bpp = 32;
    if (drmIoctl(s.fd, DRM_IOCTL_MODE_CREATE_DUMB, &create) != 0)
      throw DeviceError(fmt::format("projector {}: cannot allocate a {}x{} buffer ({})", s.name,
                                    create.width, create.height, std::strerror(errno)));
    b.handle = create.handle;
    b.pitch = create.pitch;
    b.size = create.size;
    if (drmModeAddFB(s.fd, create.width, create.height, 24, 32, b.pitch, b.handle,
                     &b.framebuffer) != 0)
      throw DeviceError(
          fmt::format("projector {}: cannot add a framebuffer ({})", s.name, std::strerror(errno)));
    drm_mode_map_dumb map{};
    map.handle = b.handle;
    if (drmIoctl(s.fd, DRM_IOCTL_MODE_MAP_DUMB, &map) != 0)
      throw DeviceError(
          fmt::format("projector {}: cannot map its buffer ({})", s.name, std::strerror(errno)));
    void* mapped = mmap(nullptr, b.size, PROT_READ | PROT_WRITE, MAP_SHARED, s.fd, map.offset);
    if (mapped == MAP_FAILED)
      throw DeviceError(
          fmt::format("projector {}: cannot map its buffer ({})", s.name, std::strerror(errno)));
    b.map = static_cast<std::uint8_t*>(mapped);
    std::memset(b.map, 0, b.size);
  }
  s.saved = drmModeGetCrtc(s.fd, s.crtc);
  if (drmModeSetCrtc(s.fd, s.crtc, s.buffers[0].framebuffer, 0, 0, &s.connector, 1, &s.mode) != 0)
    throw DeviceError(fmt::format(
        "projector {} on {}: cannot set mode {}x{} ({}); another display server (X11, Wayland) "
        "may hold the card: stop it",
        s.name, s.device, s.mode.hdisplay, s.mode.vdisplay, std::strerror(errno)));
}

DrmProjector::~DrmProjector() = default;

std::string DrmProjector::describe() const {
  return fmt::format("projector {} on {} ({}x{} @ {} Hz)", state_->name, state_->device, width(),
                     height(), state_->mode.vrefresh);
}

int DrmProjector::width() const { return state_->mode.hdisplay; }
int DrmProjector::height() const { return state_->mode.vdisplay; }

void DrmProjector::show(std::span<const std::uint8_t> pixels) {
  State& s = *state_;
  const int w = width(), h = height();
  if (pixels.size() != static_cast<std::size_t>(w) * h)
    throw InputError(fmt::format("projector {}: a {}-pixel pattern for a {}x{} display", s.name,
                                 pixels.size(), w, h));
  State::Buffer& back = s.buffers[1 - s.front];
  for (int y = 0; y < h; ++y) {
    auto* row = reinterpret_cast<std::uint32_t*>(back.map + std::size_t(y) * back.pitch);
    for (int x = 0; x < w; ++x) {
      const std::uint32_t g = pixels[std::size_t(y) * w + x];
      row[x] = (g << 16) | (g << 8) | g;  // XRGB8888 grey
    }
  }
  s.flipped = false;
  if (drmModePageFlip(s.fd, s.crtc, back.framebuffer, DRM_MODE_PAGE_FLIP_EVENT, &s) != 0)
    throw DeviceError(
        fmt::format("projector {}: page flip failed ({})", s.name, std::strerror(errno)));
  drmEventContext events{};
  events.version = 2;
  events.page_flip_handler = [](int, unsigned, unsigned, unsigned, void* data) {
    static_cast<State*>(data)->flipped = true;
  };
  while (!s.flipped) {
    pollfd p{s.fd, POLLIN, 0};
    if (poll(&p, 1, 1000) <= 0)
      throw DeviceError(fmt::format(
          "projector {}: the pattern did not reach the screen within 1 s (no vblank); check the "
          "projector is on",
          s.name));
    drmHandleEvent(s.fd, &events);
  }
  s.front = 1 - s.front;
}

}  // namespace sherd::drivers
