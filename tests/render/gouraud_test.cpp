// The reference Gouraud renderer and its pinhole camera, checked on scenes whose images are
// known in closed form: a uniform quad filling the view, a linear radiosity ramp, a box seen
// from inside, surfaces seen from behind.

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <glm/gtc/constants.hpp>
#include <stdexcept>
#include <string>

#include "render/camera_rays.h"
#include "render/gouraud_renderer.h"
#include "render/image.h"
#include "solver/discretization.h"
#include "solver/ray_tracer.h"

namespace penumbra {
namespace {

const double kPi = glm::pi<double>();

std::string vecString(const Vec3& v) {
    return "(" + std::to_string(v.x) + ", " + std::to_string(v.y) + ", " + std::to_string(v.z) +
           ")";
}

/// A scene with one object of the given shape and a white material.
Scene oneObjectScene(ShapeType type, Vec3 size, Vec3 rotateDeg, bool twoSided, double elementSize) {
    Scene scene;
    scene.settings.patchSize = 1.0;
    scene.settings.elementSize = elementSize;
    Material white;
    white.reflectance = Rgb(0.5);
    white.twoSided = twoSided;
    scene.materials.push_back({"white", white});
    SceneObject object;
    object.id = "thing";
    object.shape.type = type;
    object.shape.size = size;
    object.material = "white";
    object.transform.rotateDeg = rotateDeg;
    scene.objects.push_back(object);
    return scene;
}

/// A 4 m × 4 m quad in the z = 0 plane facing +Z, in front of the default test camera.
Scene facingQuadScene(bool twoSided = false) {
    return oneObjectScene(ShapeType::Quad, Vec3(4, 0, 4), Vec3(90, 0, 0), twoSided, 0.5);
}

Camera cameraAt(Vec3 position, Vec3 lookAt, double fovDeg = 40) {
    Camera camera;
    camera.name = "test";
    camera.position = position;
    camera.lookAt = lookAt;
    camera.up = Vec3(0, 1, 0);
    camera.fovDeg = fovDeg;
    return camera;
}

void expectUniform(const Image& image, const Rgb& expected, double tolerance,
                   const std::string& what) {
    int failures = 0;
    for (int y = 0; y < image.height && failures < 5; ++y) {
        for (int x = 0; x < image.width && failures < 5; ++x) {
            const Rgb& p = image.at(x, y);
            if (glm::length(p - expected) > tolerance) {
                ADD_FAILURE() << what << ": pixel (" << x << ", " << y << ") = " << vecString(p)
                              << ", expected " << vecString(expected);
                ++failures;
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// Camera

TEST(CameraRays, CentreCornerAndProjectionAgree) {
    const Camera camera = cameraAt(Vec3(1, 2, 3), Vec3(1, 2, 0), 60);
    const CameraRays rays(camera, 64, 32);
    const Vec3 centre = rays.rayDirection(32, 16);
    EXPECT_NEAR(glm::length(centre - Vec3(0, 0, -1)), 0, 1e-12) << rays.toString();

    // The top edge centre is fovY/2 above the axis; the right edge centre follows the aspect.
    const Vec3 top = rays.rayDirection(32, 0);
    EXPECT_NEAR(std::acos(glm::dot(top, centre)), glm::radians(30.0), 1e-12);
    EXPECT_GT(top.y, 0) << "py grows downwards";
    const Vec3 right = rays.rayDirection(64, 16);
    EXPECT_NEAR(right.x / -right.z, 2 * std::tan(glm::radians(30.0)), 1e-12);
    EXPECT_GT(right.x, 0) << "px grows to the right";

    // Projection inverts the ray direction.
    for (auto [px, py] : {std::pair{0.5, 0.5}, std::pair{10.25, 30.0}, std::pair{63.5, 1.0}}) {
        const auto p = rays.projectToPixel(rays.origin() + 7.0 * rays.rayDirection(px, py));
        ASSERT_TRUE(p.has_value());
        EXPECT_NEAR(p->x, px, 1e-9);
        EXPECT_NEAR(p->y, py, 1e-9);
    }
    EXPECT_FALSE(rays.projectToPixel(Vec3(1, 2, 5)).has_value()) << "behind the camera";
}

TEST(CameraRays, RejectsInvalidCamerasAndFixesParallelUp) {
    EXPECT_THROW(CameraRays(cameraAt(Vec3(0), Vec3(0)), 8, 8), std::invalid_argument);
    EXPECT_THROW(CameraRays(cameraAt(Vec3(0), Vec3(0, 0, -1), 0), 8, 8), std::invalid_argument);
    EXPECT_THROW(CameraRays(cameraAt(Vec3(0), Vec3(0, 0, -1)), 0, 8), std::invalid_argument);
    const CameraRays down(cameraAt(Vec3(0, 5, 0), Vec3(0, 0, 0)), 8, 8);
    const Vec3 d = down.rayDirection(4, 4);
    EXPECT_NEAR(glm::length(d - Vec3(0, -1, 0)), 0, 1e-12);
    EXPECT_NEAR(glm::dot(down.up(), down.forward()), 0, 1e-12);
}

// ---------------------------------------------------------------------------------------
// Renderer

TEST(Gouraud, UniformQuadFillingTheViewIsUniformRadiance) {
    const Scene scene = facingQuadScene();
    const Discretization disc(scene);
    const RayTracer tracer(disc);
    ASSERT_NEAR(glm::length(disc.elements()[0].normal - Vec3(0, 0, 1)), 0, 1e-9)
        << "the test assumes rotate_deg (90,0,0) turns +Y into +Z: "
        << disc.elements()[0].toString();

    const Rgb radiance(0.2, 0.5, 0.8);
    const std::vector<Rgb> b(disc.elements().size(), kPi * radiance);
    const Camera camera = cameraAt(Vec3(0, 0, 3), Vec3(0, 0, 0));
    const Image image = renderGouraud(disc, tracer, b, camera, 32, 24);
    ASSERT_EQ(image.width, 32);
    ASSERT_EQ(image.height, 24);
    expectUniform(image, radiance, 1e-9, "uniform quad");

    // Written as PNG, every pixel is the 8-bit sRGB encoding of B/π.
    const std::string path = ::testing::TempDir() + "penumbra_gouraud_uniform.png";
    writePng(image, path);
    const Image read = readPng(path);
    Rgb expected;
    for (int c = 0; c < 3; ++c)
        expected[c] = srgbDecode(std::round(255 * srgbEncode(radiance[c])) / 255);
    expectUniform(read, expected, 1e-12, "uniform quad PNG");
}

TEST(Gouraud, LinearRampIsInterpolatedBetweenNeighboursAndMonotonic) {
    const Scene scene = facingQuadScene();
    const Discretization disc(scene);
    const RayTracer tracer(disc);

    // Radiosity linear in x per element: channel 0 rises, channel 2 falls, channel 1 is flat.
    auto ramp = [](double x) { return Rgb(3.0 + 2.0 * x, 1.0, 5.0 - 1.5 * x); };
    std::vector<Rgb> b;
    for (const Element& e : disc.elements()) b.push_back(ramp(e.centroid.x));

    // 30° keeps the view inside |x| < 1.5 m, away from the quad's border elements.
    const Camera camera = cameraAt(Vec3(0, 0, 3), Vec3(0, 0, 0), 30);
    const int w = 48, h = 32;

    // One sample per pixel: the pixel lies between the values of its element and neighbours.
    const Image single = renderGouraud(disc, tracer, b, camera, w, h, 1);
    const CameraRays rays(camera, w, h);
    for (int y = 0; y < h; y += 3) {
        for (int x = 0; x < w; ++x) {
            const RayHit hit = tracer.intersect(rays.origin(), rays.rayDirection(x + 0.5, y + 0.5));
            ASSERT_GE(hit.element, 0) << "pixel (" << x << ", " << y << ") missed the quad";
            Rgb lo = b[hit.element], hi = b[hit.element];
            for (int n : disc.elementNeighbours(hit.element)) {
                lo = glm::min(lo, b[n]);
                hi = glm::max(hi, b[n]);
            }
            for (int c = 0; c < 3; ++c) {
                const double v = single.at(x, y)[c] * kPi;
                EXPECT_GE(v, lo[c] - 1e-9) << "pixel (" << x << ", " << y << ") channel " << c;
                EXPECT_LE(v, hi[c] + 1e-9) << "pixel (" << x << ", " << y << ") channel " << c;
            }
        }
    }

    // Supersampled: monotonic along rows and equal to the ramp at the pixel centre's hit
    // point (the visible part is interior, where vertex means of a linear field are exact,
    // and the pixel-to-plane map is affine so the box filter averages to the centre).
    const Image image = renderGouraud(disc, tracer, b, camera, w, h, 3);
    const double tanHalf = std::tan(glm::radians(15.0));
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const double worldX = 3.0 * (2.0 * (x + 0.5) / w - 1.0) * tanHalf * w / h;
            const Rgb expected = ramp(worldX) / kPi;
            EXPECT_NEAR(glm::length(image.at(x, y) - expected), 0, 1e-5)
                << "pixel (" << x << ", " << y << ") = " << vecString(image.at(x, y))
                << ", expected " << vecString(expected);
            if (x > 0) {
                EXPECT_GT(image.at(x, y).x, image.at(x - 1, y).x) << "row " << y << " x " << x;
                EXPECT_LT(image.at(x, y).z, image.at(x - 1, y).z) << "row " << y << " x " << x;
                EXPECT_NEAR(image.at(x, y).y, 1.0 / kPi, 1e-9);
            }
        }
    }
}

TEST(Gouraud, BoxSeenFromInsideIsBlackUnlessTwoSided) {
    const Camera camera = cameraAt(Vec3(0.1, 0.05, 0.2), Vec3(0.3, -0.2, -1), 90);
    const Rgb radiance(0.3, 0.6, 0.1);
    for (bool twoSided : {false, true}) {
        const Scene scene =
            oneObjectScene(ShapeType::Box, Vec3(2, 2, 2), Vec3(0, 0, 0), twoSided, 0.5);
        const Discretization disc(scene);
        const RayTracer tracer(disc);
        const std::vector<Rgb> b(disc.elements().size(), kPi * radiance);
        const Image image = renderGouraud(disc, tracer, b, camera, 24, 24);
        expectUniform(image, twoSided ? radiance : Rgb(0.0), 1e-9,
                      twoSided ? "two-sided box from inside" : "one-sided box from inside");
    }
}

TEST(Gouraud, BackOfQuadIsBlackUnlessTwoSidedAndMissesAreBlack) {
    const Camera behind = cameraAt(Vec3(0, 0, -3), Vec3(0, 0, 0));
    const Rgb radiance(0.4, 0.4, 0.2);
    for (bool twoSided : {false, true}) {
        const Scene scene = facingQuadScene(twoSided);
        const Discretization disc(scene);
        const RayTracer tracer(disc);
        const std::vector<Rgb> b(disc.elements().size(), kPi * radiance);
        expectUniform(renderGouraud(disc, tracer, b, behind, 16, 16),
                      twoSided ? radiance : Rgb(0.0), 1e-9, "quad from behind");
        const Camera away = cameraAt(Vec3(0, 0, 3), Vec3(0, 0, 6));
        expectUniform(renderGouraud(disc, tracer, b, away, 16, 16), Rgb(0.0), 0,
                      "camera looking away");
    }
}

TEST(Gouraud, PartialCoverageIsTheCoveredFraction) {
    // A 1 m quad seen head-on from 3 m: the image's edge pixels straddle its silhouette and
    // average the covered sub-samples (box filter); the total equals the covered area.
    const Scene scene = oneObjectScene(ShapeType::Quad, Vec3(1, 0, 1), Vec3(90, 0, 0), false, 0.25);
    const Discretization disc(scene);
    const RayTracer tracer(disc);
    const std::vector<Rgb> b(disc.elements().size(), Rgb(kPi));
    const Camera camera = cameraAt(Vec3(0, 0, 3), Vec3(0, 0, 0));
    const int size = 40, s = 8;
    const Image image = renderGouraud(disc, tracer, b, camera, size, size, s);
    double covered = 0;
    for (const Rgb& p : image.pixels) {
        EXPECT_GE(p.x, -1e-12);
        EXPECT_LE(p.x, 1 + 1e-9);
        covered += p.x;
    }
    // Pixel footprint at the quad's distance: (2·3·tan 20° / size)².
    const double pixelSide = 2 * 3 * std::tan(glm::radians(20.0)) / size;
    EXPECT_NEAR(covered * pixelSide * pixelSide, 1.0, 0.02);
}

TEST(Gouraud, DeterministicAcrossThreadCounts) {
    const Scene scene = oneObjectScene(ShapeType::Box, Vec3(1, 1, 1), Vec3(20, 30, 0), false, 0.2);
    const Discretization disc(scene);
    const RayTracer tracer(disc);
    std::vector<Rgb> b;
    for (const Element& e : disc.elements())
        b.push_back(Rgb(1 + e.centroid.x, 2, 1 - e.centroid.y));
    const Camera camera = cameraAt(Vec3(1.5, 1, 2), Vec3(0, 0, 0));
    const Image parallel = renderGouraud(disc, tracer, b, camera, 37, 29, 2);
    Image serial;
    tbb::task_arena one(1);
    one.execute([&] { serial = renderGouraud(disc, tracer, b, camera, 37, 29, 2); });
    ASSERT_EQ(parallel.pixels.size(), serial.pixels.size());
    int lit = 0;
    for (size_t i = 0; i < parallel.pixels.size(); ++i) {
        ASSERT_EQ(parallel.pixels[i], serial.pixels[i]) << "pixel index " << i;
        lit += parallel.pixels[i].y > 0;
    }
    EXPECT_GT(lit, 100) << "the box should cover part of the image";
}

TEST(Gouraud, APreviewVersionIsSeenAsIfAliveAndObjectAtNamesWhatEachPixelShows) {
    // A wall and, in front of its centre, a smaller quad: the "dragged" object. Dead, it is
    // gone from the plain image; as the preview version it is seen exactly as when alive.
    Scene scene = oneObjectScene(ShapeType::Quad, Vec3(6, 0, 6), Vec3(90, 0, 0), false, 0.5);
    SceneObject mover = scene.objects[0];
    mover.id = "mover";
    mover.shape.size = Vec3(1, 0, 1);
    mover.transform.translate = Vec3(0, 0, 1);
    scene.objects.push_back(mover);
    Discretization disc(scene);
    RayTracer tracer(disc);
    std::vector<Rgb> b;
    for (const Element& e : disc.elements())
        b.push_back(e.object == 0 ? Rgb(1, 2, 3) : Rgb(3 + e.centroid.x, 2, 1 - e.centroid.y));
    const Camera camera = cameraAt(Vec3(0.3, 0.2, 4), Vec3(0, 0, 0));
    const int w = 33, h = 25;

    std::vector<int> aliveAt;
    GouraudExtras alive;
    alive.objectAt = &aliveAt;
    const Image withMover = renderGouraud(disc, tracer, b, camera, w, h, 1, alive);
    ASSERT_EQ(aliveAt.size(), std::size_t(w * h));
    const int centre = (h / 2) * w + w / 2;
    EXPECT_EQ(aliveAt[centre], 1) << "the mover covers the centre";
    EXPECT_EQ(aliveAt[0], 0) << "the wall fills the corner";
    EXPECT_EQ(withMover.pixels, renderGouraud(disc, tracer, b, camera, w, h, 1).pixels)
        << "objectAt changes nothing in the image";

    disc.setAlive(1, false);
    tracer.updateAlive(1);
    std::vector<int> deadAt;
    GouraudExtras dead;
    dead.objectAt = &deadAt;
    const Image withoutMover = renderGouraud(disc, tracer, b, camera, w, h, 1, dead);
    EXPECT_EQ(deadAt[centre], 0) << "the wall behind the dead mover";
    EXPECT_NE(withoutMover.pixels[centre], withMover.pixels[centre]);

    std::vector<int> previewAt;
    GouraudExtras preview;
    preview.previewVersion = 1;
    preview.objectAt = &previewAt;
    const Image previewed = renderGouraud(disc, tracer, b, camera, w, h, 1, preview);
    EXPECT_EQ(previewAt, aliveAt);
    for (std::size_t i = 0; i < previewed.pixels.size(); ++i)
        ASSERT_EQ(previewed.pixels[i], withMover.pixels[i]) << "pixel index " << i;

    // objectAt is per pixel: one sample each.
    EXPECT_THROW(renderGouraud(disc, tracer, b, camera, w, h, 2, preview), std::invalid_argument);
}

TEST(Gouraud, RejectsBadArguments) {
    const Scene scene = facingQuadScene();
    const Discretization disc(scene);
    const RayTracer tracer(disc);
    const std::vector<Rgb> b(disc.elements().size(), Rgb(1.0));
    const Camera camera = cameraAt(Vec3(0, 0, 3), Vec3(0, 0, 0));
    EXPECT_THROW(renderGouraud(disc, tracer, std::vector<Rgb>(3), camera, 8, 8),
                 std::invalid_argument);
    EXPECT_THROW(renderGouraud(disc, tracer, b, camera, 8, 8, 0), std::invalid_argument);
    EXPECT_THROW(renderGouraud(disc, tracer, b, camera, 0, 8), std::invalid_argument);
}

}  // namespace
}  // namespace penumbra
