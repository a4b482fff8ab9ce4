#include "render/gl/offscreen_context.h"

// glad's header first: it stands in for GL/gl.h, which osmesa.h would otherwise include.
#include <glad/gl.h>
// (separate blocks keep the order)
#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GL/osmesa.h>

#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <vector>

namespace penumbra {

struct OffscreenContext::Impl {
    // EGL
    EGLDisplay display = EGL_NO_DISPLAY;
    EGLContext context = EGL_NO_CONTEXT;
    // OSMesa: a 1 × 1 colour buffer (the passes render into their own framebuffer objects).
    OSMesaContext osmesa = nullptr;
    unsigned char pixel[4] = {0, 0, 0, 0};
};

namespace {

GLADapiproc eglLoad(const char* name) {
    return reinterpret_cast<GLADapiproc>(eglGetProcAddress(name));
}
GLADapiproc osmesaLoad(const char* name) {
    return reinterpret_cast<GLADapiproc>(OSMesaGetProcAddress(name));
}

bool hasExtension(const char* list, const char* name) {
    if (!list) return false;
    const std::size_t n = std::strlen(name);
    for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n)
        if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
    return false;
}

/// An EGL display on a hardware device, or EGL_NO_DISPLAY. With `allowSoftware`, Mesa's
/// surfaceless platform (llvmpipe) when no device is found.
EGLDisplay findEglDisplay(bool allowSoftware) {
    const char* clientExtensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    auto queryDevices =
        reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
    auto queryDeviceString = reinterpret_cast<PFNEGLQUERYDEVICESTRINGEXTPROC>(
        eglGetProcAddress("eglQueryDeviceStringEXT"));
    auto getPlatformDisplay = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
        eglGetProcAddress("eglGetPlatformDisplayEXT"));
    if (!getPlatformDisplay) return EGL_NO_DISPLAY;
    if (hasExtension(clientExtensions, "EGL_EXT_platform_device") && queryDevices &&
        queryDeviceString) {
        EGLDeviceEXT devices[16];
        EGLint count = 0;
        if (queryDevices(16, devices, &count)) {
            for (EGLint i = 0; i < count; ++i) {
                const char* ext = queryDeviceString(devices[i], EGL_EXTENSIONS);
                // Mesa marks its software device; anything else renders on hardware.
                if (hasExtension(ext, "EGL_MESA_device_software")) continue;
                EGLDisplay d = getPlatformDisplay(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr);
                if (d != EGL_NO_DISPLAY) return d;
            }
        }
    }
    if (allowSoftware && hasExtension(clientExtensions, "EGL_MESA_platform_surfaceless"))
        return getPlatformDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    return EGL_NO_DISPLAY;
}

}  // namespace

OffscreenContext::OffscreenContext(Backend backend) : mImpl(std::make_unique<Impl>()) {
    if (backend == Backend::Auto) {
        const char* forced = std::getenv("PENUMBRA_GL");
        if (forced && std::strcmp(forced, "egl") == 0) backend = Backend::Egl;
        if (forced && std::strcmp(forced, "osmesa") == 0) backend = Backend::OsMesa;
    }
    EGLDisplay display = EGL_NO_DISPLAY;
    if (backend == Backend::Auto) {
        display = findEglDisplay(false);
        backend = display != EGL_NO_DISPLAY ? Backend::Egl : Backend::OsMesa;
    } else if (backend == Backend::Egl) {
        display = findEglDisplay(true);
        if (display == EGL_NO_DISPLAY)
            throw std::runtime_error("EGL: no device or surfaceless display");
    }
    mBackend = backend;
    if (backend == Backend::Egl) {
        EGLint major = 0, minor = 0;
        if (!eglInitialize(display, &major, &minor))
            throw std::runtime_error("EGL: eglInitialize failed");
        mImpl->display = display;
        if (!eglBindAPI(EGL_OPENGL_API)) throw std::runtime_error("EGL: no desktop OpenGL");
        // No surface type: the context renders into framebuffer objects only (a surfaceless
        // display has no window configs, the default surface type).
        const EGLint configAttribs[] = {EGL_SURFACE_TYPE, 0, EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT,
                                        EGL_NONE};
        EGLConfig config;
        EGLint configs = 0;
        if (!eglChooseConfig(display, configAttribs, &config, 1, &configs) || configs < 1)
            throw std::runtime_error("EGL: no OpenGL config");
        const EGLint contextAttribs[] = {EGL_CONTEXT_MAJOR_VERSION,
                                         4,
                                         EGL_CONTEXT_MINOR_VERSION,
                                         5,
                                         EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                         EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                         EGL_NONE};
        mImpl->context = eglCreateContext(display, config, EGL_NO_CONTEXT, contextAttribs);
        if (mImpl->context == EGL_NO_CONTEXT)
            throw std::runtime_error("EGL: cannot create a GL 4.5 core context");
        makeCurrent();
        if (!gladLoadGL(eglLoad)) throw std::runtime_error("EGL: cannot load GL functions");
    } else {
        const int attribs[] = {OSMESA_FORMAT,
                               OSMESA_RGBA,
                               OSMESA_DEPTH_BITS,
                               0,
                               OSMESA_PROFILE,
                               OSMESA_CORE_PROFILE,
                               OSMESA_CONTEXT_MAJOR_VERSION,
                               4,
                               OSMESA_CONTEXT_MINOR_VERSION,
                               5,
                               0};
        mImpl->osmesa = OSMesaCreateContextAttribs(attribs, nullptr);
        if (!mImpl->osmesa) throw std::runtime_error("OSMesa: cannot create a GL 4.5 core context");
        makeCurrent();
        if (!gladLoadGL(osmesaLoad)) throw std::runtime_error("OSMesa: cannot load GL functions");
    }
    const GLubyte* r = glGetString(GL_RENDERER);
    mRenderer = r ? reinterpret_cast<const char*>(r) : "";
}

OffscreenContext::~OffscreenContext() {
    if (mImpl->osmesa) OSMesaDestroyContext(mImpl->osmesa);
    if (mImpl->display != EGL_NO_DISPLAY) {
        eglMakeCurrent(mImpl->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        if (mImpl->context != EGL_NO_CONTEXT) eglDestroyContext(mImpl->display, mImpl->context);
        eglTerminate(mImpl->display);
    }
}

void OffscreenContext::makeCurrent() {
    if (mImpl->osmesa) {
        if (!OSMesaMakeCurrent(mImpl->osmesa, mImpl->pixel, GL_UNSIGNED_BYTE, 1, 1))
            throw std::runtime_error("OSMesa: cannot make the context current");
    } else if (!eglMakeCurrent(mImpl->display, EGL_NO_SURFACE, EGL_NO_SURFACE, mImpl->context)) {
        throw std::runtime_error("EGL: cannot make the context current (surfaceless)");
    }
}

std::string OffscreenContext::name() const { return mBackend == Backend::Egl ? "egl" : "osmesa"; }

}  // namespace penumbra
