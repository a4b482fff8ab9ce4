// Two-sided materials (DESIGN.md: "reflects on both sides; emission stays front-only"): twin
// back elements, the ray tracer's mapping of back hits to them, and the light they receive
// compared with a one-sided surface turned over.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "render/gouraud_renderer.h"
#include "solver/discretization.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

/// A lamp facing up at y = 0 and a panel at y = 1 above it. `twoSided`: the panel faces up
/// (its back toward the lamp) in a two-sided material; otherwise it is one-sided and turned
/// over to face the lamp.
Scene panelOverLamp(bool twoSided, bool panelEmits = false) {
    Scene scene;
    scene.settings.patchSize = 0.5;
    scene.settings.elementSize = 0.25;
    test::addMaterial(scene, "lamp", Rgb(0.5), Rgb(10.0));
    test::addMaterial(scene, "panel", Rgb(0.6, 0.5, 0.4), panelEmits ? Rgb(3.0) : Rgb(0.0));
    scene.materials.back().material.twoSided = twoSided;
    scene.objects.push_back(test::makeQuad("lamp", 1.0, 1.0, "lamp", {0, 0, 0}));
    scene.objects.push_back(test::makeQuad("panel", 1.5, 1.0, "panel", {0.2, 1, 0},
                                           twoSided ? Vec3(0.0) : Vec3(180, 0, 0)));
    return scene;
}

std::vector<int> elementsOf(const Discretization& disc, int object, bool facingDown) {
    std::vector<int> out;
    for (std::size_t e = 0; e < disc.elements().size(); ++e)
        if (disc.elements()[e].object == object && (disc.elements()[e].normal.y < 0) == facingDown)
            out.push_back(static_cast<int>(e));
    return out;
}

TEST(TwoSided, BackSheetTwinsEveryFaceWithFlippedNormalsAndNoEmission) {
    Scene one = panelOverLamp(false, true), two = panelOverLamp(true, true);
    Discretization d1(one), d2(two);
    const int panel = 1;
    const auto front = elementsOf(d2, panel, false), back = elementsOf(d2, panel, true);
    ASSERT_FALSE(front.empty());
    EXPECT_EQ(front.size(), back.size());
    EXPECT_EQ(front.size(), elementsOf(d1, panel, true).size());
    double frontArea = 0, backArea = 0;
    for (int e : front) frontArea += d2.elements()[e].area;
    for (int e : back) backArea += d2.elements()[e].area;
    EXPECT_NEAR(frontArea, 1.5, 1e-12);
    EXPECT_NEAR(backArea, 1.5, 1e-12);
    for (int e : back) {
        const Element& el = d2.elements()[e];
        EXPECT_NEAR(el.normal.y, -1.0, 1e-12);
        EXPECT_EQ(d2.patchMaterial(el.patch).emission, Rgb(0.0)) << "emission is front-only";
        EXPECT_EQ(d2.patchMaterial(el.patch).reflectance, Rgb(0.6, 0.5, 0.4));
        // Every back element lies exactly on a front element.
        const bool matched = std::any_of(front.begin(), front.end(), [&](int f) {
            return glm::length(d2.elements()[f].centroid - el.centroid) < 1e-12;
        });
        EXPECT_TRUE(matched) << el.toString();
    }
    for (int e : front) EXPECT_EQ(d2.elementMaterial(e).emission, Rgb(3.0));
    // A one-sided scene has no twins.
    EXPECT_TRUE(d1.objects()[panel].faceTwin.empty());
}

TEST(TwoSided, RaysHittingTheBackReturnTheTwinWithItsOwnInterpolation) {
    Scene two = panelOverLamp(true), one = panelOverLamp(false);
    one.objects[1].transform.rotateDeg = Vec3(0.0);  // one-sided, facing up: back toward the lamp
    Discretization d2(two), d1(one);
    RayTracer t2(d2), t1(d1);
    for (int k = 0; k < 20; ++k) {
        const Vec3 origin(0.2 + 0.06 * (k - 10), 0.5, 0.03 * (k % 7) - 0.1);
        const Vec3 up(0, 1, 0);
        const RayHit h2 = t2.intersect(origin, up);
        ASSERT_EQ(h2.object, 1);
        const Element& el = d2.elements()[h2.element];
        EXPECT_FALSE(h2.backFace);
        EXPECT_LT(el.normal.y, 0) << "the back of a two-sided panel is its twin";
        EXPECT_LT(h2.geometricNormal.y, 0);
        // The weights interpolate the twin's own vertices to the hit point.
        Vec3 p(0.0);
        double sum = 0;
        for (std::size_t i = 0; i < el.vertices.size(); ++i) {
            p += h2.weights[i] * d2.objects()[1].worldPositions[el.vertices[i]];
            sum += h2.weights[i];
        }
        EXPECT_NEAR(sum, 1.0, 1e-9);
        EXPECT_LT(glm::length(p - h2.position), 1e-5);
        EXPECT_EQ(t2.firstHit(origin, up).element, h2.element);
        EXPECT_FALSE(t2.firstHit(origin, up).backFace);
        // From above the front is hit.
        const RayHit top = t2.intersect(origin + Vec3(0, 1, 0), -up);
        EXPECT_GT(d2.elements()[top.element].normal.y, 0);
        EXPECT_FALSE(top.backFace);
        // One-sided: the front element, seen from behind.
        const RayHit h1 = t1.intersect(origin, up);
        EXPECT_TRUE(h1.backFace);
        EXPECT_GT(d1.elements()[h1.element].normal.y, 0);
    }
}

TEST(TwoSided, BackReceivesAndReflectsAsAOneSidedSurfaceTurnedOver) {
    // The two-sided panel's back and the turned-over one-sided panel see the same lamp with
    // nothing in between: exact contour-integral form factors make them agree to rounding.
    // The lamp also receives the panel's reflection, so the exchange runs both ways.
    Scene two = panelOverLamp(true), one = panelOverLamp(false);
    Discretization d2(two), d1(one);
    RayTracer t2(d2), t1(d1);
    ProgressiveSolver s2(d2, t2), s1(d1, t1);
    s2.converge(1e-9, 100000);
    s1.converge(1e-9, 100000);
    const auto back = elementsOf(d2, 1, true), turned = elementsOf(d1, 1, true);
    ASSERT_EQ(back.size(), turned.size());
    double maxB = 0;
    for (int e : back) {
        const Element& el = d2.elements()[e];
        auto match = std::find_if(turned.begin(), turned.end(), [&](int f) {
            return glm::length(d1.elements()[f].centroid - el.centroid) < 1e-9;
        });
        ASSERT_NE(match, turned.end());
        const Rgb b2 = s2.radiosity()[e], b1 = s1.radiosity()[*match];
        EXPECT_NEAR(b2.x, b1.x, 1e-6 * b1.x + 1e-12);
        EXPECT_NEAR(b2.z, b1.z, 1e-6 * b1.z + 1e-12);
        maxB = std::max(maxB, b2.x);
    }
    EXPECT_GT(maxB, 0.5) << "the back must be lit";
    // The front sees no light at all (nothing above it).
    for (int e : elementsOf(d2, 1, false)) EXPECT_EQ(s2.radiosity()[e], Rgb(0.0));
    // The lamp gets the same light back in both scenes.
    for (int e : elementsOf(d2, 0, false)) {
        const Rgb b2 = s2.radiosity()[e];
        const Rgb b1 = s1.radiosity()[e];
        EXPECT_NEAR(b2.x, b1.x, 1e-6 * b1.x);
    }
}

TEST(TwoSided, GouraudShowsTheBacksOwnLight) {
    // Seen from below, between lamp and panel, the two-sided panel's centre pixel shows the
    // back's radiosity (B/π), the turned-over one-sided panel the same, and a one-sided
    // panel facing away shows black (its back absorbs).
    Camera below;
    below.position = Vec3(0.2, 0.3, 0.9);
    below.lookAt = Vec3(0.2, 1.0, 0.0);
    below.up = Vec3(0, 0, -1);
    auto centre = [&](const Scene& scene) {
        Discretization disc(scene);
        RayTracer tracer(disc);
        ProgressiveSolver solver(disc, tracer);
        solver.converge(1e-9, 100000);
        const Image img = renderGouraud(disc, tracer, solver.radiosity(), below, 33, 33, 1);
        return img.pixels[16 * 33 + 16];
    };
    Scene away = panelOverLamp(false);
    away.objects[1].transform.rotateDeg = Vec3(0.0);
    const Rgb two = centre(panelOverLamp(true)), turned = centre(panelOverLamp(false));
    EXPECT_GT(two.x, 0.05);
    EXPECT_NEAR(two.x, turned.x, 1e-3 * turned.x);
    EXPECT_NEAR(two.z, turned.z, 1e-3 * turned.z);
    EXPECT_EQ(centre(away), Rgb(0.0));
}

}  // namespace
}  // namespace penumbra
