// With no EGL driver at all the renderer fails with one clear ProcessingError. The context is
// made once per process, so the case runs in a child process of this test executable with
// libglvnd pointed at no vendor library.
#include "render/egl_context.h"

#include "core/errors.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace sherd::render {
namespace {

TEST(EglContext, MissingDriverIsAClearProcessingError) {
  if (std::getenv("SHERD_RENDER_NO_EGL_CHILD")) {
    try {
      GlContextLock lock;
      FAIL() << "a context was made without any EGL vendor library";
    } catch (const ProcessingError& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("no headless OpenGL ES 3 context"), std::string::npos) << message;
      EXPECT_NE(message.find("EGL_MESA_platform_surfaceless not offered"), std::string::npos)
          << message;
    }
    return;
  }
  const std::string self = std::filesystem::read_symlink("/proc/self/exe").string();
  const std::string command =
      "SHERD_RENDER_NO_EGL_CHILD=1 __EGL_VENDOR_LIBRARY_FILENAMES=/nonexistent.json '" + self +
      "' --gtest_filter=EglContext.MissingDriverIsAClearProcessingError >/dev/null 2>&1";
  EXPECT_EQ(std::system(command.c_str()), 0) << "the child's expectations failed: " << command;
}

TEST(EglContext, DescribesTheContextItMade) {
  if (std::getenv("SHERD_RENDER_NO_EGL_CHILD")) GTEST_SKIP();
  const std::string description = GlContextLock::description();
  EXPECT_NE(description.find("OpenGL ES 3"), std::string::npos) << description;
}

}  // namespace
}  // namespace sherd::render
