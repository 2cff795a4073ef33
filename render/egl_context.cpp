#include "render/egl_context.h"

#include "core/errors.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GLES3/gl3.h>
#include <fmt/format.h>

#include <cstring>
#include <mutex>
#include <vector>

namespace sherd::render {
namespace {

bool has_extension(const char* list, const char* name) {
  if (!list) return false;
  const std::size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)); p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  return false;
}

struct SharedContext {
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  std::string description;
};

// Initialises `display` and makes an ES 3 context on it that needs no surface (we render into
// FBOs); on failure appends the reason to `why`.
bool make_context(EGLDisplay display, const std::string& platform, SharedContext& out,
                  std::string& why) {
  EGLint major = 0, minor = 0;
  if (display == EGL_NO_DISPLAY || !eglInitialize(display, &major, &minor)) {
    why += fmt::format("{}: eglInitialize failed (0x{:x}); ", platform, eglGetError());
    return false;
  }
  if (!has_extension(eglQueryString(display, EGL_EXTENSIONS), "EGL_KHR_surfaceless_context")) {
    why += platform + ": no EGL_KHR_surfaceless_context; ";
    eglTerminate(display);
    return false;
  }
  // Surface type 0: any config will do, we draw into FBOs (the default would demand windows).
  const EGLint config_attribs[] = {EGL_SURFACE_TYPE, 0, EGL_RENDERABLE_TYPE, EGL_OPENGL_ES3_BIT,
                                   EGL_NONE};
  EGLConfig config = nullptr;
  EGLint count = 0;
  if (!eglBindAPI(EGL_OPENGL_ES_API) ||
      !eglChooseConfig(display, config_attribs, &config, 1, &count) || count < 1) {
    why += platform + ": no OpenGL ES 3 config; ";
    eglTerminate(display);
    return false;
  }
  const EGLint context_attribs[] = {EGL_CONTEXT_MAJOR_VERSION, 3, EGL_NONE};
  EGLContext context = eglCreateContext(display, config, EGL_NO_CONTEXT, context_attribs);
  if (context == EGL_NO_CONTEXT ||
      !eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
    why += fmt::format("{}: no OpenGL ES 3 context (0x{:x}); ", platform, eglGetError());
    if (context != EGL_NO_CONTEXT) eglDestroyContext(display, context);
    eglTerminate(display);
    return false;
  }
  out.display = display;
  out.context = context;
  out.description =
      fmt::format("{}, {}, {}", platform, reinterpret_cast<const char*>(glGetString(GL_RENDERER)),
                  reinterpret_cast<const char*>(glGetString(GL_VERSION)));
  eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  return true;
}

// A GPU through the device platform first (no X/Wayland needed); software devices are left to
// the surfaceless platform, which Mesa backs with llvmpipe.
bool try_device_platform(const char* client_extensions, SharedContext& out, std::string& why) {
  if (!has_extension(client_extensions, "EGL_EXT_platform_device") ||
      !has_extension(client_extensions, "EGL_EXT_device_enumeration")) {
    why += "EGL_EXT_platform_device/EGL_EXT_device_enumeration not offered; ";
    return false;
  }
  auto query_devices =
      reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
  auto query_device_string = reinterpret_cast<PFNEGLQUERYDEVICESTRINGEXTPROC>(
      eglGetProcAddress("eglQueryDeviceStringEXT"));
  auto get_platform_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
      eglGetProcAddress("eglGetPlatformDisplayEXT"));
  EGLint count = 0;
  if (!query_devices || !query_device_string || !get_platform_display ||
      !query_devices(0, nullptr, &count) || count <= 0) {
    why += "EGL device platform: no devices; ";
    return false;
  }
  std::vector<EGLDeviceEXT> devices(static_cast<std::size_t>(count));
  query_devices(count, devices.data(), &count);
  for (EGLint i = 0; i < count; ++i) {
    if (has_extension(query_device_string(devices[i], EGL_EXTENSIONS), "EGL_MESA_device_software"))
      continue;
    EGLDisplay display = get_platform_display(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr);
    if (make_context(display, fmt::format("EGL_EXT_platform_device #{}", i), out, why)) return true;
  }
  why += "EGL device platform: no usable GPU device; ";
  return false;
}

bool try_surfaceless_platform(const char* client_extensions, SharedContext& out, std::string& why) {
  if (!has_extension(client_extensions, "EGL_MESA_platform_surfaceless")) {
    why += "EGL_MESA_platform_surfaceless not offered; ";
    return false;
  }
  auto get_platform_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
      eglGetProcAddress("eglGetPlatformDisplayEXT"));
  if (!get_platform_display) {
    why += "eglGetPlatformDisplayEXT missing; ";
    return false;
  }
  return make_context(
      get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr),
      "EGL_MESA_platform_surfaceless", out, why);
}

std::recursive_mutex& context_mutex() {
  static std::recursive_mutex mutex;
  return mutex;
}

// Built once; a failure is remembered so that every plate reports it without retrying.
const SharedContext& shared_context() {
  static const SharedContext context = [] {
    SharedContext made;
    std::string why;
    const char* client_extensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    if (!client_extensions) why += "EGL client extensions unavailable (EGL < 1.5?); ";
    if (!try_device_platform(client_extensions, made, why) &&
        !try_surfaceless_platform(client_extensions, made, why))
      made.description = why;
    return made;
  }();
  if (context.context == EGL_NO_CONTEXT)
    throw ProcessingError(
        fmt::format("render: no headless OpenGL ES 3 context: {}install a GPU EGL driver or Mesa "
                    "(libegl-mesa0, libgles2)",
                    context.description));
  return context;
}

}  // namespace

// Nesting on one thread (a plate holds a renderer per view) makes current only once.
thread_local int lock_depth = 0;

GlContextLock::GlContextLock() {
  context_mutex().lock();
  if (lock_depth++ > 0) return;
  try {
    const SharedContext& context = shared_context();
    if (!eglMakeCurrent(context.display, EGL_NO_SURFACE, EGL_NO_SURFACE, context.context))
      throw ProcessingError(fmt::format("render: eglMakeCurrent failed (0x{:x})", eglGetError()));
  } catch (...) {
    --lock_depth;
    context_mutex().unlock();
    throw;
  }
}

GlContextLock::~GlContextLock() {
  if (--lock_depth == 0) {
    const SharedContext& context = shared_context();
    eglMakeCurrent(context.display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  }
  context_mutex().unlock();
}

std::string GlContextLock::description() {
  std::lock_guard lock(context_mutex());
  return shared_context().description;
}

}  // namespace sherd::render
