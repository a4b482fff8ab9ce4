// The viewport's display modes in the real editor window (CTest label `display`, under
// `xvfb-run -a`):
// - edge-and-point on cube-room, once the lighting is converged and the display has rendered
//   its settle frames, shows nearly the Gouraud picture (the same radiosity solution
//   seen through the point shader's direct + indirect shading), and the edges overlay visibly
//   differs from the plain edge-and-point image;
// - out-of-date: converged, nothing is tinted; after an add and a few redistribution shots with
//   the solver paused, exactly the objects whose patches hold unshot energy (read from the
//   solver) are tinted red and every other object's pixels equal the Gouraud image of the same
//   frame;
// - in one window: samples overlay dots cover 1–3% of the pixels (Bala et al.), spread over the
//   image, as many as the frame's new samples; the plain cache differs from edge-and-point
//   mostly at the edges the edges overlay marks; the difference mode is near black where the
//   display matches its reference and turns red where an added object is missing from it.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <future>
#include <thread>

#include "render/image.h"
#include "solver/discretization.h"
#include "ui/editor_app.h"
#include "ui/editor_test_support.h"
#include "ui/view_mode.h"
#include "ui/viewport_renderer.h"

namespace penumbra {
namespace {

const std::string kSource = PENUMBRA_SOURCE_DIR;

int runCommand(const std::string& command) {
    const int status = std::system(command.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// ---------------------------------------------------------------------------------------------
// In-process: the viewport images themselves (ViewportImage: the display radiance and the rgba
// with the mode's overlay).

using test::runUntil;

EditorOptions cubeRoom(ViewMode mode) {
    EditorOptions options;
    options.scene = kSource + "/scenes/cube-room.json";
    options.width = 800;
    options.height = 499;  // a 440 × 456 viewport: multiples of 4, as the display renders
    options.quiet = true;
    options.mode = mode;
    return options;
}

/// The image once the runner is quiescent in `mode` (display modes: settled frames).
std::shared_ptr<const ViewportImage> settledImage(EditorApp& app, ViewMode mode, double seconds) {
    SessionRunner& runner = *app.runner();
    std::shared_ptr<const ViewportImage> image;
    const bool ok = runUntil(
        app,
        [&] {
            image = runner.image();
            return runner.quiescent() && image && image->mode == mode;
        },
        seconds);
    const SolverSnapshot solver = runner.solver();
    static const auto t0 = std::chrono::steady_clock::now();
    std::printf("[%.1f s] %s settled: %d\n",
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
                toString(mode), ok ? 1 : 0);
    EXPECT_TRUE(ok) << "no settled image in mode " << toString(mode) << ": image mode "
                    << (image ? toString(image->mode) : "none") << ", settled frames "
                    << (image ? image->settledFrames : -1) << ", solver idle " << solver.idle
                    << ", unshot " << solver.unshotFraction << ", queued " << runner.queued();
    return ok ? image : nullptr;
}

/// Largest channel difference of pixel i between two 8-bit RGBA images.
int rgbaDifference(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b,
                   std::size_t i) {
    int d = 0;
    for (int c = 0; c < 3; ++c) d = std::max(d, std::abs(int(a[4 * i + c]) - int(b[4 * i + c])));
    return d;
}

TEST(ViewModeDisplay, EdgeAndPointMatchesGouraudAndTheEdgesOverlayDiffers) {
    // Converged under the Gouraud view, then the display modes of the same view at half the
    // viewport's resolution (--display-divisor 2; the viewport, 440 × 456 in an 800 × 499
    // window, halves to a multiple of 4), compared with the Gouraud image box-filtered 2 × 2.
    EditorOptions options = cubeRoom(ViewMode::Gouraud);
    options.displayDivisor = 2;
    EditorApp app(options);
    const auto gouraud = settledImage(app, ViewMode::Gouraud, 60);
    app.setViewMode(ViewMode::EdgeAndPoint);
    const auto epi = settledImage(app, ViewMode::EdgeAndPoint, 30);
    app.setViewMode(ViewMode::EdgesOverlay);
    const auto edges = settledImage(app, ViewMode::EdgesOverlay, 30);
    ASSERT_TRUE(gouraud && epi && edges);
    const int w = epi->render.radiance.width, h = epi->render.radiance.height;
    ASSERT_EQ(gouraud->render.radiance.width, 2 * w);
    ASSERT_EQ(gouraud->render.radiance.height, 2 * h);
    ASSERT_EQ(edges->render.radiance.width, w);
    Image half(w, h);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            half.at(x, y) = 0.25 * (gouraud->render.radiance.at(2 * x, 2 * y) +
                                    gouraud->render.radiance.at(2 * x + 1, 2 * y) +
                                    gouraud->render.radiance.at(2 * x, 2 * y + 1) +
                                    gouraud->render.radiance.at(2 * x + 1, 2 * y + 1));
    const std::vector<std::uint8_t> reference = encodeDisplay(half);
    const std::size_t n = static_cast<std::size_t>(w) * h;
    // Mean sRGB |epi − gouraud| over the viewport; pixels the overlay changes by > 0.15.
    double sum = 0;
    std::size_t changed = 0;
    for (std::size_t i = 0; i < n; ++i) {
        for (int c = 0; c < 3; ++c)
            sum += std::abs(int(epi->render.rgba[4 * i + c]) - int(reference[4 * i + c]));
        changed += rgbaDifference(edges->render.rgba, epi->render.rgba, i) > 0.15 * 255 ? 1 : 0;
    }
    const double epiVsGouraud = sum / (3.0 * 255.0 * double(n));
    const double edgesVsEpi = double(changed) / double(n);
    // Bound: the two renderers differ in shading (per-pixel point shading with exact direct
    // light vs per-vertex interpolation) and at silhouettes, a small part of it. A mean
    // sRGB difference of 0.02 is five grey levels in every pixel; an empty, unlit or direct-only
    // image is far beyond it.
    EXPECT_LT(epiVsGouraud, 0.02);
    // The overlay paints the simple/complex pixels along every edge (about 2.5% of the viewport
    // in cube-room): more than 1% of the pixels change by over 0.15 in some channel.
    EXPECT_GT(edgesVsEpi, 0.01);
    std::printf(
        "viewport mean sRGB |epi - gouraud| %.4f (bound 0.02); pixels changed by the "
        "edges overlay %.4f (bound > 0.01)\n",
        epiVsGouraud, edgesVsEpi);
}

TEST(ViewModeDisplay, TheCommandLineRejectsAnUnknownMode) {
    const std::string command = std::string(PENUMBRA_EDITOR_EXE) + " " + kSource +
                                "/scenes/cube-room.json --mode sepia 2>/dev/null";
    EXPECT_EQ(runCommand(command), 2) << command;
}

TEST(ViewModeDisplay, OutOfDateTintsExactlyTheObjectsWithPendingEnergy) {
    EditorApp app(cubeRoom(ViewMode::OutOfDate));
    SessionRunner& runner = *app.runner();
    // Converged first: before its first shot the solver is idle too, with everything pending.
    ASSERT_TRUE(runUntil(
        app, [&] { return runner.solver().converged; }, 60));
    auto converged = settledImage(app, ViewMode::OutOfDate, 60);
    ASSERT_TRUE(converged);

    // Converged: (almost) no pixel is tinted: the rgba is the Gouraud radiance encoded.
    auto tintedFraction = [](const ViewportImage& image) {
        const std::vector<std::uint8_t> plain = encodeDisplay(image.render.radiance);
        std::size_t tinted = 0;
        for (std::size_t i = 0; i < image.render.radiance.pixels.size(); ++i)
            tinted += rgbaDifference(plain, image.render.rgba, i) > 8 ? 1 : 0;
        return double(tinted) / double(image.render.radiance.pixels.size());
    };
    const double before = tintedFraction(*converged);
    EXPECT_LT(before, 0.01);

    // Pause, add a box over the table and shoot a few redistribution shots: receivers get
    // unshot energy that the paused solver leaves pending.
    runner.setPaused(true);
    SceneObject box;
    box.id = "pending-box";
    box.shape.type = ShapeType::Box;
    box.shape.size = Vec3(0.4);
    box.material = "wood";
    box.transform.translate = Vec3(0.2, 1.3, 0.0);
    runner.submit(AddCommand{box});
    runner.submit(SolveCommand{6});
    ASSERT_TRUE(runUntil(
        app, [&] { return runner.queued() == 0 && runner.document()->find("pending-box"); }, 30));

    // An image of this state: rendered after the edit (the view is unchanged, so wait for a
    // new image and then for it to stay).
    std::shared_ptr<const ViewportImage> image;
    ASSERT_TRUE(runUntil(
        app,
        [&] {
            image = runner.image();
            return image && image != converged && !image->reduced;
        },
        20));
    runUntil(
        app, [] { return false; }, 0.5);
    image = runner.image();
    const int w = image->render.radiance.width, h = image->render.radiance.height;

    // The tint the solver's state asks for, per pixel: the paused solver's |unshot ΔB| per
    // element, seen through the same camera, over 5% of the mean display radiosity (read and
    // rendered on the solver thread).
    std::promise<std::vector<double>> promise;
    const Camera camera = image->camera;
    runner.post([&promise, camera, w, h](EditSession& s) {
        const Discretization& disc = s.discretization();
        const ProgressiveSolver& solver = s.solver();
        const std::vector<Rgb> b = solver.displayRadiosity();
        std::vector<Rgb> pendingB(disc.elements().size(), Rgb(0.0));
        double sum = 0;
        std::size_t count = 0;
        for (std::size_t e = 0; e < disc.elements().size(); ++e) {
            const int patch = disc.elements()[e].patch;
            if (patch < 0 || !disc.patchAlive(patch)) continue;
            pendingB[e] = glm::abs(solver.unshotRadiosity(patch));
            sum += luminance(b[e]);
            ++count;
        }
        const double scale = 0.05 * sum / double(count);
        const ViewportRender seen = renderViewport(disc, s.tracer(), pendingB, camera, w, h);
        std::vector<double> weight(seen.radiance.pixels.size());
        for (std::size_t i = 0; i < weight.size(); ++i)
            weight[i] =
                0.75 * std::clamp(luminance(seen.radiance.pixels[i]) * M_PI / scale, 0.0, 1.0);
        promise.set_value(weight);
    });
    auto future = promise.get_future();
    ASSERT_TRUE(runUntil(
        app, [&] { return future.wait_for(std::chrono::seconds(0)) == std::future_status::ready; },
        30));
    const std::vector<double> weight = future.get();
    ASSERT_EQ(weight.size(), static_cast<std::size_t>(w) * h);

    // Tinted exactly where the solver has pending energy: red up, green down; elsewhere the
    // Gouraud image of the same frame.
    const std::vector<std::uint8_t> plain = encodeDisplay(image->render.radiance);
    std::size_t strong = 0, strongTinted = 0, quiet = 0, quietPlain = 0, tinted = 0,
                tintedExpected = 0, notRed = 0;
    for (std::size_t i = 0; i < weight.size(); ++i) {
        const int d = rgbaDifference(plain, image->render.rgba, i);
        if (weight[i] > 0.1) {
            ++strong;
            strongTinted += d > 0 || plain[4 * i] == 255 ? 1 : 0;
        }
        if (weight[i] < 0.002) {
            ++quiet;
            quietPlain += d <= 1 ? 1 : 0;
        }
        if (d > 8) {
            ++tinted;
            tintedExpected += weight[i] > 0.01 ? 1 : 0;
            notRed += image->render.rgba[4 * i] < plain[4 * i] ||
                              image->render.rgba[4 * i + 1] > plain[4 * i + 1]
                          ? 1
                          : 0;
        }
    }
    ASSERT_GT(strong, weight.size() / 50) << "the redistribution shots left little pending";
    ASSERT_GT(quiet, weight.size() / 100) << "nothing is left without pending energy";
    EXPECT_GT(double(strongTinted), 0.99 * double(strong));
    EXPECT_GT(double(quietPlain), 0.99 * double(quiet));
    EXPECT_GT(double(tintedExpected), 0.99 * double(tinted));
    EXPECT_EQ(notRed, 0u);
    const double after = tintedFraction(*image);
    EXPECT_GT(after, before + 0.02);
    std::printf(
        "tinted pixels: converged %.4f, after the add %.4f; strong pending %zu px (%zu tinted), "
        "no pending %zu px (%zu as Gouraud)\n",
        before, after, strong, strongTinted, quiet, quietPlain);
}

TEST(ViewModeDisplay, SamplesCacheAndDifferenceModesShowWhatTheySay) {
    // Converge under the Gouraud view first (the display's shader threads would share the
    // cores with the solver), then switch to the display.
    // The display at half the viewport's resolution (--display-divisor 2) keeps each mode's
    // settle frames short.
    EditorOptions options = cubeRoom(ViewMode::Gouraud);
    options.displayDivisor = 2;
    EditorApp app(options);
    SessionRunner& runner = *app.runner();
    ASSERT_TRUE(settledImage(app, ViewMode::Gouraud, 60));
    app.setViewMode(ViewMode::EdgeAndPoint);
    const auto epi = settledImage(app, ViewMode::EdgeAndPoint, 30);
    ASSERT_TRUE(epi);
    const int w = epi->render.radiance.width, h = epi->render.radiance.height;
    const std::size_t n = static_cast<std::size_t>(w) * h;

    // Samples overlay: yellow dots on each frame's new samples, 1–3% of the pixels (Bala et
    // al.). The shader is asynchronous, so a loaded machine delivers fewer in some frames:
    // look at 12 successive frames and take the median one.
    app.setViewMode(ViewMode::SamplesOverlay);
    ASSERT_TRUE(settledImage(app, ViewMode::SamplesOverlay, 30));
    struct SampleFrame {
        std::size_t dots = 0, newSamples = 0, quadrant[4] = {0, 0, 0, 0};
        double fraction = 0;
        std::string note;
    };
    std::vector<SampleFrame> frames;
    std::shared_ptr<const ViewportImage> shown;
    runUntil(
        app,
        [&] {
            const auto image = runner.image();
            if (!image || image == shown || image->mode != ViewMode::SamplesOverlay) return false;
            shown = image;
            SampleFrame f;
            for (std::size_t i = 0; i < n; ++i) {
                const std::uint8_t* p = &image->render.rgba[4 * i];
                if (p[0] == 255 && p[1] == 230 && p[2] == 0) {
                    ++f.dots;
                    const int x = int(i % w), y = int(i / w);
                    ++f.quadrant[(x < w / 2 ? 0 : 1) + (y < h / 2 ? 0 : 2)];
                }
            }
            f.newSamples = image->display.newSamples;
            f.fraction = image->display.newSampleFraction;
            f.note = image->note;
            frames.push_back(f);
            return frames.size() >= 12;
        },
        20);
    ASSERT_GE(frames.size(), 6u);
    for (const SampleFrame& f : frames) {
        // A dot per new sample (several samples may land in one pixel; a few lie off screen).
        EXPECT_LE(f.dots, f.newSamples);
        EXPECT_GE(double(f.dots), 0.7 * double(f.newSamples));
        EXPECT_NE(f.note.find(std::to_string(f.newSamples) + " new samples"), std::string::npos)
            << f.note;
    }
    std::sort(frames.begin(), frames.end(),
              [](const SampleFrame& a, const SampleFrame& b) { return a.dots < b.dots; });
    const SampleFrame& median = frames[frames.size() / 2];
    const double dotFraction = double(median.dots) / double(n);
    EXPECT_GE(dotFraction, 0.01);
    EXPECT_LE(dotFraction, 0.03);
    EXPECT_GE(median.fraction, 0.01);
    EXPECT_LE(median.fraction, 0.03);
    // Spread over the image, not in a block.
    for (std::size_t q : median.quadrant) EXPECT_GT(double(q), 0.1 * double(median.dots) / 4);

    // Plain cache vs edge-and-point: they differ mostly next to the edges the overlay marks.
    app.setViewMode(ViewMode::EdgesOverlay);
    const auto edges = settledImage(app, ViewMode::EdgesOverlay, 30);
    const auto epi2 = epi;  // the same view and lighting
    app.setViewMode(ViewMode::Cache);
    const auto cache = settledImage(app, ViewMode::Cache, 30);
    ASSERT_TRUE(edges && epi2 && cache);
    std::vector<std::uint8_t> edgePixel(n, 0);
    const std::vector<std::uint8_t> edgesPlain = encodeDisplay(edges->render.radiance);
    for (std::size_t i = 0; i < n; ++i)
        if (rgbaDifference(edgesPlain, edges->render.rgba, i) > 20) edgePixel[i] = 1;
    // Near an edge: within 3 pixels of a marked pixel.
    std::vector<std::uint8_t> near(n, 0);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            if (edgePixel[static_cast<std::size_t>(y) * w + x])
                for (int dy = -3; dy <= 3; ++dy)
                    for (int dx = -3; dx <= 3; ++dx) {
                        const int xx = x + dx, yy = y + dy;
                        if (xx >= 0 && yy >= 0 && xx < w && yy < h)
                            near[static_cast<std::size_t>(yy) * w + xx] = 1;
                    }
    double nearSum = 0, farSum = 0;
    std::size_t nearN = 0, farN = 0;
    const std::vector<std::uint8_t> a = encodeDisplay(epi2->render.radiance);
    const std::vector<std::uint8_t> b = encodeDisplay(cache->render.radiance);
    for (std::size_t i = 0; i < n; ++i) {
        const double d = rgbaDifference(a, b, i) / 255.0;
        if (near[i])
            nearSum += d, ++nearN;
        else
            farSum += d, ++farN;
    }
    ASSERT_GT(nearN, n / 100) << "the edges overlay marked almost nothing";
    ASSERT_GT(farN, n / 4);
    const double nearMean = nearSum / nearN, farMean = farSum / farN;
    EXPECT_GT(nearMean, 0.005) << "cache and edge-and-point should differ at edges";
    EXPECT_GT(nearMean, 2.0 * farMean);
    std::printf(
        "samples (median of %zu frames): %.4f of pixels dotted (%zu dots, %zu new samples); "
        "cache vs epi: mean max-channel |diff| %.4f near edges (%zu px), %.4f elsewhere\n",
        frames.size(), dotFraction, median.dots, median.newSamples, nearMean, nearN, farMean);

    // Difference vs reference: near black where the display matches its reference.
    app.setViewMode(ViewMode::Difference);
    std::shared_ptr<const ViewportImage> diff;
    ASSERT_TRUE(runUntil(
        app,
        [&] {
            diff = runner.image();
            return runner.quiescent() && diff && diff->mode == ViewMode::Difference &&
                   diff->meanDifference >= 0;
        },
        40))
        << (diff ? diff->note : std::string("no image"));
    auto lowAndRed = [n](const ViewportImage& image) {
        std::size_t low = 0, red = 0;
        for (std::size_t i = 0; i < n; ++i) {
            const std::uint8_t* p = &image.render.rgba[4 * i];
            low += p[0] == 0 && p[1] < 52 ? 1 : 0;     // falseColour(t < 0.25): |d| < 0.025
            red += p[0] == 255 && p[1] < 128 ? 1 : 0;  // t > 0.87
        }
        return std::pair{double(low) / double(n), double(red) / double(n)};
    };
    const auto [low, red] = lowAndRed(*diff);
    EXPECT_LT(diff->meanDifference, 0.02);
    EXPECT_GT(low, 0.9);
    EXPECT_LT(red, 0.01);

    // An object the reference does not have: red where it is.
    SceneObject box;
    box.id = "unseen-box";
    box.shape.type = ShapeType::Box;
    box.shape.size = Vec3(0.5);
    box.material = "wood";
    box.transform.translate = Vec3(0.2, 1.3, 0.0);
    runner.submit(AddCommand{box});
    std::shared_ptr<const ViewportImage> changed;
    ASSERT_TRUE(runUntil(
        app,
        [&] {
            changed = runner.image();
            return runner.document()->find("unseen-box") && changed &&
                   changed->meanDifference > 2 * diff->meanDifference &&
                   lowAndRed(*changed).second > 0.01;
        },
        40));
    const auto [lowAfter, redAfter] = lowAndRed(*changed);
    EXPECT_GT(redAfter, 0.01);
    EXPECT_GT(changed->meanDifference, 2 * diff->meanDifference);
    std::printf(
        "difference: mean %.4f, %.3f near black, %.4f red; with an added box %.4f, "
        "%.3f near black, %.4f red\n",
        diff->meanDifference, low, red, changed->meanDifference, lowAfter, redAfter);
}

}  // namespace
}  // namespace penumbra
