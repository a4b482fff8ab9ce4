#pragma once
// HifiMesh's internals shared by its two translation units (hifi_mesh.cpp: meshing and sampling
// each element, assembling, locating and rendering the triangles; hifi_discontinuities.cpp: the
// shadow events and contact lines that cross an element, and the elements an edit re-meshes):
// the wedges and their index, the contacts' index, an element's geometry in its plane, and what
// finds the discontinuities on one element. Include only from those two files.
//
// Index: Wedge · allWedges · insideSolid · WedgeIndex · ElementGeometry · rankWedges ·
// ContactIndex · contactsOn · dropBoundarySegments

#include <cstdint>
#include <utility>
#include <vector>

#include "core/math.h"
#include "render/box_tree.h"
#include "render/hifi/hifi_mesh.h"

namespace penumbra::hifi_detail {

/// A VE or EV event as two rays from source points a_k through blocker points b_k (VE:
/// a0 = a1, a light vertex; EV: b0 = b1, a blocker vertex).
struct Wedge {
    Vec3 a[2], b[2];
    double brightness = 0;  ///< B_src (luminance of the emission)
    int emitterObject = -1, blockerObject = -1;
};

/// Every VE/EV event of every light outline with every other object (blockers through their
/// welded element meshes: silhouette edges from a light corner, vertices whose one ring a
/// light edge's plane supports); with `blockers`, only those objects block, alive or not (the
/// versions an edit removed cast the events that went). With `tracer`, a blocker edge or
/// vertex buried inside another solid casts nothing (the solid around it casts the shadow).
std::vector<Wedge> allWedges(const Discretization& disc, const std::vector<int>* blockers = nullptr,
                             const RayTracer* tracer = nullptr);

/// Whether x lies inside an object other than `self` that bounds a solid: the first surface
/// along `dir`, passing through `self` (a back sheet looks into its own object), is such an
/// object seen from inside — from behind, or its back sheet (a two-sided object's inside).
bool insideSolid(const Discretization& disc, const RayTracer& tracer,
                 const std::vector<std::uint8_t>& sealed, const Vec3& x, const Vec3& dir, int self);

/// The area of the element that holds the median square metre of surface (elements sorted by
/// area): the scene's element size as its large surfaces have it, whatever a finely tessellated
/// mesh adds in number.
double areaWeightedMedianArea(const Discretization& disc);

/// The wedges by where they can cut an element, so that an element tests only the wedges
/// that may reach it, not every wedge in the scene. A wedge's region beyond its blocker is
/// the convex part of its plane between its two rays; clipped to the scene's box and cut
/// into slabs across its longest extent (eight elements thick, at most 16), each piece is bounded
/// by a box, and the boxes by a bounding-volume hierarchy. One box for the whole region, a
/// long diagonal strip from a blocker to the far wall, would hold most of the scene's
/// elements; its slabs' boxes follow the strip.
class WedgeIndex {
public:
    /// No index: query() answers every wedge.
    WedgeIndex() = default;
    WedgeIndex(const std::vector<Wedge>& wedges, const Discretization& disc);

    /// The wedges whose region may meet `poly`'s box, ascending (of `count` wedges).
    void query(const std::vector<Vec3>& poly, std::size_t count, std::vector<int>& out) const;

private:
    /// Sutherland–Hodgman against the box's six planes.
    static std::vector<Vec3> clipToBox(std::vector<Vec3> poly, const Box3& box);

    std::vector<Box3> mBoxes;  ///< per piece of a wedge's region
    std::vector<int> mWedge;   ///< per piece, its wedge
    BoxTree mTree;             ///< over mBoxes
    double mPad = 0;
    bool mIndexed = false;
};

struct ElementGeometry {
    std::vector<Vec3> poly;
    std::vector<glm::dvec2> poly2;
    PlaneFrame frame;
};

/// Element e's polygon (world space and in its plane's frame) and that frame.
ElementGeometry geometryOf(const Discretization& disc, int e);

/// The segments `wedges` cut on element e (those `index` finds may reach it), strongest first.
std::vector<Discontinuity> rankWedges(const Discretization& disc, int e, const ElementGeometry& g,
                                      const std::vector<Wedge>& wedges, const WedgeIndex& index);

/// Per object: element polygons (front sheet) and bounds, for contact lines.
/// Element polygons find where a surface crosses a plane; its sharp edges (creases and
/// boundaries of the welded mesh, never the grid lines inside a flat face) where it rests on
/// or nearly touches one.
struct ContactIndex {
    struct Object {
        Vec3 lo{1e300}, hi{-1e300};
        std::vector<std::vector<Vec3>> polygons;
        std::vector<std::pair<Vec3, Vec3>> sharpEdges;
        bool sealed = false;  ///< bounds a solid (EdgeMesh::sealed): its inside is hidden
    };
    std::vector<Object> objects;
    explicit ContactIndex(const Discretization& disc);
};

/// The contact lines on element e, clipped to it. `unclipped`, when given, receives them
/// before clipping (in the element's plane): a point on one of those is on a contact whether
/// or not the clip kept it (a contact along the element's edge may fall either way).
std::vector<Discontinuity> contactsOn(
    const Discretization& disc, int e, const ElementGeometry& g, const ContactIndex& index,
    double contactFraction, std::vector<std::pair<glm::dvec2, glm::dvec2>>* unclipped = nullptr);

/// Drops segments lying on the element's boundary (they add nothing) or shorter than `tol`.
void dropBoundarySegments(const std::vector<glm::dvec2>& poly,
                          std::vector<std::pair<glm::dvec2, glm::dvec2>>& segs, double tol);

}  // namespace penumbra::hifi_detail
