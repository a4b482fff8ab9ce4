#pragma once
// An offscreen OpenGL 4.5 core context with no window system: EGL on a GPU when one exists,
// OSMesa (llvmpipe) otherwise, chosen at run time; never X. GL functions are loaded through
// glad, so the pass that uses the context does not care which one it is.

#include <memory>
#include <string>

namespace penumbra {

class OffscreenContext {
public:
    enum class Backend { Auto, Egl, OsMesa };
    /// Creates the context and makes it current on the calling thread. Auto picks EGL when an
    /// EGL device that is not a software renderer exists, else OSMesa; PENUMBRA_GL=egl|osmesa
    /// overrides Auto. Throws std::runtime_error naming what failed.
    explicit OffscreenContext(Backend backend = Backend::Auto);
    ~OffscreenContext();
    OffscreenContext(const OffscreenContext&) = delete;
    OffscreenContext& operator=(const OffscreenContext&) = delete;

    /// Makes the context current on the calling thread again.
    void makeCurrent();
    Backend backend() const { return mBackend; }
    /// "egl" or "osmesa", and the GL_RENDERER string.
    std::string name() const;
    std::string renderer() const { return mRenderer; }

private:
    struct Impl;
    std::unique_ptr<Impl> mImpl;
    Backend mBackend = Backend::OsMesa;
    std::string mRenderer;
};

}  // namespace penumbra
