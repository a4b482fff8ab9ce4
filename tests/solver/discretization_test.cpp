// Discretization into patches and elements, against closed forms computed here:
//  - counts: the smallest grid whose cells are no longer than patch_size (patches) and, within
//    each patch, element_size (elements), measured in world space; `segments` for round shapes;
//  - areas: exact for quads and boxes; for spheres and cylinders the exact area of the
//    inscribed polyhedron (trapezoid and regular-polygon formulas), which must lie between
//    cos²(largest facet angle) · 4πr² and 4πr² (resp. the cylinder's 2πrh + 2πr² scaled by the
//    regular-polygon ratio);
//  - structure: each element in exactly one patch, patch areas, outward normals, transforms
//    (written out with explicit trigonometry in test_scenes.h), conforming split meshes (no
//    interior boundary edges; Euler characteristic of a closed mesh), vertex values, symmetric
//    neighbours, and element subdivision that keeps area and conformity.
//
// Index: helpers · quads and boxes · spheres and cylinders · transforms · meshes ·
//        vertex values and neighbours · subdivision

#include "solver/discretization.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "test_scenes.h"

namespace penumbra {
namespace {

// ---------------------------------------------------------------------------------------------
// Helpers

std::string str(const Vec3& v) {
    std::ostringstream s;
    s.precision(9);
    s << "(" << v.x << ", " << v.y << ", " << v.z << ")";
    return s.str();
}

/// Patches along a length, and elements along one patch: the fewest equal cells no longer
/// than the target (lengths are chosen away from exact multiples).
int cells(double length, double target) { return static_cast<int>(std::ceil(length / target)); }

/// Element meshes hold double-precision points, so "exact" geometry below means to within
/// kExact relative (rounding only).
constexpr double kExact = 1e-12;

SceneObject makeShape(const std::string& id, ShapeType type) {
    SceneObject o;
    o.id = id;
    o.shape.type = type;
    o.material = "white";
    return o;
}

Scene sceneWith(std::vector<SceneObject> objects, double patchSize, double elementSize) {
    Scene scene = test::emptyScene(patchSize, elementSize);
    test::addMaterial(scene, "white", Rgb(0.5));
    scene.objects = std::move(objects);
    return scene;
}

/// Each element in exactly one patch, of the same object; patch area = Σ element areas;
/// element areas positive; total area = Σ patch areas.
void checkPatchStructure(const Discretization& disc) {
    std::vector<int> owner(disc.elements().size(), -1);
    double total = 0;
    for (int p = 0; p < static_cast<int>(disc.patches().size()); ++p) {
        const Patch& P = disc.patches()[p];
        ASSERT_FALSE(P.elements.empty()) << "patch " << p << " has no elements";
        double sum = 0;
        for (int e : P.elements) {
            ASSERT_GE(e, 0);
            ASSERT_LT(e, static_cast<int>(disc.elements().size()));
            EXPECT_EQ(owner[e], -1)
                << "element " << e << " is in patches " << owner[e] << " and " << p;
            owner[e] = p;
            EXPECT_EQ(disc.elements()[e].patch, p)
                << "element " << e << " names patch " << disc.elements()[e].patch << ", listed in "
                << p;
            EXPECT_EQ(disc.elements()[e].object, P.object);
            EXPECT_GT(disc.elements()[e].area, 0);
            sum += disc.elements()[e].area;
        }
        EXPECT_NEAR(P.area, sum, 1e-12 * sum)
            << "patch " << p << ": area " << P.area << ", Σ element areas " << sum;
        total += P.area;
    }
    for (std::size_t e = 0; e < owner.size(); ++e)
        EXPECT_GE(owner[e], 0) << "element " << e << " belongs to no patch";
    EXPECT_NEAR(disc.totalArea(), total, 1e-12 * total);
}

double objectArea(const Discretization& disc, int object) {
    double a = 0;
    for (const Element& el : disc.elements())
        if (el.object == object) a += el.area;
    return a;
}

int objectElements(const Discretization& disc, int object) {
    int n = 0;
    for (const Element& el : disc.elements()) n += el.object == object;
    return n;
}

int objectPatches(const Discretization& disc, int object) {
    int n = 0;
    for (const Patch& p : disc.patches()) n += p.object == object;
    return n;
}

/// Every element's normal points away from `centre`.
void checkOutward(const Discretization& disc, int object, const Vec3& centre) {
    for (int e = 0; e < static_cast<int>(disc.elements().size()); ++e) {
        const Element& el = disc.elements()[e];
        if (el.object != object) continue;
        EXPECT_GT(glm::dot(el.centroid - centre, el.normal), 0) << "inward: " << el.toString();
        EXPECT_NEAR(glm::length(el.normal), 1.0, 1e-12);
    }
}

/// World length of the object's boundary edges (OpenMesh): zero for a closed conforming
/// mesh, the outer rim for an open one; a T-junction or unshared split point adds to it.
double boundaryLength(const Discretization& disc, int object, int* count = nullptr) {
    const ObjectSurface& s = disc.objects()[object];
    double length = 0;
    int n = 0;
    for (auto e : s.mesh.edges())
        if (s.mesh.is_boundary(e)) {
            auto h = s.mesh.halfedge_handle(e, 0);
            length += glm::length(s.worldPositions[s.mesh.to_vertex_handle(h).idx()] -
                                  s.worldPositions[s.mesh.from_vertex_handle(h).idx()]);
            ++n;
        }
    if (count) *count = n;
    return length;
}

void checkNeighboursSymmetric(const Discretization& disc) {
    for (int e = 0; e < static_cast<int>(disc.elements().size()); ++e) {
        const std::vector<int> nbs = disc.elementNeighbours(e);
        EXPECT_EQ(std::find(nbs.begin(), nbs.end(), e), nbs.end())
            << "element " << e << " is its own neighbour";
        for (int nb : nbs) {
            const std::vector<int> back = disc.elementNeighbours(nb);
            ASSERT_NE(std::find(back.begin(), back.end(), e), back.end())
                << "element " << e << " lists " << nb << " as a neighbour, not conversely";
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Quads and boxes

TEST(Discretization, QuadCountsAndAreas) {
    // 2.3 × 1.1 with patches ≤ 0.5 and elements ≤ 0.12: 5 × 3 patches of 4 × 4 elements.
    const double sx = 2.3, sz = 1.1, P = 0.5, E = 0.12;
    Discretization disc(sceneWith({test::makeQuad("q", sx, sz, "white", {0, 0, 0})}, P, E));
    const int pu = cells(sx, P), pv = cells(sz, P);
    const int eu = cells(sx / pu, E), ev = cells(sz / pv, E);
    ASSERT_EQ(pu * pv, 15);
    EXPECT_EQ(disc.patches().size(), static_cast<std::size_t>(pu * pv));
    EXPECT_EQ(disc.elements().size(), static_cast<std::size_t>(pu * eu * pv * ev));
    EXPECT_NEAR(disc.totalArea(), sx * sz, kExact * sx * sz) << disc.toString();
    const double elementArea = (sx / (pu * eu)) * (sz / (pv * ev));
    for (const Element& el : disc.elements()) {
        EXPECT_NEAR(el.area, elementArea, kExact * elementArea) << el.toString();
        EXPECT_NEAR(el.normal.y, 1.0, 1e-12) << el.toString();
        EXPECT_EQ(el.vertices.size(), 4u);
    }
    for (const Patch& p : disc.patches())
        EXPECT_NEAR(p.area, sx * sz / (pu * pv), kExact * p.area) << p.toString();
    checkPatchStructure(disc);
    EXPECT_NEAR(boundaryLength(disc, 0), 2 * (sx + sz), kExact) << "shared grid vertices";
}

TEST(Discretization, ObjectPatchSizeOverridesTheScenes) {
    // A 0.8 × 0.6 lamp with its own patch_size 1: one shooter whose outline is the whole
    // quad, elements still of the scene's element_size (8 × 6 of 0.1).
    SceneObject lamp = test::makeQuad("lamp", 0.8, 0.6, "white", {0, 0, 0});
    lamp.patchSize = 1.0;
    Discretization disc(
        sceneWith({lamp, test::makeQuad("floor", 0.8, 0.6, "white", {0, -1, 0})}, 0.1, 0.1));
    int lampPatches = 0, floorPatches = 0;
    for (const Patch& p : disc.patches()) (p.object == 0 ? lampPatches : floorPatches) += 1;
    EXPECT_EQ(lampPatches, 1);
    EXPECT_EQ(floorPatches, 48);
    EXPECT_EQ(disc.patches()[0].elements.size(), 48u);
    EXPECT_NEAR(disc.patches()[0].area, 0.48, kExact);
    EXPECT_EQ(disc.patches()[0].outline.size(), 4u) << "a planar patch keeps its outline";
    checkPatchStructure(disc);
}

TEST(Discretization, BoxCountsAreasAndOutwardNormals) {
    const Vec3 size(0.9, 0.45, 1.3);
    const double P = 0.5, E = 0.2;
    SceneObject box = makeShape("box", ShapeType::Box);
    box.shape.size = size;
    Discretization disc(sceneWith({box}, P, E));
    int elements = 0, patches = 0;
    for (auto [a, b] : {std::pair{size.y, size.z}, {size.z, size.x}, {size.x, size.y}}) {
        int pa = cells(a, P), pb = cells(b, P);
        patches += 2 * pa * pb;
        elements += 2 * pa * cells(a / pa, E) * pb * cells(b / pb, E);
    }
    EXPECT_EQ(static_cast<int>(disc.patches().size()), patches);
    EXPECT_EQ(static_cast<int>(disc.elements().size()), elements);
    const double area = 2 * (size.x * size.y + size.y * size.z + size.z * size.x);
    EXPECT_NEAR(disc.totalArea(), area, kExact * area);
    checkOutward(disc, 0, Vec3(0.0));
    checkPatchStructure(disc);
    // Every element lies on the box surface, its normal the face's axis.
    for (const Element& el : disc.elements()) {
        const Vec3 an = glm::abs(el.normal);
        const int axis = an.x > 0.5 ? 0 : an.y > 0.5 ? 1 : 2;
        EXPECT_NEAR(std::abs(el.centroid[axis]), size[axis] / 2, kExact) << el.toString();
        EXPECT_NEAR(an[axis], 1.0, kExact) << el.toString();
    }
}

// ---------------------------------------------------------------------------------------------
// Spheres and cylinders

/// Area of the UV sphere inscribed polyhedron with nu cells around and nv from pole to pole:
/// isosceles trapezoids (triangles at the poles). Also returns the smallest distance from the
/// centre to a facet plane, for the bound cos² · 4πr² ≤ area ≤ 4πr².
double uvSphereArea(double r, int nu, int nv, double* minPlaneDistance) {
    const double dphi = 2 * M_PI / nu, c = std::cos(dphi / 2), s = std::sin(dphi / 2);
    double area = 0, dmin = r;
    for (int j = 0; j < nv; ++j) {
        const double t0 = M_PI * j / nv, t1 = M_PI * (j + 1) / nv;
        const double a = 2 * r * std::sin(t0) * s, b = 2 * r * std::sin(t1) * s;
        // Chord midpoints in the meridian plane through the cell's middle: (ρ, y).
        const double m0x = r * std::sin(t0) * c, m0y = r * std::cos(t0);
        const double m1x = r * std::sin(t1) * c, m1y = r * std::cos(t1);
        const double h = std::hypot(m1x - m0x, m1y - m0y);
        area += nu * 0.5 * (a + b) * h;
        dmin = std::min(dmin, std::abs(m0x * m1y - m0y * m1x) / h);
    }
    if (minPlaneDistance) *minPlaneDistance = dmin;
    return area;
}

/// The number of elements around the vertex at world position `apex` (a pole or cap centre).
int fanCountAt(const Discretization& disc, int object, const Vec3& apex) {
    int n = 0;
    for (int e = 0; e < static_cast<int>(disc.elements().size()); ++e) {
        if (disc.elements()[e].object != object) continue;
        for (const Vec3& v : disc.elementPolygon(e))
            if (glm::length(v - apex) < 1e-6) {
                ++n;
                break;
            }
    }
    return n;
}

void checkSphere(double r, int segments, double P, double E, Vec3 centre, int expectNu,
                 int expectNv) {
    SceneObject sphere = makeShape("sphere", ShapeType::Sphere);
    sphere.shape.radius = r;
    sphere.shape.segments = segments;
    sphere.transform.translate = centre;
    Discretization disc(sceneWith({sphere}, P, E));
    const int nu = fanCountAt(disc, 0, centre + Vec3(0, r, 0));
    ASSERT_GT(nu, 0) << "no element touches the north pole";
    EXPECT_EQ(fanCountAt(disc, 0, centre - Vec3(0, r, 0)), nu) << "south pole";
    ASSERT_EQ(disc.elements().size() % nu, 0u);
    const int nv = static_cast<int>(disc.elements().size()) / nu;
    EXPECT_GE(nu, segments);
    EXPECT_GE(nv, segments / 2);
    if (expectNu > 0) {
        EXPECT_EQ(nu, expectNu);
    }
    if (expectNv > 0) {
        EXPECT_EQ(nv, expectNv);
    }

    double dmin = 0;
    const double poly = uvSphereArea(r, nu, nv, &dmin);
    const double sphereArea = 4 * M_PI * r * r;
    EXPECT_NEAR(disc.totalArea(), poly, kExact * poly)
        << "UV sphere " << nu << " × " << nv << ": area " << disc.totalArea()
        << ", inscribed polyhedron " << poly;
    EXPECT_LE(disc.totalArea(), sphereArea) << "an inscribed polyhedron is smaller than 4πr²";
    EXPECT_GE(disc.totalArea(), sphereArea * (dmin / r) * (dmin / r))
        << "area " << disc.totalArea()
        << " below cos²α · 4πr² = " << sphereArea * (dmin / r) * (dmin / r);
    for (int e = 0; e < static_cast<int>(disc.elements().size()); ++e)
        for (const Vec3& v : disc.elementPolygon(e))
            ASSERT_NEAR(glm::length(v - centre), r, kExact * r) << "vertex off the sphere";
    checkOutward(disc, 0, centre);
    checkPatchStructure(disc);
    int boundaryEdges = 0;
    EXPECT_EQ(boundaryLength(disc, 0, &boundaryEdges), 0.0)
        << boundaryEdges << " boundary edges: the sphere's seam or poles are not shared";
    checkNeighboursSymmetric(disc);
}

TEST(Discretization, SphereCoarseIsSegmentsByHalfSegments) {
    // Patches and elements larger than the sphere: the grid is `segments` × segments/2, one
    // patch.
    checkSphere(1.0, 12, 100, 100, Vec3(0.0), 12, 6);
    Discretization disc(sceneWith({[] {
                                      SceneObject s = makeShape("s", ShapeType::Sphere);
                                      s.shape.radius = 1.0;
                                      s.shape.segments = 12;
                                      return s;
                                  }()},
                                  100, 100));
    EXPECT_EQ(disc.patches().size(), 1u);
    EXPECT_EQ(disc.elements().size(), 72u);
}

TEST(Discretization, SphereFineAreaApproachesFourPiRSquared) {
    checkSphere(0.7, 16, 0.5, 0.15, Vec3(1, -2, 0.5), 0, 0);
    checkSphere(0.3, 8, 0.25, 0.05, Vec3(0.0), 0, 0);
}

void checkCylinder(double r, double h, int segments, double P, double E, Vec3 centre,
                   int expectNu) {
    SceneObject cyl = makeShape("cylinder", ShapeType::Cylinder);
    cyl.shape.radius = r;
    cyl.shape.height = h;
    cyl.shape.segments = segments;
    cyl.transform.translate = centre;
    Discretization disc(sceneWith({cyl}, P, E));
    const int nu = fanCountAt(disc, 0, centre + Vec3(0, h / 2, 0));
    EXPECT_EQ(fanCountAt(disc, 0, centre - Vec3(0, h / 2, 0)), nu) << "bottom cap";
    EXPECT_GE(nu, segments);
    if (expectNu > 0) {
        EXPECT_EQ(nu, expectNu);
    }
    // Side: nu planar rectangles of chord 2r sin(π/nu); caps: regular nu-gons.
    const double side = nu * 2 * r * std::sin(M_PI / nu) * h;
    const double caps = 2 * 0.5 * nu * r * r * std::sin(2 * M_PI / nu);
    const double round = 2 * M_PI * r * h + 2 * M_PI * r * r;
    EXPECT_NEAR(disc.totalArea(), side + caps, kExact * (side + caps))
        << nu << "-sided cylinder: area " << disc.totalArea() << ", closed form " << side + caps;
    const double ratio = std::sin(2 * M_PI / nu) / (2 * M_PI / nu);  // the smaller of the two
    EXPECT_LE(disc.totalArea(), round);
    EXPECT_GE(disc.totalArea(), ratio * round)
        << "area " << disc.totalArea() << " below the regular-polygon bound " << ratio * round;
    checkOutward(disc, 0, centre);
    checkPatchStructure(disc);
    checkNeighboursSymmetric(disc);
    // Side vertices on the cylinder, cap vertices within the disk.
    for (const Element& el : disc.elements()) {
        const bool cap = std::abs(el.normal.y) > 0.5;
        for (int v : el.vertices) {
            const Vec3 p = disc.objects()[0].worldPositions[v] - centre;
            if (cap) {
                EXPECT_NEAR(std::abs(p.y), h / 2, kExact);
            } else {
                EXPECT_NEAR(std::hypot(p.x, p.z), r, kExact * r);
            }
        }
    }
}

TEST(Discretization, CylinderCoarseAndFine) {
    checkCylinder(0.5, 1.2, 20, 100, 100, Vec3(0.0), 20);
    Discretization coarse(sceneWith({[] {
                                        SceneObject c = makeShape("c", ShapeType::Cylinder);
                                        c.shape.radius = 0.5;
                                        c.shape.height = 1.2;
                                        c.shape.segments = 20;
                                        return c;
                                    }()},
                                    100, 100));
    EXPECT_EQ(coarse.patches().size(), 3u) << "side and two caps";
    EXPECT_EQ(coarse.elements().size(), 60u) << "20 side quads and 20 triangles per cap";
    checkCylinder(0.4, 0.9, 12, 0.5, 0.1, Vec3(-1, 0.5, 2), 0);
}

TEST(Discretization, ParallelogramOutlinesAndTheirFans) {
    // The form factors sample a parallelogram outline directly and any other outline by its
    // fan triangles. Quads (also tilted and far from the origin), box faces and the back
    // sheet of a two-sided quad are parallelograms; a cylinder's disk caps are not. Every
    // outline's fans add up to twice its patch's area.
    SceneObject far = test::makeQuad("far", 0.7, 0.3, "white", {1e4, -2e4, 3e4}, {20, 35, 50});
    SceneObject box = makeShape("box", ShapeType::Box);
    box.shape.size = Vec3(0.9, 0.45, 1.3);
    box.transform.rotateDeg = Vec3(10, 20, 30);
    SceneObject cylinder = makeShape("cylinder", ShapeType::Cylinder);
    cylinder.shape.radius = 0.5;
    cylinder.shape.height = 1.2;
    cylinder.shape.segments = 20;
    cylinder.transform.translate = Vec3(3, 0, 0);
    SceneObject sheet = test::makeQuad("sheet", 0.8, 0.6, "both", {0, 2, 0});
    Scene scene = sceneWith({far, box, cylinder, sheet}, 100, 100);
    test::addMaterial(scene, "both", Rgb(0.5));
    scene.materials.back().material.twoSided = true;
    Discretization disc(scene);
    int parallelograms[4] = {0, 0, 0, 0}, others[4] = {0, 0, 0, 0};
    for (const Patch& P : disc.patches()) {
        if (P.outline.empty()) continue;
        ASSERT_FALSE(P.outlineFans.empty());
        EXPECT_NEAR(P.outlineFans.back(), 2 * P.area, 1e-6 * P.area) << P.toString();
        (P.parallelogram ? parallelograms : others)[P.object] += 1;
    }
    EXPECT_EQ(parallelograms[0], 1) << "the far, tilted quad";
    EXPECT_EQ(others[0], 0);
    EXPECT_EQ(parallelograms[1], 6) << "the box's faces";
    EXPECT_EQ(others[1], 0);
    EXPECT_EQ(others[2], 2) << "the cylinder's caps";
    EXPECT_EQ(parallelograms[2], 0);
    EXPECT_EQ(parallelograms[3], 2) << "the two-sided quad's front and back sheets";
    EXPECT_EQ(others[3], 0);
}

// ---------------------------------------------------------------------------------------------
// Transforms

TEST(Discretization, QuadTransformIsScaleThenRotateXYZThenTranslate) {
    // Rotating +Y by 90° about X then 90° about Y gives +X (the other order would give +Z).
    SceneObject quad = test::makeQuad("q", 1, 1, "white", {1, 2, 3}, {90, 90, 0});
    quad.transform.scale = Vec3(2, 1, 0.5);
    Discretization disc(sceneWith({quad}, 0.5, 0.25));
    const Vec3 normal = test::worldDirection(quad.transform, {0, 1, 0});
    ASSERT_NEAR(normal.x, 1.0, 1e-12) << str(normal);
    const std::vector<Vec3> corners = test::quadCorners(quad);
    Vec3 lo(1e9), hi(-1e9), clo(1e9), chi(-1e9);
    for (const Vec3& c : corners) clo = glm::min(clo, c), chi = glm::max(chi, c);
    for (int e = 0; e < static_cast<int>(disc.elements().size()); ++e) {
        const Element& el = disc.elements()[e];
        EXPECT_NEAR(glm::dot(el.normal, normal), 1.0, kExact) << el.toString();
        for (const Vec3& v : disc.elementPolygon(e)) {
            lo = glm::min(lo, v), hi = glm::max(hi, v);
            EXPECT_NEAR(glm::dot(v - quad.transform.translate, normal), 0, kExact);
        }
    }
    for (int k = 0; k < 3; ++k) {
        EXPECT_NEAR(lo[k], clo[k], kExact) << "axis " << k << ": " << str(lo) << " vs " << str(clo);
        EXPECT_NEAR(hi[k], chi[k], kExact) << "axis " << k << ": " << str(hi) << " vs " << str(chi);
    }
    EXPECT_NEAR(disc.totalArea(), 2.0 * 0.5, kExact);
    // Gridded in world units: 2 m → 4 patches × 2 elements, 0.5 m → 1 patch × 2 elements.
    EXPECT_EQ(disc.patches().size(), 4u);
    EXPECT_EQ(disc.elements().size(), 16u);
}

TEST(Discretization, BoxTransformInWorldSpace) {
    SceneObject box = makeShape("box", ShapeType::Box);
    box.shape.size = Vec3(1, 2, 3);
    box.transform.scale = Vec3(1, 1, 2);
    box.transform.rotateDeg = Vec3(0, 0, 90);
    box.transform.translate = Vec3(5, 0, 0);
    Discretization disc(sceneWith({box}, 0.5, 0.25));
    // Scaled to 1 × 2 × 6, then (x, y) → (−y, x): AABB [4, 6] × [−0.5, 0.5] × [−3, 3].
    Vec3 lo(1e9), hi(-1e9);
    for (int e = 0; e < static_cast<int>(disc.elements().size()); ++e)
        for (const Vec3& v : disc.elementPolygon(e)) lo = glm::min(lo, v), hi = glm::max(hi, v);
    const Vec3 wantLo(4, -0.5, -3), wantHi(6, 0.5, 3);
    for (int k = 0; k < 3; ++k) {
        EXPECT_NEAR(lo[k], wantLo[k], kExact * 10) << str(lo);
        EXPECT_NEAR(hi[k], wantHi[k], kExact * 10) << str(hi);
    }
    EXPECT_NEAR(disc.totalArea(), 2 * (2 * 1 + 1 * 6 + 2 * 6), kExact * 40);
    checkOutward(disc, 0, box.transform.translate);
    checkPatchStructure(disc);
    // World-space gridding: the 6 m edge gets 12 patches of 2 elements.
    int longFaceElements = 0;
    for (const Element& el : disc.elements()) longFaceElements += std::abs(el.normal.x) > 0.5;
    EXPECT_EQ(longFaceElements, 2 * (12 * 2) * (2 * 2)) << "±X faces are 6 m × 1 m";
}

TEST(Discretization, ScaledRotatedSphere) {
    // Uniform scale 2 with rotation and translation: the area is 4 × that of the unit-radius
    // polyhedron with the same grid, and the normals point away from the translated centre.
    SceneObject s = makeShape("s", ShapeType::Sphere);
    s.shape.radius = 0.5;
    s.shape.segments = 10;
    s.transform.scale = Vec3(2.0);
    s.transform.rotateDeg = Vec3(20, -35, 50);
    s.transform.translate = Vec3(-1, 3, 2);
    Discretization disc(sceneWith({s}, 100, 100));
    EXPECT_EQ(disc.elements().size(), 50u) << "10 × 5 grid";
    EXPECT_NEAR(disc.totalArea(), uvSphereArea(1.0, 10, 5, nullptr), kExact * disc.totalArea());
    checkOutward(disc, 0, s.transform.translate);
    // The pole follows the rotation.
    const Vec3 pole = test::worldPoint(s.transform, {0, 0.5, 0});
    EXPECT_EQ(fanCountAt(disc, 0, pole), 10) << "no fan at the rotated pole " << str(pole);
}

// ---------------------------------------------------------------------------------------------
// Meshes

TEST(Discretization, LargeTriangleIsSplitConformingly) {
    SceneObject o = makeShape("tri", ShapeType::Mesh);
    const Vec3 a(0, 0, 0), b(1.3, 0, 0), c(0, 0, -0.9);  // counter-clockwise from +Y
    o.shape.mesh.positions = {a, b, c};
    o.shape.mesh.triangles = {{0, 1, 2}};
    const double E = 0.2;
    Discretization disc(sceneWith({o}, 0.5, E));
    const double longest = glm::length(c - b);
    const int n = cells(longest, E);  // 8: edges split into n, the triangle into n²
    ASSERT_EQ(n, 8);
    EXPECT_EQ(disc.elements().size(), static_cast<std::size_t>(n * n));
    EXPECT_EQ(disc.objects()[0].mesh.n_vertices(), static_cast<std::size_t>((n + 1) * (n + 2) / 2));
    const double area = 0.5 * 1.3 * 0.9;
    EXPECT_NEAR(disc.totalArea(), area, kExact * area);
    for (const Element& el : disc.elements()) {
        EXPECT_NEAR(el.area, area / (n * n), kExact * area / (n * n)) << el.toString();
        EXPECT_NEAR(el.normal.y, 1.0, kExact) << el.toString();
        EXPECT_EQ(el.vertices.size(), 3u);
    }
    EXPECT_NEAR(boundaryLength(disc, 0), 1.3 + 0.9 + longest, kExact)
        << "interior boundary edges: split points are not shared";
    checkPatchStructure(disc);
    checkNeighboursSymmetric(disc);
}

/// A regular icosahedron of edge 2 (vertices (0, ±1, ±φ) and cyclic), outward winding.
TriMesh icosahedron() {
    const double phi = (1 + std::sqrt(5.0)) / 2;
    TriMesh m;
    for (double s1 : {-1.0, 1.0})
        for (double s2 : {-phi, phi}) {
            m.positions.push_back({0, s1, s2});
            m.positions.push_back({s1, s2, 0});
            m.positions.push_back({s2, 0, s1});
        }
    const int n = static_cast<int>(m.positions.size());
    auto edge = [&](int i, int j) {
        return std::abs(glm::length(m.positions[i] - m.positions[j]) - 2.0) < 1e-9;
    };
    for (int i = 0; i < n; ++i)
        for (int j = i + 1; j < n; ++j)
            for (int k = j + 1; k < n; ++k)
                if (edge(i, j) && edge(j, k) && edge(i, k)) {
                    const Vec3 nrm = glm::cross(m.positions[j] - m.positions[i],
                                                m.positions[k] - m.positions[i]);
                    if (glm::dot(nrm, m.positions[i]) > 0)
                        m.triangles.push_back({i, j, k});
                    else
                        m.triangles.push_back({i, k, j});
                }
    return m;
}

void checkIcosahedron(const Transform& t, double elementSize, int expectN) {
    SceneObject o = makeShape("ico", ShapeType::Mesh);
    o.shape.mesh = icosahedron();
    ASSERT_EQ(o.shape.mesh.positions.size(), 12u);
    ASSERT_EQ(o.shape.mesh.triangles.size(), 20u);
    o.transform = t;
    Discretization disc(sceneWith({o}, 0.5, elementSize));
    const double edge = 2.0 * t.scale.x;  // uniform scale
    const int n = cells(edge, elementSize);
    ASSERT_EQ(n, expectN);
    // Geodesic frequency n: F = 20 n², V = 10 n² + 2, E = 30 n²; closed: χ = 2, no boundary.
    const auto& mesh = disc.objects()[0].mesh;
    EXPECT_EQ(disc.elements().size(), static_cast<std::size_t>(20 * n * n));
    EXPECT_EQ(mesh.n_vertices(), static_cast<std::size_t>(10 * n * n + 2))
        << "split points along shared edges must be shared";
    EXPECT_EQ(mesh.n_edges(), static_cast<std::size_t>(30 * n * n));
    int boundaryEdges = 0;
    EXPECT_EQ(boundaryLength(disc, 0, &boundaryEdges), 0.0) << boundaryEdges << " boundary edges";
    EXPECT_EQ(static_cast<long>(mesh.n_vertices()) - static_cast<long>(mesh.n_edges()) +
                  static_cast<long>(mesh.n_faces()),
              2L);
    const double area = 20 * std::sqrt(3.0) / 4 * edge * edge;
    EXPECT_NEAR(disc.totalArea(), area, kExact * area);
    checkOutward(disc, 0, t.translate);
    checkPatchStructure(disc);
    checkNeighboursSymmetric(disc);
}

TEST(Discretization, IcosahedronSplitStaysClosed) {
    checkIcosahedron(Transform{}, 0.7, 3);
    Transform t;
    t.scale = Vec3(0.5);
    t.rotateDeg = Vec3(10, 20, 30);
    t.translate = Vec3(1, 1, 1);
    checkIcosahedron(t, 0.7, 2);
    checkIcosahedron(Transform{}, 3.0, 1);  // no split
}

TEST(Discretization, GroupingByElementsKeepsTheElementsOneAPatch) {
    // Every kind of shape, a two-sided panel and mesh, a lamp with its own patch size, under
    // patches of 0.5 and elements of 0.12: PatchGrouping::Elements builds the same elements,
    // the front ones at the same indices, the back sheets' twins of the same fronts; a grid
    // cell is a patch of its own (planar: outlined by its four corners), mesh faces far
    // smaller than an element share patches of about one element, and the lamp keeps its one
    // patch.
    SceneObject box = makeShape("box", ShapeType::Box);
    box.shape.size = Vec3(0.9, 0.45, 1.3);
    box.transform.rotateDeg = Vec3(0, 25, 0);
    SceneObject ball = makeShape("ball", ShapeType::Sphere);
    ball.shape.radius = 0.4;
    ball.shape.segments = 12;
    ball.transform.translate = Vec3(2, 0, 0);
    SceneObject ico = makeShape("ico", ShapeType::Mesh);
    ico.shape.mesh = icosahedron();
    ico.transform.scale = Vec3(0.5);  // edge 1: split into 9², faces of 0.0053 m²
    ico.transform.translate = Vec3(-2, 0, 0);
    ico.material = "both";
    SceneObject lamp = test::makeQuad("lamp", 0.8, 0.6, "white", {0, 2, 0}, {180, 0, 0});
    lamp.patchSize = 1.0;
    SceneObject panel = test::makeQuad("panel", 2.3, 1.1, "both", {0, -1, 0});
    panel.material = "both";
    Scene scene = sceneWith({box, ball, ico, lamp, panel}, 0.5, 0.12);
    test::addMaterial(scene, "both", Rgb(0.5));
    scene.materials.back().material.twoSided = true;
    const Discretization patches(scene);
    const Discretization leaves(scene, PatchGrouping::Elements);
    ASSERT_EQ(leaves.elements().size(), patches.elements().size());
    ASSERT_EQ(leaves.objects().size(), patches.objects().size());
    int backFaces = 0;
    for (std::size_t o = 0; o < patches.objects().size(); ++o) {
        const ObjectSurface &s = patches.objects()[o], &t = leaves.objects()[o];
        ASSERT_EQ(s.faceElement.size(), t.faceElement.size()) << s.id;
        for (int f = 0; f < static_cast<int>(s.faceElement.size()); ++f) {
            const bool back = s.isBackFace(f);
            backFaces += back;
            const int tf = back ? t.faceTwin.at(s.faceTwin.at(f)) : f;
            const int e = s.faceElement[f], g = t.faceElement.at(tf);
            if (!back) {
                ASSERT_EQ(e, g) << s.id << " face " << f;
            }
            const Element &a = patches.elements()[e], &b = leaves.elements()[g];
            ASSERT_TRUE(a.object == b.object && (back || a.vertices == b.vertices) &&
                        a.centroid == b.centroid && a.normal == b.normal && a.area == b.area)
                << s.id << " face " << f << ": " << a.toString() << " vs " << b.toString();
        }
    }
    EXPECT_EQ(backFaces, objectElements(patches, 2) / 2 + objectElements(patches, 4) / 2);
    checkPatchStructure(leaves);
    const int icoObject = 2, lampObject = 3;
    EXPECT_EQ(objectPatches(leaves, lampObject), 1);
    int gridPatches = 0;
    for (const Patch& p : leaves.patches()) {
        if (p.object == icoObject || p.object == lampObject) continue;
        ++gridPatches;
        ASSERT_EQ(p.elements.size(), 1u) << p.toString();
        const Element& el = leaves.elements()[p.elements[0]];
        if (p.object != 1) {  // the ball's cells are not planar
            ASSERT_EQ(p.outline.size(), 4u) << p.toString();
            EXPECT_NEAR(0.5 * glm::length(newellNormal(p.outline)), el.area, kExact)
                << p.toString();
        }
    }
    EXPECT_EQ(gridPatches, static_cast<int>(leaves.elements().size()) -
                               objectElements(leaves, icoObject) -
                               objectElements(leaves, lampObject));
    // The icosahedron's patches: several faces each, of about one element's area, more of them
    // than of patch size.
    const double elementArea = 0.12 * 0.12;
    for (const Patch& p : leaves.patches()) {
        if (p.object == icoObject) {
            EXPECT_LE(p.area, 2 * elementArea) << p.toString();
        }
    }
    EXPECT_LT(objectPatches(leaves, icoObject), objectElements(leaves, icoObject) / 2);
    EXPECT_GT(objectPatches(leaves, icoObject), 4 * objectPatches(patches, icoObject));
}

TEST(Discretization, CountElementsPlansWhatTheConstructorBuilds) {
    // Every kind of shape, transformed, one with its own patch size, at three element sizes:
    // the planned count is the number of elements built (one-sided, so no back sheets).
    SceneObject quad = test::makeQuad("quad", 2.3, 1.1, "white", {0, 0, 0});
    quad.patchSize = 0.9;
    SceneObject box = makeShape("box", ShapeType::Box);
    box.shape.size = Vec3(0.9, 0.45, 1.3);
    box.transform.rotateDeg = Vec3(0, 30, 0);
    SceneObject sphere = makeShape("sphere", ShapeType::Sphere);
    sphere.shape.radius = 0.5;
    sphere.shape.segments = 10;
    sphere.transform.scale = Vec3(2.0, 1.0, 0.7);
    SceneObject cylinder = makeShape("cylinder", ShapeType::Cylinder);
    cylinder.shape.radius = 0.4;
    cylinder.shape.height = 0.9;
    cylinder.shape.segments = 12;
    SceneObject tri = makeShape("tri", ShapeType::Mesh);
    tri.shape.mesh.positions = {{0, 0, 0}, {1.3, 0, 0}, {0, 0, -0.9}, {0.2, 0.01, 0.3}};
    tri.shape.mesh.triangles = {{0, 1, 2}, {0, 3, 1}};
    tri.transform.scale = Vec3(1.5);
    for (const double E : {0.05, 0.13, 0.4}) {
        const Scene scene = sceneWith({quad, box, sphere, cylinder, tri}, 4 * E, E);
        const Discretization disc(scene);
        EXPECT_EQ(Discretization::countElements(scene),
                  static_cast<double>(disc.elements().size()))
            << "element size " << E;
    }
    // Too fine: refused as the constructor refuses it, naming the object.
    const Scene tooFine = sceneWith({sphere}, 4e-6, 1e-6);
    try {
        (void)Discretization::countElements(tooFine);
        ADD_FAILURE() << "a sphere of 1e-6 elements was counted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("'sphere'"), std::string::npos) << e.what();
    }
}

// ---------------------------------------------------------------------------------------------
// Vertex values and neighbours

TEST(Discretization, VertexValuesOfConstantAndLinearFields) {
    SceneObject quad = test::makeQuad("q", 1.1, 0.7, "white", {0, 0, 0});
    SceneObject box = makeShape("box", ShapeType::Box);
    box.shape.size = Vec3(0.6, 0.5, 0.4);
    box.transform.translate = Vec3(3, 0, 0);
    SceneObject sphere = makeShape("sphere", ShapeType::Sphere);
    sphere.shape.radius = 0.4;
    sphere.transform.translate = Vec3(-3, 0, 0);
    SceneObject cyl = makeShape("cyl", ShapeType::Cylinder);
    cyl.transform.translate = Vec3(0, 0, 3);
    SceneObject ico = makeShape("ico", ShapeType::Mesh);
    ico.shape.mesh = icosahedron();
    ico.transform.translate = Vec3(0, 0, -5);
    Discretization disc(sceneWith({quad, box, sphere, cyl, ico}, 0.5, 0.2));
    const Rgb k(0.3, 1.7, 42.0);
    const std::vector<Rgb> constant(disc.elements().size(), k);
    for (int o = 0; o < static_cast<int>(disc.objects().size()); ++o) {
        const std::vector<Rgb> values = disc.vertexValues(o, constant);
        ASSERT_EQ(values.size(), disc.objects()[o].mesh.n_vertices());
        for (std::size_t v = 0; v < values.size(); ++v)
            for (int c = 0; c < 3; ++c)
                ASSERT_NEAR(values[v][c], k[c], 1e-12 * k[c])
                    << disc.objects()[o].id << " vertex " << v << ": " << values[v][c];
    }
    // On the uniform quad grid, the area-weighted mean of the linear field x over the four
    // elements around an interior vertex is the vertex's own x.
    std::vector<Rgb> linear(disc.elements().size());
    for (std::size_t e = 0; e < linear.size(); ++e) linear[e] = Rgb(disc.elements()[e].centroid.x);
    const std::vector<Rgb> values = disc.vertexValues(0, linear);
    const ObjectSurface& s = disc.objects()[0];
    int interior = 0;
    for (auto v : s.mesh.vertices()) {
        if (s.mesh.is_boundary(v)) continue;
        ++interior;
        EXPECT_NEAR(values[v.idx()].x, s.worldPositions[v.idx()].x, kExact) << "vertex " << v.idx();
    }
    EXPECT_GT(interior, 10);
}

TEST(Discretization, NeighboursOnAGridAndSymmetry) {
    // 5 × 4 elements in one patch: corner elements have 3 neighbours, edge ones 5, interior 8.
    Discretization disc(sceneWith({test::makeQuad("q", 1.0, 0.8, "white", {0, 0, 0})}, 10, 0.2));
    ASSERT_EQ(disc.elements().size(), 20u);
    for (int e = 0; e < 20; ++e) {
        const Vec3 c = disc.elements()[e].centroid;
        const bool edgeX = std::abs(std::abs(c.x) - 0.4) < kExact;
        const bool edgeZ = std::abs(std::abs(c.z) - 0.3) < kExact;
        const std::size_t want = edgeX && edgeZ ? 3 : edgeX || edgeZ ? 5 : 8;
        EXPECT_EQ(disc.elementNeighbours(e).size(), want) << disc.elements()[e].toString();
    }
    checkNeighboursSymmetric(disc);
}

// ---------------------------------------------------------------------------------------------
// Subdivision

TEST(Discretization, SubdivideElementKeepsAreaAndConformity) {
    Discretization disc(sceneWith({test::makeQuad("q", 1.0, 1.0, "white", {0, 0, 0})}, 10, 0.25));
    ASSERT_EQ(disc.elements().size(), 16u);
    const double parentArea = disc.elements()[5].area;
    const std::vector<int> children = disc.subdivideElement(5);
    ASSERT_EQ(children.size(), 4u);
    EXPECT_EQ(children[0], 5) << "the first child reuses the parent's index";
    for (int c : children) {
        EXPECT_NEAR(disc.elements()[c].area, parentArea / 4, kExact * parentArea);
        EXPECT_EQ(disc.elements()[c].patch, disc.elements()[5].patch);
    }
    EXPECT_NEAR(objectArea(disc, 0), 1.0, kExact);
    EXPECT_NEAR(boundaryLength(disc, 0), 4.0, kExact) << "T-junction after subdivision";
    // A child subdivides again (level 2), still conforming.
    disc.subdivideElement(children[2]);
    EXPECT_NEAR(objectArea(disc, 0), 1.0, kExact);
    EXPECT_NEAR(boundaryLength(disc, 0), 4.0, kExact);
    EXPECT_EQ(objectElements(disc, 0), 16 + 3 + 3);
    EXPECT_EQ(objectPatches(disc, 0), 1);
    checkPatchStructure(disc);
    checkNeighboursSymmetric(disc);

    // Triangles split into four triangles.
    SceneObject o = makeShape("ico", ShapeType::Mesh);
    o.shape.mesh = icosahedron();
    Discretization ico(sceneWith({o}, 0.5, 3.0));
    const double area = ico.totalArea();
    std::vector<int> tri = ico.subdivideElement(0);
    ASSERT_EQ(tri.size(), 4u);
    for (int c : tri) EXPECT_EQ(ico.elements()[c].vertices.size(), 3u);
    EXPECT_NEAR(objectArea(ico, 0), area, kExact * area);
    EXPECT_EQ(boundaryLength(ico, 0), 0.0) << "the closed mesh opened";
    checkPatchStructure(ico);
    checkNeighboursSymmetric(ico);
}

}  // namespace
}  // namespace penumbra
