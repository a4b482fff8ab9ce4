// A still view converges (issue 47, point 5): the point shader says which points carry no
// sampling noise (ShadedPoint::exact), the render cache merges a pixel's samples into their
// mean (RenderCacheOptions::mergeSamples), the EPI shows a pixel's own point through its filters
// (EpiOptions::ownPointPrior), and together a still view of a faceted object comes closer to a
// reference render than Gouraud does and than the paper's reconstruction of the same points.
//
// Index: exact points · merging · own points · the still view

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "edit/edit_session.h"
#include "render/camera_rays.h"
#include "render/display/edge_point_image.h"
#include "render/display/interactive_display.h"
#include "render/display/point_shader.h"
#include "render/display/render_cache.h"
#include "render/gouraud_renderer.h"
#include "solver/discretization.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

/// makeLitRoom's room with a low-poly sphere (8 segments: flat facets whose creases are far
/// below the sharp-edge cutoff) on the slab.
Scene facetedRoom() {
    Scene scene = test::makeLitRoom("white");
    SceneObject ball;
    ball.id = "ball";
    ball.shape.type = ShapeType::Sphere;
    ball.shape.radius = 0.35;
    ball.shape.segments = 8;
    ball.material = "red";
    ball.transform.translate = Vec3(0.2, -0.4, 0.1);
    scene.objects.push_back(ball);
    return scene;
}

Camera ballCamera() {
    Camera c;
    c.position = Vec3(0.9, 0.4, 1.3);
    c.lookAt = Vec3(0.1, -0.6, 0.0);
    c.fovDeg = 50;
    return c;
}

/// Shader options whose 0.6 m lamp gets the full 4 × 4 rays from anywhere in the room (the
/// agreement ShadedPoint::exact asks for).
PointShaderOptions denseShadowRays() {
    PointShaderOptions o = displayShaderOptions();
    o.threads = 0;
    o.formFactorPerRay = 1e-4;
    return o;
}

// ---------------------------------------------------------------------------------------------
// Exact points

TEST(StillView, PointsInFullLightAreExactAndPenumbraPointsAreNot) {
    EditSession session(test::makeLitRoom("white"), SolverOptions{});
    session.converge(1e-3);
    const PointShader shader(session.discretization(), session.tracer(), SolverOptions{},
                             denseShadowRays());
    // Rays down onto the floor from below the slab's height (the slab spans y −0.85 … −0.75).
    auto floorRequest = [](double x, double z, std::uint64_t frame) {
        ShadeRequest r;
        r.origin = Vec3(x, -1.0, z);
        r.direction = Vec3(0, -1, 0);
        r.frame = frame;
        return r;
    };
    auto floorPoint = [&](double x, double z) { return shader.shade(floorRequest(x, z, 0)); };
    // The open floor sees the whole lamp: every ray unblocked, exact. Under the middle of the
    // slab (1.2 × 0.8 m at height -0.8, centred at x 0.2, z 0.1) the whole lamp is hidden.
    const ShadedPoint open = floorPoint(-1.2, -1.2);
    ASSERT_TRUE(open.hit());
    EXPECT_TRUE(open.exact);
    // A walk from under the slab's middle out into the open crosses its penumbra: some points
    // there are not exact, and every exact one's value is the same from another seed, up to the
    // small noise an umbra keeps (its sampled blocked part against the analytic unoccluded one).
    int noisy = 0, exact = 0;
    for (int k = 0; k <= 40; ++k) {
        const double x = 0.2 + 1.1 * k / 40.0;
        const ShadedPoint p = floorPoint(x, 0.1);
        ASSERT_TRUE(p.hit());
        if (!p.exact) {
            ++noisy;
            continue;
        }
        ++exact;
        const ShadedPoint q = shader.shade(floorRequest(x, 0.1, 7));  // another seed
        EXPECT_NEAR(q.radiance.x, p.radiance.x, 0.01 * open.radiance.x) << "x " << x;
    }
    EXPECT_GT(noisy, 0);
    EXPECT_GT(exact, 0);
    // A miss is exact (black).
    ShadeRequest out;
    out.origin = Vec3(0, 0, 10);  // outside the room, looking away
    out.direction = Vec3(0, 0, 1);
    EXPECT_TRUE(shader.shade(out).exact);
}

// ---------------------------------------------------------------------------------------------
// Merging

Camera wallCamera() {
    Camera c;
    c.position = Vec3(0, 0, 5);
    c.lookAt = Vec3(0, 0, 0);
    c.fovDeg = 40;
    return c;
}

/// A cache over one wall 5 m away (element 3 everywhere), reprojected once so that pixel
/// (10, 10) holds a point of colour 1 shaded under state 1.
struct MergeFixture {
    CameraRays rays{wallCamera(), 32, 32};
    std::unique_ptr<RenderCache> cache;
    explicit MergeFixture(int mergeSamples) {
        RenderCacheOptions o;
        o.mergeSamples = mergeSamples;
        cache = std::make_unique<RenderCache>(32, 32, 64, o);
        cache->insert(sample(10.3, 10.6, Rgb(1.0), 1));
        (void)cache->reproject(rays);
    }
    ShadedPoint sample(double px, double py, Rgb colour, std::uint64_t shading,
                       int element = 3) const {
        ShadedPoint p;
        p.pixel = {px, py};
        p.position = rays.origin() + 5.0 * rays.rayDirection(px, py) /
                                         std::abs(rays.rayDirection(px, py).z);
        p.radiance = colour;
        p.object = 0;
        p.element = element;
        p.shading = shading;
        p.frame = 1;
        return p;
    }
};

TEST(StillView, ASampleOfTheSamePixelElementAndStateMergesIntoTheMean) {
    MergeFixture f(32);
    f.cache->insert(f.sample(10.8, 10.2, Rgb(3.0), 1));
    ASSERT_EQ(f.cache->size(), 1u);
    EXPECT_DOUBLE_EQ(f.cache->points()[0].colour.x, 2.0);
    EXPECT_EQ(f.cache->points()[0].samples, 2);
    const auto& screen = f.cache->reproject(f.rays);
    ASSERT_EQ(screen.size(), 1u);
    EXPECT_EQ(screen[0].trust, epiTrust(false, 2));
}

TEST(StillView, ASampleOfAnotherStateReplacesTheMeanAndOtherElementsOrPixelsAreNewPoints) {
    MergeFixture f(32);
    f.cache->insert(f.sample(10.5, 10.5, Rgb(5.0), 2));  // the lighting changed
    ASSERT_EQ(f.cache->size(), 1u);
    EXPECT_DOUBLE_EQ(f.cache->points()[0].colour.x, 5.0);
    EXPECT_EQ(f.cache->points()[0].samples, 1);
    (void)f.cache->reproject(f.rays);
    f.cache->insert(f.sample(10.5, 10.5, Rgb(1.0), 2, /*element=*/4));  // another surface
    f.cache->insert(f.sample(20.5, 10.5, Rgb(1.0), 2));                 // another pixel
    EXPECT_EQ(f.cache->size(), 3u);
}

TEST(StillView, AMergeKeepsTheReprojectionsPendingScreenPointsAsTheyWere) {
    // Reprojected into EPI arrays, the screen point list is built only when asked: it shows
    // the points as reprojected, also after a sample merged into one.
    MergeFixture f(32);
    std::vector<double> depth(32 * 32);
    std::vector<glm::vec3> colour(32 * 32);
    std::vector<std::uint8_t> position(32 * 32), trust(32 * 32);
    const EpiPointArrays arrays{depth.data(), colour.data(), position.data(), 32, 32, trust.data()};
    f.cache->reproject(f.rays, arrays);
    const std::size_t k = 10 * 32 + 10;
    EXPECT_EQ(colour[k].x, 1.0f);
    f.cache->insert(f.sample(10.8, 10.2, Rgb(3.0), 1));
    ASSERT_EQ(f.cache->size(), 1u);
    EXPECT_DOUBLE_EQ(f.cache->points()[0].colour.x, 2.0);
    const auto& screen = f.cache->screenPoints();
    ASSERT_EQ(screen.size(), 1u);
    EXPECT_DOUBLE_EQ(screen[0].colour.x, 1.0);
    EXPECT_EQ(screen[0].trust, trust[k]);
    EXPECT_EQ(static_cast<int>(screen[0].position.x), 10);
    EXPECT_EQ(static_cast<int>(screen[0].position.y), 10);
    // The next reprojection shows the mean.
    EXPECT_DOUBLE_EQ(f.cache->reproject(f.rays)[0].colour.x, 2.0);
}

TEST(StillView, WithoutMergingEverySampleIsAPointOfItsOwn) {
    MergeFixture f(0);
    f.cache->insert(f.sample(10.8, 10.2, Rgb(3.0), 1));
    EXPECT_EQ(f.cache->size(), 2u);
}

TEST(StillView, TheMeanIsCappedAtMergeSamples) {
    MergeFixture f(4);
    for (int k = 0; k < 10; ++k) {
        f.cache->insert(f.sample(10.5, 10.5, Rgb(1.0), 1));
        (void)f.cache->reproject(f.rays);
    }
    EXPECT_EQ(f.cache->points()[0].samples, 4);
    // An exponential mean of weight 1/4 from here: one sample of 5 moves it by 1.
    f.cache->insert(f.sample(10.5, 10.5, Rgb(5.0), 1));
    EXPECT_DOUBLE_EQ(f.cache->points()[0].colour.x, 2.0);
}

TEST(StillView, APointShadedForAnotherViewIsNotThePixelsOwnUntilASampleOfThisViewMerges) {
    for (bool parallel : {true, false}) {
        SCOPED_TRACE(parallel ? "parallel" : "serial");
        MergeFixture f(32);
        RenderCacheOptions o;
        o.mergeSamples = 32;
        o.parallel = parallel;
        f.cache = std::make_unique<RenderCache>(32, 32, 64, o);
        f.cache->insert(f.sample(10.3, 10.6, Rgb(1.0), 1));
        ASSERT_EQ(f.cache->reproject(f.rays).size(), 1u);
        EXPECT_EQ(f.cache->reproject(f.rays)[0].trust, epiTrust(false, 1));  // still this view

        // The camera turns a little: the point still lands in the raster, but was shaded
        // for the other view (it could be hidden in this one).
        Camera turned = wallCamera();
        turned.lookAt = Vec3(0.05, 0, 0);
        const CameraRays moved(turned, 32, 32);
        const auto& screen = f.cache->reproject(moved);
        ASSERT_EQ(screen.size(), 1u);
        EXPECT_EQ(screen[0].trust, 0);

        // A sample requested in this view (frame ≥ the view's first) merges and makes it own.
        const auto p = moved.projectToPixel(f.cache->points()[0].position);
        ASSERT_TRUE(p);
        ShadedPoint s = f.sample(10.5, 10.5, Rgb(1.0), 1);
        s.position = moved.origin() + 5.0 * moved.rayDirection(p->x, p->y) /
                                          std::abs(moved.rayDirection(p->x, p->y).z);
        s.frame = f.cache->frame();
        f.cache->insert(s);
        ASSERT_EQ(f.cache->size(), 1u);
        const auto& again = f.cache->reproject(moved);
        ASSERT_EQ(again.size(), 1u);
        EXPECT_EQ(again[0].trust, epiTrust(false, 2));
    }
}

// ---------------------------------------------------------------------------------------------
// Own points

/// Every pixel of a 24 × 24 image with a point of a checkerboard's colour (no edges), `trust`.
std::vector<ScreenPoint> checkerPoints(std::uint8_t trust) {
    std::vector<ScreenPoint> points;
    for (int y = 0; y < 24; ++y)
        for (int x = 0; x < 24; ++x) {
            ScreenPoint p;
            p.position = {x + 0.4, y + 0.6};
            p.depth = 2.0;
            p.colour = Rgb(((x + y) % 2) ? 1.0 : 0.2);
            p.trust = trust;
            points.push_back(p);
        }
    return points;
}

TEST(StillView, APointOfTrustZeroIsNotShownAsItsPixelsValue) {
    EdgePointImage plain(24, 24, displayEpiOptions());
    plain.build({}, checkerPoints(0));
    const Image unknown = plain.reconstruct(true);
    EpiOptions paper = displayEpiOptions();
    paper.ownPointPrior = 0;
    EdgePointImage filtered(24, 24, paper);
    filtered.build({}, checkerPoints(0));
    const Image reference = filtered.reconstruct(true);
    for (int y = 0; y < 24; ++y)
        for (int x = 0; x < 24; ++x) EXPECT_EQ(unknown.at(x, y).x, reference.at(x, y).x);
}

TEST(StillView, AnExactOwnPointIsThePixelsValueAndANoisyOneIsWeighedByItsSamples) {
    EpiOptions paper = displayEpiOptions();
    paper.ownPointPrior = 0;
    EdgePointImage plain(24, 24, paper);
    plain.build({}, checkerPoints(0));
    const Image filtered = plain.reconstruct(true);

    EdgePointImage exact(24, 24, displayEpiOptions());
    exact.build({}, checkerPoints(kEpiTrustExact));
    const Image own = exact.reconstruct(true);

    const std::uint8_t threeSamples = epiTrust(false, 3);
    EdgePointImage noisy(24, 24, displayEpiOptions());
    noisy.build({}, checkerPoints(threeSamples));
    const Image weighed = noisy.reconstruct(true);
    const double k = displayEpiOptions().ownPointPrior;
    for (int y = 0; y < 24; ++y)
        for (int x = 0; x < 24; ++x) {
            const double c = ((x + y) % 2) ? 1.0 : 0.2;
            // The filters blur the checkerboard; the own point restores it.
            EXPECT_EQ(own.at(x, y).x, double(float(c))) << x << "," << y;  // colours are floats
            EXPECT_NEAR(weighed.at(x, y).x, (3.0 * c + k * filtered.at(x, y).x) / (3.0 + k), 1e-6)
                << x << "," << y;
        }
    EXPECT_GT(std::abs(filtered.at(12, 12).x - 0.2), 0.1);
}

// ---------------------------------------------------------------------------------------------
// The still view

/// The display error after `frames` still frames against `reference`, with the display's
/// options or the paper's reconstruction (no merging, no own points).
double stillError(EditSession& session, const CameraRays& rays, const Image& reference,
                  int frames, bool ownPoints) {
    InteractiveDisplayOptions o;
    o.width = rays.width();
    o.height = rays.height();
    o.synchronous = true;
    o.sampleFraction = 0.05;
    o.shader = denseShadowRays();
    if (!ownPoints) {
        o.cache.mergeSamples = 0;
        o.epi.ownPointPrior = 0;
    }
    InteractiveDisplay display(session.discretization(), session.tracer(),
                               interactiveSolverOptions(), o);
    display.apply(SolutionView::of(session.solver()));
    (void)display.warmUp(rays, 0.25);
    Image image;
    for (int f = 0; f < frames; ++f) image = display.renderFrame(rays);
    return relativeDisplayRmse(image, reference);
}

TEST(StillView, AStillViewOfAFacetedObjectComesCloserToTheReferenceThanGouraud) {
    EditSession session(facetedRoom(), interactiveSolverOptions());
    session.converge(1e-3);
    const CameraRays rays(ballCamera(), 80, 80);
    PointShader shader(session.discretization(), session.tracer(), interactiveSolverOptions(),
                       denseShadowRays());
    shader.updateSolution(session.solver());
    const Image reference = renderShaderReference(shader, rays, 3);
    const Image gouraud = renderGouraud(session.discretization(), session.tracer(),
                                        session.solver().displayRadiosity(), ballCamera(), 80,
                                        80, 3);
    const double gouraudError = relativeDisplayRmse(gouraud, reference);
    const double early = stillError(session, rays, reference, 4, true);
    const double still = stillError(session, rays, reference, 60, true);
    const double paper = stillError(session, rays, reference, 60, false);
    std::printf("still view: Gouraud %.4f, display after 4 frames %.4f, after 60 %.4f (paper's "
                "reconstruction %.4f)\n",
                gouraudError, early, still, paper);
    EXPECT_LT(still, early);
    EXPECT_LT(still, gouraudError);
    EXPECT_LT(still, paper);
}

}  // namespace
}  // namespace penumbra
