#pragma once
// The paper's per-pixel passes (Hardt & Teller 1996 §2.3–2.6) on the GL context current on
// the calling thread: (a) each HifiMesh triangle's index and (b) the perspective-correct
// barycentric coordinates of its visible point, rendered into an offscreen framebuffer
// (integer and float attachments instead of the paper's colour-coded ids and texture trick)
// and read back; (c) a parallel CPU pass evaluates each pixel's interpolant.

#include <cstdint>
#include <vector>

#include "render/image.h"

namespace penumbra {

class CameraRays;
class Discretization;
class HifiMesh;

struct InterpolantGlTiming {
    double rasterMs = 0;    ///< (a) and (b): drawing, including the GPU's work
    double readMs = 0;      ///< reading both buffers back
    double evaluateMs = 0;  ///< (c)
};

class InterpolantGlRenderer {
public:
    /// Compiles the shaders; a GL 4.5 core context must be current (OffscreenContext, or the
    /// editor's window). Throws std::runtime_error with the compiler's message on failure.
    InterpolantGlRenderer();
    ~InterpolantGlRenderer();
    InterpolantGlRenderer(const InterpolantGlRenderer&) = delete;
    InterpolantGlRenderer& operator=(const InterpolantGlRenderer&) = delete;

    /// Uploads the mesh's triangles (again after the mesh changed).
    void upload(const HifiMesh& mesh);
    /// Radiance (B/π) of the view, `samples`² jittered passes per pixel averaged. Pixels
    /// that see the back of a one-sided surface or nothing are black.
    Image render(const Discretization& disc, const HifiMesh& mesh, const CameraRays& rays,
                 int samples = 1, InterpolantGlTiming* timing = nullptr);
    /// The last pass's buffers: triangle index + 1 (0: none) and (s, t) per pixel, top row
    /// first, as CameraRays numbers pixels.
    const std::vector<std::uint32_t>& ids() const { return mIds; }
    const std::vector<float>& barycentrics() const { return mBary; }

private:
    void ensureTarget(int width, int height);
    unsigned mProgram = 0, mVao = 0, mVbo = 0, mFbo = 0, mIdTex = 0, mBaryTex = 0, mDepth = 0;
    int mWidth = 0, mHeight = 0;
    int mVertexCount = 0;
    float mSceneSize = 1;
    std::vector<std::uint32_t> mIds;
    std::vector<float> mBary;
    /// GL's rows (bottom up) as read back, kept between frames: a 1280 × 720 frame would
    /// otherwise allocate and clear 11 MB for them.
    std::vector<std::uint32_t> mRowIds;
    std::vector<float> mRowBary;
};

}  // namespace penumbra
