// The headless EGL context (gl_context.h).
#include "simgate/sim/gl_context.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <cstdlib>
#include <cstring>
#include <sstream>

namespace simgate::sim {

namespace {

// Where an install that lacks EGL finds it.
constexpr const char* k_install_hint = "install libegl1 and libgl1-mesa-dri";

bool has_extension(const char* list, const char* name) {
  if (!list) return false;
  const std::size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  return false;
}

std::string egl_error() {
  const EGLint code = eglGetError();
  std::ostringstream out;
  out << "EGL error 0x" << std::hex << code;
  switch (code) {
    case EGL_NOT_INITIALIZED: out << " EGL_NOT_INITIALIZED"; break;
    case EGL_BAD_ACCESS: out << " EGL_BAD_ACCESS"; break;
    case EGL_BAD_ALLOC: out << " EGL_BAD_ALLOC"; break;
    case EGL_BAD_ATTRIBUTE: out << " EGL_BAD_ATTRIBUTE"; break;
    case EGL_BAD_CONFIG: out << " EGL_BAD_CONFIG"; break;
    case EGL_BAD_CONTEXT: out << " EGL_BAD_CONTEXT"; break;
    case EGL_BAD_DISPLAY: out << " EGL_BAD_DISPLAY"; break;
    case EGL_BAD_MATCH: out << " EGL_BAD_MATCH"; break;
    case EGL_BAD_PARAMETER: out << " EGL_BAD_PARAMETER"; break;
    default: break;
  }
  return out.str();
}

}  // namespace

std::unique_ptr<GlContext> GlContext::make(std::string& why_not) {
  why_not.clear();
  if (const char* off = std::getenv("SIMGATE_RENDERER_UNAVAILABLE")) {
    why_not = std::string("rendering is switched off (SIMGATE_RENDERER_UNAVAILABLE=") + off + ")";
    return nullptr;
  }
  std::unique_ptr<GlContext> gl(new GlContext());
  // Mesa's surfaceless platform needs neither a display server nor a GPU
  EGLDisplay display = EGL_NO_DISPLAY;
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  auto get_platform_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
      eglGetProcAddress("eglGetPlatformDisplayEXT"));
  if (get_platform_display && has_extension(client, "EGL_MESA_platform_surfaceless")) {
    display = get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    gl->platform_ = "surfaceless";
  }
  if (display == EGL_NO_DISPLAY) {
    display = eglGetDisplay(EGL_DEFAULT_DISPLAY);
    gl->platform_ = "default";
  }
  if (display == EGL_NO_DISPLAY) {
    why_not =
        "no EGL display (" + egl_error() + ", no Mesa surfaceless platform): " + k_install_hint;
    return nullptr;
  }
  EGLint major = 0, minor = 0;
  if (!eglInitialize(display, &major, &minor)) {
    why_not = "EGL display could not be initialised (" + egl_error() + "): " + k_install_hint;
    return nullptr;
  }
  gl->display_ = display;  // from here the destructor releases what was made
  const char* extensions = eglQueryString(display, EGL_EXTENSIONS);
  if (!has_extension(extensions, "EGL_KHR_surfaceless_context")) {
    why_not = "EGL display has no EGL_KHR_surfaceless_context (Mesa's has): " +
              std::string(k_install_hint);
    return nullptr;
  }
  if (!eglBindAPI(EGL_OPENGL_API)) {
    why_not = "EGL has no desktop OpenGL (" + egl_error() + "): " + k_install_hint;
    return nullptr;
  }
  // a config for desktop OpenGL, or none at all (MuJoCo draws into its own framebuffer)
  const EGLint attributes[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
  EGLConfig config = nullptr;
  EGLint count = 0;
  if (!eglChooseConfig(display, attributes, &config, 1, &count) || count < 1) {
    if (!has_extension(extensions, "EGL_KHR_no_config_context")) {
      why_not = "EGL has no configuration for desktop OpenGL: " + std::string(k_install_hint);
      return nullptr;
    }
    config = EGL_NO_CONFIG_KHR;
  }
  EGLContext context = eglCreateContext(display, config, EGL_NO_CONTEXT, nullptr);
  if (context == EGL_NO_CONTEXT) {
    why_not = "EGL could not create an OpenGL context (" + egl_error() + ")";
    return nullptr;
  }
  gl->context_ = context;
  if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
    why_not = "EGL could not make its OpenGL context current (" + egl_error() + ")";
    return nullptr;
  }
  return gl;
}

GlContext::~GlContext() {
  if (display_ == EGL_NO_DISPLAY) return;
  eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  if (context_ != EGL_NO_CONTEXT) eglDestroyContext(display_, context_);
  // the display stays initialised (one per process, reused by the next context): its driver
  // stays loaded, as does every library the process loads
  eglReleaseThread();
}

std::string GlContext::gl_renderer() const {
  // core GL functions through EGL (EGL_KHR_get_all_proc_addresses, which Mesa has): no
  // link to libGL for one string
  constexpr unsigned k_gl_renderer = 0x1F01;  // GL_RENDERER
  using GetString = const unsigned char* (*)(unsigned);
  auto get_string = reinterpret_cast<GetString>(eglGetProcAddress("glGetString"));
  if (!get_string) return "";
  const unsigned char* name = get_string(k_gl_renderer);
  return name ? reinterpret_cast<const char*>(name) : "";
}

}  // namespace simgate::sim
