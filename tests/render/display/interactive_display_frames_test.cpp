// The interactive display (Bala et al. 2003 §3): point shader, render cache, edge finder and EPI
// wired into frames. Image error is displayRmse (sRGB-encoded, clipped, as the PNG shows it).
// Truths: the display's own every-pixel reference (the same shader, 4×4
// supersampled), the same frames run twice, the analytic near-plane clip, and a from-scratch
// display of the edited scene.
//
// (The file is not named interactive_display_test.cpp: tests/CMakeLists.txt reserves names
// ending in _display_test for tests that need an X display.)
//
// Index: helpers · projection and error · convergence and epi vs cache · determinism ·
//        asynchronous mode · edits

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <unordered_set>

#include "display_events.h"
#include "edit/edit_session.h"
#include "render/display/interactive_display.h"
#include "solver/discretization.h"

namespace penumbra {
namespace {

// ---------------------------------------------------------------------------------------------
// Helpers

const std::string kCornell = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cornell-box.json";
constexpr int kSize = 64;

std::unique_ptr<EditSession> openCornell() {
    auto session = EditSession::open(kCornell, interactiveSolverOptions());
    session->converge(1e-2);
    return session;
}

Camera cornellCamera(const EditSession& session) { return *session.scene().findCamera("default"); }

InteractiveDisplayOptions smallOptions(double sampleFraction = 0.02) {
    InteractiveDisplayOptions o;
    o.width = kSize;
    o.height = kSize;
    o.sampleFraction = sampleFraction;
    return o;
}

std::unique_ptr<InteractiveDisplay> makeDisplay(EditSession& session,
                                                InteractiveDisplayOptions options) {
    auto display = std::make_unique<InteractiveDisplay>(session.discretization(), session.tracer(),
                                                        interactiveSolverOptions(), options);
    display->apply(SolutionView::of(session.solver()));
    return display;
}

// ---------------------------------------------------------------------------------------------
// Projection and error

TEST(ProjectEdges, ClipsAgainstTheNearPlaneAndKeepsViewDepth) {
    Camera c;
    c.position = Vec3(0, 0, 0);
    c.lookAt = Vec3(0, 0, -1);
    c.up = Vec3(0, 1, 0);
    c.fovDeg = 90;
    CameraRays camera(c, 100, 100);
    WorldEdge crossing;  // from behind the camera to 4 m in front, 1 m to the right
    crossing.a = Vec3(1, 0, 2);
    crossing.b = Vec3(1, 0, -4);
    WorldEdge behind;
    behind.a = Vec3(0, 1, 1);
    behind.b = Vec3(1, 1, 0.5);
    WorldEdge inFront;
    inFront.a = Vec3(-1, -1, -2);
    inFront.b = Vec3(1, 1, -3);
    inFront.kind = EdgeKind::Shadow;
    const double near = 0.5;
    auto edges = projectEdges({crossing, behind, inFront}, camera, near);
    ASSERT_EQ(edges.size(), 2u) << "the edge behind the camera must be dropped";
    // Crossing edge: clipped where depth = 0.5, i.e. z = -0.5: the point (1, 0, -0.5).
    EXPECT_NEAR(edges[0].depthA, near, 1e-12);
    EXPECT_NEAR(edges[0].depthB, 4.0, 1e-12);
    auto pa = camera.projectToPixel(Vec3(1, 0, -0.5));
    auto pb = camera.projectToPixel(Vec3(1, 0, -4));
    ASSERT_TRUE(pa && pb);
    EXPECT_NEAR(edges[0].a.x, pa->x, 1e-9);
    EXPECT_NEAR(edges[0].a.y, pa->y, 1e-9);
    EXPECT_NEAR(edges[0].b.x, pb->x, 1e-9);
    // 90° field of view, 100 px: x = 50 + 50·(1 / depth).
    EXPECT_NEAR(edges[0].a.x, 50 + 50 * (1 / 0.5), 1e-9);
    EXPECT_NEAR(edges[0].b.x, 50 + 50 * (1 / 4.0), 1e-9);
    EXPECT_EQ(edges[1].kind, ScreenEdge::Kind::Shadow);
    EXPECT_NEAR(edges[1].depthA, 2.0, 1e-12);
    EXPECT_NEAR(edges[1].depthB, 3.0, 1e-12);
}

TEST(ImageRmse, MatchesClosedForm) {
    Image a(2, 1, Rgb(0.0)), b(2, 1, Rgb(0.0));
    a.at(0, 0) = Rgb(3, 0, 0);  // squared differences: 9 over 6 values
    EXPECT_NEAR(imageRmse(a, b), std::sqrt(9.0 / 6.0), 1e-12);
    b = Image(2, 1, Rgb(1.0));
    EXPECT_NEAR(relativeImageRmse(Image(2, 1, Rgb(0.5)), b), 0.5, 1e-12);
    EXPECT_THROW(imageRmse(a, Image(1, 1)), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// Convergence and epi vs cache

TEST(InteractiveDisplay, ConvergesToTheReferenceAndEdgesBeatPlainInterpolation) {
    auto session = openCornell();
    auto display = makeDisplay(*session, smallOptions(0.02));
    const CameraRays camera(cornellCamera(*session), kSize, kSize);
    const Image reference = display->renderReference(camera, 4);

    // Sparse start: one sample per 4 × 4 pixels, then 2% per frame.
    display->warmUp(camera, 1.0 / 16);
    const Image first = display->renderFrame(camera, true);
    const double firstErr = displayRmse(first, reference);
    Image epi;
    double cacheErr = 0, epiErr = 0;
    for (int frame = 0; frame < 12; ++frame) epi = display->renderFrame(camera, true);
    epiErr = displayRmse(epi, reference);
    cacheErr = displayRmse(display->reconstructLast(false), reference);
    std::printf(
        "[ info ] display RMSE: first frame %.4f, after 12 frames epi %.4f, cache %.4f "
        "(same samples), %zu points\n",
        firstErr, epiErr, cacheErr, display->lastFrame().visiblePoints);
    EXPECT_LT(epiErr, 0.035) << display->lastFrame().toString();
    EXPECT_LT(epiErr, firstErr) << "more samples must bring the image closer to the reference";
    EXPECT_LT(epiErr, 0.6 * cacheErr)
        << "edge-respecting interpolation must beat plain interpolation of the same points";
    const DisplayFrameStats& st = display->lastFrame();
    EXPECT_GT(st.silhouetteEdges, 0u);
    EXPECT_GT(st.shadowEdges, 0u);
    EXPECT_GT(st.complexPixels + st.simplePixels, 0u);
    EXPECT_NEAR(st.newSampleFraction, 0.02, 0.005);
}

// ---------------------------------------------------------------------------------------------
// Determinism

TEST(InteractiveDisplay, SynchronousFramesAreDeterministic) {
    auto session = openCornell();
    Camera c = cornellCamera(*session);
    auto run = [&](EditSession& s) {
        auto display = makeDisplay(s, smallOptions(0.03));
        std::vector<Image> frames;
        for (int k = 0; k < 4; ++k) {
            Camera moved = c;
            moved.position += Vec3(0.02 * k, 0.01 * k, 0);
            const CameraRays camera(moved, kSize, kSize);
            if (k == 0) display->warmUp(camera, 0.25);
            frames.push_back(display->renderFrame(camera, true));
        }
        return frames;
    };
    const auto a = run(*session);
    const auto b = run(*session);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t k = 0; k < a.size(); ++k)
        for (std::size_t p = 0; p < a[k].pixels.size(); ++p)
            ASSERT_EQ(a[k].pixels[p], b[k].pixels[p])
                << "frame " << k << " pixel " << p << " differs between identical runs";
}

// ---------------------------------------------------------------------------------------------
// Asynchronous mode

TEST(InteractiveDisplay, AsynchronousModeTakesWorkerResults) {
    auto session = openCornell();
    InteractiveDisplayOptions o = smallOptions(0.05);
    o.synchronous = false;
    o.shader.threads = 2;
    auto display = makeDisplay(*session, o);
    const CameraRays camera(cornellCamera(*session), kSize, kSize);
    const Image reference = display->renderReference(camera, 2);
    display->renderFrame(camera, true);
    std::size_t taken = 0;
    Image image;
    for (int k = 0; k < 40; ++k) {
        display->shader().waitIdle();
        image = display->renderFrame(camera, true);
        taken += display->lastFrame().newSamples;
    }
    EXPECT_GT(taken, static_cast<std::size_t>(0.5 * kSize * kSize))
        << "the workers' results must reach the cache";
    const double err = displayRmse(image, reference);
    EXPECT_LT(err, 0.035) << display->lastFrame().toString();
}

// ---------------------------------------------------------------------------------------------
// Edits

TEST(InteractiveDisplay, EditInvalidatesMovedObjectAndConvergesToTheNewReference) {
    auto session = openCornell();
    auto display = makeDisplay(*session, smallOptions(0.04));
    const CameraRays camera(cornellCamera(*session), kSize, kSize);
    display->warmUp(camera, 0.25);
    for (int k = 0; k < 4; ++k) display->renderFrame(camera, true);
    const Image before = display->renderFrame(camera, true);

    // Move the short box across the floor.
    const std::string id = "short-box";
    const int oldVersion = session->objectVersion(id);
    std::size_t onOld = 0;
    for (const CachePoint& p : display->cache().points()) onOld += p.object == oldVersion;
    ASSERT_GT(onOld, 0u) << "the box must be visible before the move";
    EditCommand move;
    move.op = MoveCommand{id, Vec3(-0.2, 0, 0.15)};
    EditEvent result = session->apply(move);
    session->converge(1e-2);
    std::vector<int> changed = result.added;
    changed.insert(changed.end(), result.removed.begin(), result.removed.end());
    ASSERT_FALSE(changed.empty());
    const auto start = std::chrono::steady_clock::now();
    const std::size_t dropped =
        display->apply(test::changedEvent(result.added, result.removed), {}, &session->solver());
    const double notifyMs =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    for (const CachePoint& p : display->cache().points())
        ASSERT_NE(p.object, oldVersion) << "a point on the moved object survived: " << p.toString();
    EXPECT_GE(dropped, onOld);

    const Image newReference = display->renderReference(camera, 4);
    const double staleErr = displayRmse(before, newReference);
    Image after = display->renderFrame(camera, true);
    const double shadowMs = display->lastShadowUpdateMs();
    for (int k = 0; k < 20; ++k) after = display->renderFrame(camera, true);
    const double err = displayRmse(after, newReference);
    std::size_t onNew = 0;
    for (const CachePoint& p : display->cache().points()) onNew += p.object == result.added[0];
    std::printf(
        "[ info ] move: %zu points dropped in %.1f ms, shadow edges %.1f ms; error vs new "
        "reference: before the move %.4f, 20 frames after %.4f\n",
        dropped, notifyMs, shadowMs, staleErr, err);
    EXPECT_GT(onNew, 0u) << "the moved box must be sampled again";
    EXPECT_LT(err, 0.035);
    EXPECT_LT(err, 0.5 * staleErr) << "the display must follow the edit";
}

}  // namespace
}  // namespace penumbra
