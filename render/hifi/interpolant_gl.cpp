#include "render/hifi/interpolant_gl.h"

#include <glad/gl.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/timing.h"
#include "render/camera_rays.h"
#include "render/hifi/hifi_mesh.h"
#include "solver/discretization.h"

namespace penumbra {

namespace {

const char* kVertexShader = R"(#version 450 core
layout(location = 0) in vec3 position;
layout(location = 1) in vec2 bary;
uniform mat4 clipFromWorld;
out vec2 vBary;
void main() {
    vBary = bary;
    gl_Position = clipFromWorld * vec4(position, 1.0);
}
)";

// Smooth (perspective-correct) interpolation of (s, t); the primitive's index names the
// triangle. A back face writes no triangle and sits a hair behind, so where a two-sided
// surface's two sheets coincide the front one wins.
const char* kFragmentShader = R"(#version 450 core
in vec2 vBary;
layout(location = 0) out uint triangle;
layout(location = 1) out vec2 barycentric;
void main() {
    triangle = gl_FrontFacing ? uint(gl_PrimitiveID) + 1u : 0u;
    barycentric = vBary;
    gl_FragDepth = gl_FrontFacing ? gl_FragCoord.z : min(gl_FragCoord.z + 1e-6, 1.0);
}
)";

unsigned compile(GLenum type, const char* source) {
    const GLuint s = glCreateShader(type);
    glShaderSource(s, 1, &source, nullptr);
    glCompileShader(s);
    GLint ok = 0;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[2048];
        glGetShaderInfoLog(s, sizeof log, nullptr, log);
        glDeleteShader(s);
        throw std::runtime_error(std::string("interpolant shader: ") + log);
    }
    return s;
}

}  // namespace

InterpolantGlRenderer::InterpolantGlRenderer() {
    const GLuint vs = compile(GL_VERTEX_SHADER, kVertexShader);
    const GLuint fs = compile(GL_FRAGMENT_SHADER, kFragmentShader);
    mProgram = glCreateProgram();
    glAttachShader(mProgram, vs);
    glAttachShader(mProgram, fs);
    glLinkProgram(mProgram);
    glDeleteShader(vs);
    glDeleteShader(fs);
    GLint ok = 0;
    glGetProgramiv(mProgram, GL_LINK_STATUS, &ok);
    if (!ok) {
        char log[2048];
        glGetProgramInfoLog(mProgram, sizeof log, nullptr, log);
        throw std::runtime_error(std::string("interpolant program: ") + log);
    }
    glGenVertexArrays(1, &mVao);
    glGenBuffers(1, &mVbo);
}

InterpolantGlRenderer::~InterpolantGlRenderer() {
    if (mFbo) glDeleteFramebuffers(1, &mFbo);
    if (mIdTex) glDeleteTextures(1, &mIdTex);
    if (mBaryTex) glDeleteTextures(1, &mBaryTex);
    if (mDepth) glDeleteRenderbuffers(1, &mDepth);
    if (mVbo) glDeleteBuffers(1, &mVbo);
    if (mVao) glDeleteVertexArrays(1, &mVao);
    if (mProgram) glDeleteProgram(mProgram);
}

void InterpolantGlRenderer::upload(const HifiMesh& mesh) {
    // Per vertex: position, then the barycentric corner (0,0), (1,0), (0,1).
    std::vector<float> data;
    data.reserve(mesh.triangles().size() * 15);
    Vec3 lo(1e300), hi(-1e300);
    static const float corner[3][2] = {{0, 0}, {1, 0}, {0, 1}};
    for (const HifiTriangle& t : mesh.triangles())
        for (int k = 0; k < 3; ++k) {
            lo = glm::min(lo, t.p[k]);
            hi = glm::max(hi, t.p[k]);
            data.insert(data.end(), {float(t.p[k].x), float(t.p[k].y), float(t.p[k].z),
                                     corner[k][0], corner[k][1]});
        }
    mSceneSize = mesh.triangles().empty() ? 1.0f : float(glm::length(hi - lo));
    mVertexCount = static_cast<int>(mesh.triangles().size() * 3);
    glBindVertexArray(mVao);
    glBindBuffer(GL_ARRAY_BUFFER, mVbo);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(data.size() * sizeof(float)), data.data(),
                 GL_STATIC_DRAW);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 5 * sizeof(float), nullptr);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, 5 * sizeof(float),
                          reinterpret_cast<void*>(3 * sizeof(float)));
    glBindVertexArray(0);
}

void InterpolantGlRenderer::ensureTarget(int width, int height) {
    if (mFbo && width == mWidth && height == mHeight) return;
    if (!mFbo) {
        glGenFramebuffers(1, &mFbo);
        glGenTextures(1, &mIdTex);
        glGenTextures(1, &mBaryTex);
        glGenRenderbuffers(1, &mDepth);
    }
    mWidth = width;
    mHeight = height;
    glBindTexture(GL_TEXTURE_2D, mIdTex);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_R32UI, width, height, 0, GL_RED_INTEGER, GL_UNSIGNED_INT,
                 nullptr);
    glBindTexture(GL_TEXTURE_2D, mBaryTex);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RG32F, width, height, 0, GL_RG, GL_FLOAT, nullptr);
    glBindRenderbuffer(GL_RENDERBUFFER, mDepth);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, width, height);
    glBindFramebuffer(GL_FRAMEBUFFER, mFbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, mIdTex, 0);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT1, GL_TEXTURE_2D, mBaryTex, 0);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, mDepth);
    const GLenum buffers[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
    glDrawBuffers(2, buffers);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
        throw std::runtime_error("interpolant framebuffer incomplete");
}

Image InterpolantGlRenderer::render(const Discretization& disc, const HifiMesh& mesh,
                                    const CameraRays& rays, int samples,
                                    InterpolantGlTiming* timing) {
    using Clock = std::chrono::steady_clock;
    const int w = rays.width(), h = rays.height();
    ensureTarget(w, h);
    InterpolantGlTiming t;
    Image image(w, h);
    mIds.resize(static_cast<std::size_t>(w) * h);
    mBary.resize(static_cast<std::size_t>(w) * h * 2);
    mRowIds.resize(mIds.size());
    mRowBary.resize(mBary.size());
    std::uint32_t* rowIds = mRowIds.data();
    float* rowBary = mRowBary.data();

    // CameraRays' projection as a matrix (pixel centres where CameraRays puts them).
    const double tanHalfY = 0.5 * h / rays.pixelsPerUnit();
    const double tanHalfX = tanHalfY * w / h;
    const double zNear = 1e-4 * mSceneSize, zFar = 1e3 * mSceneSize;
    const Vec3 o = rays.origin();
    const int n = std::max(1, samples);
    glUseProgram(mProgram);
    const GLint loc = glGetUniformLocation(mProgram, "clipFromWorld");
    glViewport(0, 0, w, h);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glDisable(GL_CULL_FACE);
    glBindVertexArray(mVao);
    for (int k = 0; k < n * n; ++k) {
        const double jx = (k % n + 0.5) / n, jy = (k / n + 0.5) / n;
        // A sample at (i + jx, j + jy) lands on GL's pixel centre: shift the image plane.
        const double sx = -(jx - 0.5) * 2.0 / w, sy = (jy - 0.5) * 2.0 / h;
        float m[16];
        // Rows of clip = M (p, 1): x = (right·d)/tanX + sx·depth, y = (up·d)/tanY + sy·depth,
        // z = a·depth + b, w = depth, with d = p − o and depth = forward·d.
        const double a = (zFar + zNear) / (zFar - zNear), b = -2 * zFar * zNear / (zFar - zNear);
        auto setRow = [&](int r, const Vec3& v, double c) {
            m[0 * 4 + r] = float(v.x);
            m[1 * 4 + r] = float(v.y);
            m[2 * 4 + r] = float(v.z);
            m[3 * 4 + r] = float(c);
        };
        const Vec3 rx = rays.right() / tanHalfX + sx * rays.forward();
        const Vec3 ry = rays.up() / tanHalfY + sy * rays.forward();
        const Vec3 rz = a * rays.forward();
        const Vec3 rw = rays.forward();
        setRow(0, rx, -glm::dot(rx, o));
        setRow(1, ry, -glm::dot(ry, o));
        setRow(2, rz, -glm::dot(rz, o) + b);
        setRow(3, rw, -glm::dot(rw, o));
        glUniformMatrix4fv(loc, 1, GL_FALSE, m);

        auto start = Clock::now();
        const GLuint zero[4] = {0, 0, 0, 0};
        const GLfloat none[4] = {0, 0, 0, 0};
        const GLfloat far = 1.0f;
        glClearBufferuiv(GL_COLOR, 0, zero);
        glClearBufferfv(GL_COLOR, 1, none);
        glClearBufferfv(GL_DEPTH, 0, &far);
        glDrawArrays(GL_TRIANGLES, 0, mVertexCount);
        glFinish();
        t.rasterMs += msSince(start);

        start = Clock::now();
        glPixelStorei(GL_PACK_ALIGNMENT, 1);
        glReadBuffer(GL_COLOR_ATTACHMENT0);
        glReadPixels(0, 0, w, h, GL_RED_INTEGER, GL_UNSIGNED_INT, rowIds);
        glReadBuffer(GL_COLOR_ATTACHMENT1);
        glReadPixels(0, 0, w, h, GL_RG, GL_FLOAT, rowBary);
        t.readMs += msSince(start);

        start = Clock::now();
        const int triangles = static_cast<int>(mesh.triangles().size());
        // Radiance B/π averaged over the n² samples: the last pass scales.
        const bool last = k + 1 == n * n;
        const double scale = 1.0 / (M_PI * n * n);
        tbb::parallel_for(0, h, [&](int y) {
            const int row = h - 1 - y;  // GL's rows run bottom up
            for (int x = 0; x < w; ++x) {
                const std::size_t gl = static_cast<std::size_t>(row) * w + x;
                const std::size_t px = static_cast<std::size_t>(y) * w + x;
                const std::uint32_t id = rowIds[gl];
                mIds[px] = id;
                mBary[2 * px] = rowBary[2 * gl];
                mBary[2 * px + 1] = rowBary[2 * gl + 1];
                Rgb& pixel = image.at(x, y);
                if (id != 0 && static_cast<int>(id) <= triangles) {
                    const double s = rowBary[2 * gl], tt = rowBary[2 * gl + 1];
                    pixel += mesh.radiosity(disc, static_cast<int>(id) - 1, s, tt);
                }
                if (last) pixel *= scale;
            }
        });
        t.evaluateMs += msSince(start);
    }
    glBindVertexArray(0);
    if (timing) *timing = t;
    return image;
}

}  // namespace penumbra
