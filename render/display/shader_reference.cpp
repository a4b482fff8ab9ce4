// Reference renders by the point shader: every pixel shaded on a sub-pixel grid (the
// references benchmarks and tests compare displays with), and the edge-refined one whose edge
// pixels take many more samples.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <limits>
#include <stdexcept>

#include "core/random.h"
#include "render/display/interactive_display.h"

namespace penumbra {

namespace {

/// Frame number of reference samples: far from any frame a cache reaches, so the reference's
/// shadow-ray patterns are independent of the cached points'.
constexpr std::uint64_t kReferenceFrame = 0xF00DF00DULL << 16;

}  // namespace

Image renderShaderReference(const PointShader& shader, const CameraRays& camera,
                            int samplesPerAxis) {
    if (samplesPerAxis < 1)
        throw std::invalid_argument("renderShaderReference: samplesPerAxis < 1");
    const int w = camera.width(), h = camera.height(), s = samplesPerAxis;
    Image image(w, h);
    tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& rows) {
        for (int y = rows.begin(); y != rows.end(); ++y)
            for (int x = 0; x < w; ++x) {
                Rgb sum(0.0);
                for (int j = 0; j < s; ++j)
                    for (int i = 0; i < s; ++i) {
                        const glm::dvec2 p(x + (i + 0.5) / s, y + (j + 0.5) / s);
                        ShadeRequest r{p, camera.origin(), camera.rayDirection(p.x, p.y),
                                       kReferenceFrame};
                        sum += shader.shade(r).radiance;
                    }
                // The pixel's mean, clamped after averaging as a frame is.
                image.at(x, y) = glm::max(sum / static_cast<double>(s * s), Rgb(0.0));
            }
    });
    return image;
}

Image renderEdgeRefinedReference(const PointShader& shader, const CameraRays& camera,
                                 const ConvergedReferenceOptions& options,
                                 const std::function<bool(int x, int y)>& edgePixel,
                                 std::size_t* edgePixels) {
    if (options.samplesPerAxis < 1 || options.edgeSamplesPerAxis < 1 ||
        options.brightEdgeSamplesPerAxis < 1)
        throw std::invalid_argument("renderEdgeRefinedReference: samples per axis < 1 in " +
                                    options.toString());
    const int w = camera.width(), h = camera.height();
    const std::uint64_t seed = shader.options().seed;
    auto shown = [](double v) { return srgbEncodeClipped(v); };
    // Mean of s² samples on a jittered s × s grid over pixel (x, y); with `spread`, the
    // largest spread of the samples' displayed values over the channels, and in `bright` how
    // many samples displayed above white in some channel.
    auto shadePixel = [&](int x, int y, int s, double* spread, int* bright) {
        Rgb sum(0.0), lo(std::numeric_limits<double>::infinity()), hi(-lo);
        int above = 0;
        const std::uint64_t pixelKey =
            hashPair(hashPair(seed, static_cast<std::uint64_t>(y) * w + x), s);
        for (int j = 0; j < s; ++j)
            for (int i = 0; i < s; ++i) {
                const std::uint64_t k = hashPair(pixelKey, static_cast<std::uint64_t>(j * s + i));
                const glm::dvec2 p(x + (i + unitFromKey(k)) / s,
                                   y + (j + unitFromKey(k ^ 0xA5A5A5A5ull)) / s);
                ShadeRequest r{p, camera.origin(), camera.rayDirection(p.x, p.y),
                               kReferenceFrame + 1};
                const Rgb c = shader.shade(r).radiance;
                sum += c;
                above += c.x > 1.0 || c.y > 1.0 || c.z > 1.0;
                for (int ch = 0; ch < 3; ++ch) {
                    lo[ch] = std::min(lo[ch], shown(c[ch]));
                    hi[ch] = std::max(hi[ch], shown(c[ch]));
                }
            }
        if (spread) *spread = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
        if (bright) *bright = above;
        return sum / static_cast<double>(s * s);
    };
    Image image(w, h);
    const int first = options.samplesPerAxis * options.samplesPerAxis;
    // Per pixel: 1 an edge, 2 detail above white (refined at the higher rate); and how many
    // of its first samples displayed above white.
    std::vector<std::uint8_t> edge(static_cast<std::size_t>(w) * h, 0);
    std::vector<int> bright(edge.size(), 0);
    tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& rows) {
        for (int y = rows.begin(); y != rows.end(); ++y)
            for (int x = 0; x < w; ++x) {
                const std::size_t i = static_cast<std::size_t>(y) * w + x;
                double spread = 0;
                image.at(x, y) = shadePixel(x, y, options.samplesPerAxis, &spread, &bright[i]);
                edge[i] = spread > options.edgeSpread || (edgePixel && edgePixel(x, y));
            }
    });
    // Detail above white: a pixel not wholly above white with a sample above white in it or
    // in one of its eight neighbours.
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * w + x;
            if (bright[i] == first) continue;
            bool near = false;
            for (int dy = -1; dy <= 1 && !near; ++dy)
                for (int dx = -1; dx <= 1 && !near; ++dx) {
                    const int nx = x + dx, ny = y + dy;
                    near = nx >= 0 && ny >= 0 && nx < w && ny < h &&
                           bright[static_cast<std::size_t>(ny) * w + nx] > 0;
                }
            if (near) edge[i] = 2;
        }
    // Refined pixels: many more samples, instead of the first estimate.
    std::size_t edges = 0;
    for (std::uint8_t e : edge) edges += e != 0;
    if (edgePixels) *edgePixels = edges;
    tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& rows) {
        for (int y = rows.begin(); y != rows.end(); ++y)
            for (int x = 0; x < w; ++x) {
                const std::uint8_t e = edge[static_cast<std::size_t>(y) * w + x];
                const int s = e == 2   ? options.brightEdgeSamplesPerAxis
                              : e == 1 ? options.edgeSamplesPerAxis
                                       : options.samplesPerAxis;
                if (s != options.samplesPerAxis)
                    image.at(x, y) = shadePixel(x, y, s, nullptr, nullptr);
            }
    });
    return image;
}

Image InteractiveDisplay::renderConvergedReference(const CameraRays& camera,
                                                   const ConvergedReferenceOptions& options) const {
    if (options.samplesPerAxis < 1 || options.edgeSamplesPerAxis < 1)
        throw std::invalid_argument(
            "InteractiveDisplay::renderConvergedReference: samples per axis < 1 in " +
            options.toString());
    PointShader::Pause pause(*mShader);
    const PointShader shader(*mShader,
                             convergedReferenceShaderOptions(mShader->options(), options));
    const int w = camera.width(), h = camera.height();
    const bool epiEdges = options.useEpiEdges && mEpi.width() == w && mEpi.height() == h;
    std::function<bool(int, int)> edgePixel;
    if (epiEdges)
        edgePixel = [&](int x, int y) { return mEpi.pixelClass(x, y) != PixelClass::Empty; };
    return renderEdgeRefinedReference(shader, camera, options, edgePixel,
                                      &mLastReferenceEdgePixels);
}

PointShaderOptions convergedReferenceShaderOptions(const PointShaderOptions& display,
                                                   const ConvergedReferenceOptions& options) {
    // A synchronous copy of the shader with deep shadow sampling and no clamping.
    PointShaderOptions so = display;
    so.threads = 0;
    so.recordTriples = false;
    so.backgroundPreview = false;
    so.seed = hashPair(hashPair(display.seed, 0xC0C0A5EEDull), options.seed);
    so.maxStrataPerAxis = options.maxStrataPerAxis;
    so.shadowRefine = options.shadowRefine;
    so.shadowMaxRefinedPerAxis = options.shadowMaxRefinedPerAxis;
    so.shadowDecisionPerAxis = options.shadowDecisionPerAxis;
    so.clampNegative = false;
    return so;
}

}  // namespace penumbra
