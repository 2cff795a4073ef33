// The process's one headless OpenGL ES 3 context (EGL, no window system). Created on first use
// and reused: creating an EGL display and context costs far more than a plate.
#pragma once

#include <string>

namespace sherd::render {

// Makes the shared context current on this thread for the lifetime of the lock; one thread
// renders at a time; the same thread may nest locks. Throws sherd::ProcessingError naming what is
// missing when neither the EGL device platform (a GPU) nor Mesa's surfaceless platform (llvmpipe on
// CI) gives a context.
class GlContextLock {
 public:
  GlContextLock();
  ~GlContextLock();
  GlContextLock(const GlContextLock&) = delete;
  GlContextLock& operator=(const GlContextLock&) = delete;

  // e.g. "EGL_MESA_platform_surfaceless, llvmpipe (LLVM 15.0.6, 256 bits), OpenGL ES 3.2
  // Mesa 22.3.6"
  static std::string description();
};

}  // namespace sherd::render
