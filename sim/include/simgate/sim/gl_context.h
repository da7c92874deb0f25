// simgate/sim/gl_context.h — a headless desktop OpenGL context made with EGL, current on the
// thread that made it: what MuJoCo's renderer (mjr_makeContext, mjr_render) draws into.
//
// Terms:
//  - Display: Mesa's surfaceless platform when libEGL offers it (no display server, no GPU:
//    llvmpipe renders in software), else EGL's default display.
//  - Context: desktop OpenGL (eglBindAPI(EGL_OPENGL_API)), with no surface
//    (EGL_KHR_surfaceless_context): MuJoCo renders into its own offscreen framebuffer.
//
// Life cycle: make() on the thread that will make every GL call; the context stays current
// on that thread until the object is destroyed there. The EGL display stays initialised for
// the process (the next context reuses it). One user: the Renderer's render thread
// (renderer.h); the camera benchmark's bare mjr_render loop makes its own the same way, so
// that both measure the same kind of context.
//
// No GL: make() returns nullptr and says why (no libEGL vendor, no Mesa driver, no
// surfaceless support), with the packages to install. The environment variable
// SIMGATE_RENDERER_UNAVAILABLE, when set, keeps it from trying EGL and is the reason given.
#ifndef SIMGATE_SIM_GL_CONTEXT_H_
#define SIMGATE_SIM_GL_CONTEXT_H_

#include <memory>
#include <string>

namespace simgate::sim {

class GlContext {
 public:
  // A context made current on the calling thread, or nullptr with `why_not` set (a full
  // sentence naming the EGL error and what to install). Never throws for a missing driver.
  static std::unique_ptr<GlContext> make(std::string& why_not);
  // Releases the context; on the thread that made it.
  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  // "surfaceless" (Mesa's platform) or "default" (eglGetDisplay(EGL_DEFAULT_DISPLAY)).
  const std::string& platform() const { return platform_; }
  // The OpenGL renderer's name (GL_RENDERER: "llvmpipe (LLVM 15.0.6, 256 bits)"), "" when
  // it cannot be asked. On the thread that made it.
  std::string gl_renderer() const;

 private:
  GlContext() = default;
  void* display_ = nullptr;  // EGLDisplay
  void* context_ = nullptr;  // EGLContext
  std::string platform_;     // how the display was found
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_GL_CONTEXT_H_
