// Receivers in the open (Discretization::placeReceivers, SolverOptions::placeReceivers): an
// element whose centroid a solid resting on it covers receives at a point of it in the open.

#include <gtest/gtest.h>

#include "solver/discretization.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

/// A 2 m floor of 0.5 m elements under a lamp. A 0.4 × 0.4 × 0.8 box rests on it with its
/// footprint x ∈ [0.2, 0.6], z ∈ [−0.2, 0.6]: it covers the centroid (0.25, 0.25) of the
/// element [0, 0.5]², whose strip x < 0.2 stays in the open. A one-sided panel hangs 0.3 m
/// above the centroid of the element [−1, −0.5]², its back to the floor.
Scene boxOnAFloor() {
    Scene scene;
    test::addMaterial(scene, "grey", Rgb(0.5));
    test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(10.0));
    scene.objects.push_back(test::makeQuad("floor", 2, 2, "grey", {0, 0, 0}));
    scene.objects.push_back(test::makeQuad("lamp", 0.5, 0.5, "lamp", {0, 1.5, 0}, {180, 0, 0}));
    scene.objects.push_back(test::makeQuad("panel", 0.4, 0.4, "grey", {-0.75, 0.3, -0.75}));
    SceneObject box;
    box.id = "box";
    box.material = "grey";
    box.shape.type = ShapeType::Box;
    box.shape.size = Vec3(0.4, 0.8, 0.8);
    box.transform.translate = Vec3(0.4, 0.4, 0.2);
    scene.objects.push_back(box);
    scene.settings.patchSize = 0.5;
    scene.settings.elementSize = 0.5;
    return scene;
}

/// The floor's element whose centroid is nearest (x, z).
int floorElement(const Discretization& disc, double x, double z) {
    int best = -1;
    double bestDistance = 1e300;
    for (std::size_t e = 0; e < disc.elements().size(); ++e) {
        const Element& el = disc.elements()[e];
        if (el.object != 0) continue;
        const double d = glm::length(el.centroid - Vec3(x, 0, z));
        if (d < bestDistance) bestDistance = d, best = static_cast<int>(e);
    }
    return best;
}

TEST(ReceiverPlacement, ACoveredCentroidMovesIntoTheOpenPartOfItsElement) {
    Discretization disc(boxOnAFloor());
    RayTracer tracer(disc);
    EXPECT_EQ(disc.placeReceivers(tracer), 1);
    const int covered = floorElement(disc, 0.25, 0.25);
    const Vec3 r = disc.receiver(covered);
    EXPECT_LT(r.x, 0.2) << "in the strip the box leaves open";
    EXPECT_GT(r.x, 0.0);
    EXPECT_GT(r.z, 0.0);
    EXPECT_LT(r.z, 0.5);
    EXPECT_NEAR(r.y, 0.0, 1e-12) << "on the element";
    // Beside the box, and under the open panel, the centroids stay.
    for (const auto& [x, z] : {std::pair{0.75, 0.25}, std::pair{-0.25, 0.25},
                               std::pair{0.25, -0.25}, std::pair{-0.75, -0.75}}) {
        const int e = floorElement(disc, x, z);
        EXPECT_EQ(disc.receiver(e), disc.elements()[e].centroid) << x << " " << z;
    }
}

TEST(ReceiverPlacement, AnElementTheBoxCrossesReceivesTheLightOfItsOpenPart) {
    // Solved with receivers at the centroids, the crossed element gets no light at all; with
    // receivers placed, about what its open neighbour at the same distance from the lamp gets.
    for (const bool place : {false, true}) {
        Discretization disc(boxOnAFloor());
        RayTracer tracer(disc);
        SolverOptions options;
        options.placeReceivers = place;
        ProgressiveSolver solver(disc, tracer, options);
        solver.converge(1e-4, 100000);
        const double crossed = solver.radiosity()[floorElement(disc, 0.25, 0.25)].x;
        const double open = solver.radiosity()[floorElement(disc, -0.25, 0.25)].x;
        ASSERT_GT(open, 0.1);
        if (place)
            EXPECT_NEAR(crossed, open, 0.25 * open);
        else
            EXPECT_LT(crossed, 0.05 * open);
    }
}

}  // namespace
}  // namespace penumbra
