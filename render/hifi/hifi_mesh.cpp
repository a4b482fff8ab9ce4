#include "render/hifi/hifi_mesh.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <deque>
#include <limits>
#include <optional>
#include <sstream>
#include <thread>

#include "core/random.h"
#include "render/box_tree.h"
#include "render/camera_rays.h"
#include "render/edge_mesh.h"
#include "render/hifi/cdt.h"
#include "render/hifi/exact_irradiance.h"
#include "render/hifi/hifi_samples.h"
#include "render/light_change.h"
#include "solver/discretization.h"
#include "solver/form_factor.h"
#include "solver/ray_tracer.h"

namespace penumbra {

QuadraticInterpolant QuadraticInterpolant::fromSamples(const std::array<Rgb, 6>& r) {
    // Hardt & Teller §2.2: the symbolic inverse of the 6 × 6 system, with 2B, 2C, 2E stored.
    // E's r5 coefficient is 2 (R(0,1) and R(0,½) give 2E = 4r5 − 3r0 − r4, the mirror of C);
    // the paper's printed 1 does not reproduce R = t.
    QuadraticInterpolant q;
    q.c[0] = 2.0 * r[0] - 4.0 * r[1] + 2.0 * r[2];                       // A
    q.c[1] = 2.0 * (2.0 * r[0] - 2.0 * r[1] + 2.0 * r[3] - 2.0 * r[5]);  // 2B
    q.c[2] = 2.0 * (-1.5 * r[0] + 2.0 * r[1] - 0.5 * r[2]);              // 2C
    q.c[3] = 2.0 * r[0] + 2.0 * r[4] - 4.0 * r[5];                       // D
    q.c[4] = 2.0 * (-1.5 * r[0] - 0.5 * r[4] + 2.0 * r[5]);              // 2E
    q.c[5] = r[0];                                                       // F
    return q;
}

namespace {

/// The part of segment a–b inside the convex polygon `poly` (counter-clockwise, 2D);
/// false when nothing is left (Cyrus–Beck).
bool clipSegment(const std::vector<glm::dvec2>& poly, glm::dvec2& a, glm::dvec2& b) {
    double t0 = 0, t1 = 1;
    const glm::dvec2 d = b - a;
    for (std::size_t i = 0, n = poly.size(); i < n; ++i) {
        const glm::dvec2 e = poly[(i + 1) % n] - poly[i];
        // Inside: cross(e, p − poly[i]) ≥ 0.
        const double num = e.x * (a.y - poly[i].y) - e.y * (a.x - poly[i].x);
        const double den = e.x * d.y - e.y * d.x;
        if (den == 0) {
            if (num < 0) return false;
            continue;
        }
        const double t = -num / den;
        if (den > 0)
            t0 = std::max(t0, t);
        else
            t1 = std::min(t1, t);
        if (t0 > t1) return false;
    }
    const glm::dvec2 a0 = a;
    a = a0 + t0 * d;
    b = a0 + t1 * d;
    return glm::length(b - a) > 0;
}

/// A VE or EV event as two rays from source points a_k through blocker points b_k (VE:
/// a0 = a1, a light vertex; EV: b0 = b1, a blocker vertex).
struct Wedge {
    Vec3 a[2], b[2];
    double brightness = 0;  ///< B_src (luminance of the emission)
    int emitterObject = -1, blockerObject = -1;
};

/// The light's outline: its corners and boundary edges (world space), from its element mesh.
struct LightOutline {
    std::vector<Vec3> corners;
    std::vector<std::pair<Vec3, Vec3>> edges;
    Vec3 centroid{0.0}, normal{0.0};
    double brightness = 0;
    int object = -1;
};

std::vector<LightOutline> lightOutlines(const Discretization& disc) {
    std::vector<LightOutline> out;
    for (std::size_t o = 0; o < disc.objects().size(); ++o) {
        const ObjectSurface& surface = disc.objects()[o];
        if (!surface.alive) continue;
        const auto [first, count] = disc.elementRange(static_cast<int>(o));
        if (count == 0) continue;
        const Material& m = disc.elementMaterial(first);
        if (!m.isEmitter()) continue;
        const int front = std::min(surface.firstBackFace, static_cast<int>(surface.mesh.n_faces()));
        const EdgeMesh mesh = EdgeMesh::fromElementMesh(surface.mesh, 85.0, front);
        if (mesh.boundaryEdges().empty()) continue;  // closed: no outline casts sharp events
        LightOutline L;
        L.object = static_cast<int>(o);
        L.brightness = luminance(m.emission);
        auto world = [&](int v) {
            return Vec3(surface.worldFromObject * glm::dvec4(mesh.positions()[v], 1.0));
        };
        std::vector<std::vector<int>> around(mesh.positions().size());
        for (int e : mesh.boundaryEdges()) {
            const MeshEdge& edge = mesh.edges()[e];
            L.edges.emplace_back(world(edge.v0), world(edge.v1));
            around[edge.v0].push_back(edge.v1);
            around[edge.v1].push_back(edge.v0);
        }
        for (std::size_t v = 0; v < around.size(); ++v) {
            if (around[v].size() != 2) continue;
            const Vec3 p = world(static_cast<int>(v));
            const Vec3 d0 = glm::normalize(world(around[v][0]) - p);
            const Vec3 d1 = glm::normalize(world(around[v][1]) - p);
            if (glm::dot(d0, d1) > -0.9999) L.corners.push_back(p);  // the outline turns here
        }
        for (int e = first; e < first + count; ++e) {
            L.centroid += disc.elements()[e].centroid * disc.elements()[e].area;
            L.normal += disc.elements()[e].normal * disc.elements()[e].area;
        }
        double area = 0;
        for (int e = first; e < first + count; ++e) area += disc.elements()[e].area;
        L.centroid /= area;
        L.normal = glm::normalize(L.normal);
        out.push_back(std::move(L));
    }
    return out;
}

/// Per object: whether its front sheet bounds a solid (EdgeMesh::sealed), so that what lies
/// inside it is hidden and unlit.
std::vector<std::uint8_t> sealedObjects(const Discretization& disc) {
    std::vector<std::uint8_t> sealed(disc.objects().size(), 0);
    for (std::size_t o = 0; o < sealed.size(); ++o) {
        const ObjectSurface& surface = disc.objects()[o];
        if (!surface.alive || surface.mesh.n_faces() == 0) continue;
        const int front = std::min(surface.firstBackFace, static_cast<int>(surface.mesh.n_faces()));
        sealed[o] = EdgeMesh::fromElementMesh(surface.mesh, 85.0, front).sealed() ? 1 : 0;
    }
    return sealed;
}

/// Whether x lies inside an object other than `self` that bounds a solid: the first surface
/// along `dir`, passing through `self` (a back sheet looks into its own object), is such an
/// object seen from inside — from behind, or its back sheet (a two-sided object's inside).
bool insideSolid(const Discretization& disc, const RayTracer& tracer,
                 const std::vector<std::uint8_t>& sealed, const Vec3& x, const Vec3& dir,
                 int self) {
    const RayTracer::FirstHit hit = tracer.firstHit(x, dir, Visibility(self));
    if (hit.element < 0) return false;
    const Element& el = disc.elements()[hit.element];
    if (el.object == self || !sealed[std::size_t(el.object)]) return false;
    return hit.backFace || disc.objects()[el.object].isBackFace(el.face);
}

/// Every VE/EV event of every light outline with every other object (blockers through their
/// welded element meshes: silhouette edges from a light corner, vertices whose one ring a
/// light edge's plane supports); with `blockers`, only those objects block, alive or not (the
/// versions an edit removed cast the events that went). With `tracer`, a blocker edge or
/// vertex buried inside another solid casts nothing (the solid around it casts the shadow).
std::vector<Wedge> allWedges(const Discretization& disc, const std::vector<int>* blockers = nullptr,
                             const RayTracer* tracer = nullptr) {
    std::vector<Wedge> wedges;
    const std::vector<LightOutline> lights = lightOutlines(disc);
    if (lights.empty()) return wedges;
    std::vector<int> objects;
    if (blockers) {
        objects = *blockers;
    } else {
        for (std::size_t o = 0; o < disc.objects().size(); ++o)
            if (disc.objects()[o].alive) objects.push_back(static_cast<int>(o));
    }
    for (const int o : objects) {
        const ObjectSurface& surface = disc.objects()[std::size_t(o)];
        const int front = std::min(surface.firstBackFace, static_cast<int>(surface.mesh.n_faces()));
        const EdgeMesh mesh = EdgeMesh::fromElementMesh(surface.mesh, 85.0, front);
        const Mat4 objectFromWorld = glm::inverse(surface.worldFromObject);
        auto world = [&](int v) {
            return Vec3(surface.worldFromObject * glm::dvec4(mesh.positions()[v], 1.0));
        };
        for (const LightOutline& L : lights) {
            if (L.object == o) continue;
            for (const Vec3& corner : L.corners) {
                const Vec3 eye = Vec3(objectFromWorld * glm::dvec4(corner, 1.0));
                for (std::size_t e = 0; e < mesh.edges().size(); ++e) {
                    if (!mesh.isSilhouette(static_cast<int>(e), eye)) continue;
                    const MeshEdge& edge = mesh.edges()[e];
                    Wedge w;
                    w.a[0] = w.a[1] = corner;
                    w.b[0] = world(edge.v0);
                    w.b[1] = world(edge.v1);
                    // Blocker in front of the light only.
                    if (glm::dot(w.b[0] - L.centroid, L.normal) <= 0 &&
                        glm::dot(w.b[1] - L.centroid, L.normal) <= 0)
                        continue;
                    w.brightness = L.brightness;
                    w.emitterObject = L.object;
                    w.blockerObject = o;
                    wedges.push_back(w);
                }
            }
            for (const auto& [p0, p1] : L.edges) {
                for (std::size_t v = 0; v < mesh.positions().size(); ++v) {
                    const Vec3 wv = world(static_cast<int>(v));
                    if (glm::dot(wv - L.centroid, L.normal) <= 0) continue;
                    Vec3 pn = glm::cross(p1 - p0, wv - p0);
                    const double len = glm::length(pn);
                    if (!(len > 0)) continue;
                    pn /= len;
                    // The plane through the light edge and w supports the blocker at w.
                    int above = 0, below = 0;
                    const int s = mesh.neighbourStart()[v], t = mesh.neighbourStart()[v + 1];
                    if (s == t) continue;
                    for (int k = s; k < t; ++k) {
                        const double h = glm::dot(world(mesh.neighbours()[k]) - wv, pn);
                        if (h > 1e-12) ++above;
                        if (h < -1e-12) ++below;
                    }
                    if (above > 0 && below > 0) continue;
                    Wedge w;
                    w.a[0] = p0;
                    w.a[1] = p1;
                    w.b[0] = w.b[1] = wv;
                    w.brightness = L.brightness;
                    w.emitterObject = L.object;
                    w.blockerObject = o;
                    wedges.push_back(w);
                }
            }
        }
    }
    if (tracer) {
        // Buried: both ends and the middle of the blocker edge (or the vertex) inside a solid,
        // looking away from the light.
        const std::vector<std::uint8_t> sealed = sealedObjects(disc);
        auto buried = [&](const Wedge& w) {
            for (const Vec3& p : {w.b[0], w.b[1], 0.5 * (w.b[0] + w.b[1])}) {
                const Vec3 d = p - 0.5 * (w.a[0] + w.a[1]);
                if (!(glm::length(d) > 0) ||
                    !insideSolid(disc, *tracer, sealed, p, glm::normalize(d), w.blockerObject))
                    return false;
            }
            return true;
        };
        wedges.erase(std::remove_if(wedges.begin(), wedges.end(), buried), wedges.end());
    }
    return wedges;
}

/// The segment a wedge cuts on element `e` (2D in its frame, clipped) and its weight.
bool wedgeOnElement(const Wedge& w, const Element& el, const PlaneFrame& frame,
                    const std::vector<glm::dvec2>& poly, glm::dvec2& a, glm::dvec2& b,
                    double& weight) {
    if (w.blockerObject == el.object || w.emitterObject == el.object) return false;
    Vec3 r[2];
    double ratio = 0;
    for (int k = 0; k < 2; ++k) {
        const Vec3 d = w.b[k] - w.a[k];
        const double den = glm::dot(el.normal, d);
        if (den >= 0) return false;  // the ray must come at the element's front
        const double s = glm::dot(frame.origin - w.a[k], el.normal) / den;
        if (!(s > 1 + 1e-9)) return false;  // the element must lie beyond the blocker
        r[k] = w.a[k] + s * d;
        const double dsb = glm::length(d), dbr = (s - 1) * dsb;
        ratio = std::max(ratio, dsb / std::max(dbr, 1e-12));
    }
    a = frame.to2(r[0]);
    b = frame.to2(r[1]);
    if (!clipSegment(poly, a, b)) return false;
    weight = ratio * w.brightness;
    return true;
}

/// The wedges by where they can cut an element, so that an element tests only the wedges
/// that may reach it, not every wedge in the scene. A wedge's region beyond its blocker is
/// the convex part of its plane between its two rays; clipped to the scene's box, it is
/// bounded by a box, and the boxes by a bounding-volume hierarchy.
class WedgeIndex {
public:
    /// No index: query() answers every wedge.
    WedgeIndex() = default;
    WedgeIndex(const std::vector<Wedge>& wedges, const Discretization& disc) : mIndexed(true) {
        Box3 scene;
        for (const ObjectSurface& surface : disc.objects())
            if (surface.alive)
                for (const Vec3& p : surface.worldPositions) scene.extend(p);
        if (scene.empty()) return;
        const double diagonal = glm::length(scene.hi - scene.lo);
        mPad = 1e-6 * diagonal + 1e-12;
        scene.lo -= Vec3(mPad);
        scene.hi += Vec3(mPad);
        // Far enough along the rays to leave the box (the rays part by less than 180°).
        const double far = 1e3 * (diagonal + 1);
        for (const Wedge& w : wedges) {
            const Vec3 d0 = glm::normalize(w.b[0] - w.a[0]), d1 = glm::normalize(w.b[1] - w.a[1]);
            Box3 box;
            for (const Vec3& p :
                 clipToBox({w.b[0], w.b[1], w.b[1] + far * d1, w.b[0] + far * d0}, scene))
                box.extend(p);
            if (!box.empty()) box.lo -= Vec3(mPad), box.hi += Vec3(mPad);
            mBoxes.push_back(box);
        }
        mTree.build(mBoxes);
    }

    /// The wedges whose region may meet `poly`'s box, ascending (of `count` wedges).
    void query(const std::vector<Vec3>& poly, std::size_t count, std::vector<int>& out) const {
        out.clear();
        if (!mIndexed) {
            for (std::size_t i = 0; i < count; ++i) out.push_back(static_cast<int>(i));
            return;
        }
        Box3 box;
        for (const Vec3& p : poly) box.extend(p);
        box.lo -= Vec3(mPad);
        box.hi += Vec3(mPad);
        mTree.query(box, out);
        const auto missed = [&](int w) { return !mBoxes[w].overlaps(box); };
        out.erase(std::remove_if(out.begin(), out.end(), missed), out.end());
        std::sort(out.begin(), out.end());
    }

private:
    /// Sutherland–Hodgman against the box's six planes.
    static std::vector<Vec3> clipToBox(std::vector<Vec3> poly, const Box3& box) {
        for (int axis = 0; axis < 3 && !poly.empty(); ++axis)
            for (int side = 0; side < 2 && !poly.empty(); ++side) {
                // Inside: x[axis] >= lo (side 0), x[axis] <= hi (side 1).
                auto distance = [&](const Vec3& p) {
                    return side == 0 ? p[axis] - box.lo[axis] : box.hi[axis] - p[axis];
                };
                std::vector<Vec3> kept;
                for (std::size_t k = 0; k < poly.size(); ++k) {
                    const Vec3& p = poly[k];
                    const Vec3& q = poly[(k + 1) % poly.size()];
                    const double dp = distance(p), dq = distance(q);
                    if (dp >= 0) kept.push_back(p);
                    if ((dp >= 0) != (dq >= 0)) kept.push_back(p + (dp / (dp - dq)) * (q - p));
                }
                poly = std::move(kept);
            }
        return poly;
    }

    std::vector<Box3> mBoxes;  ///< per wedge (empty: its region misses the scene)
    BoxTree mTree;             ///< over mBoxes
    double mPad = 0;
    bool mIndexed = false;
};

struct ElementGeometry {
    std::vector<Vec3> poly;
    std::vector<glm::dvec2> poly2;
    PlaneFrame frame;
};

ElementGeometry geometryOf(const Discretization& disc, int e) {
    std::vector<Vec3> poly = disc.elementPolygon(e);
    PlaneFrame frame(poly, disc.elements()[e].normal);
    std::vector<glm::dvec2> poly2;
    for (const Vec3& p : poly) poly2.push_back(frame.to2(p));
    return {std::move(poly), std::move(poly2), frame};
}

std::vector<Discontinuity> rankWedges(const Discretization& disc, int e, const ElementGeometry& g,
                                      const std::vector<Wedge>& wedges, const WedgeIndex& index) {
    std::vector<Discontinuity> out;
    std::vector<int> candidates;
    index.query(g.poly, wedges.size(), candidates);
    for (int i : candidates) {
        glm::dvec2 a, b;
        double weight = 0;
        if (wedgeOnElement(wedges[i], disc.elements()[e], g.frame, g.poly2, a, b, weight))
            out.push_back({g.frame.to3(a), g.frame.to3(b), weight});
    }
    std::sort(out.begin(), out.end(),
              [](const Discontinuity& x, const Discontinuity& y) { return x.weight > y.weight; });
    return out;
}

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
    explicit ContactIndex(const Discretization& disc) : objects(disc.objects().size()) {
        for (std::size_t e = 0; e < disc.elements().size(); ++e) {
            const int ei = static_cast<int>(e);
            if (!disc.elementAlive(ei)) continue;
            const Element& el = disc.elements()[e];
            if (disc.objects()[el.object].isBackFace(el.face)) continue;
            Object& o = objects[el.object];
            o.polygons.push_back(disc.elementPolygon(ei));
            for (const Vec3& p : o.polygons.back()) {
                o.lo = glm::min(o.lo, p);
                o.hi = glm::max(o.hi, p);
            }
        }
        for (std::size_t i = 0; i < objects.size(); ++i) {
            const ObjectSurface& surface = disc.objects()[i];
            if (objects[i].polygons.empty()) continue;
            const int front =
                std::min(surface.firstBackFace, static_cast<int>(surface.mesh.n_faces()));
            const EdgeMesh mesh = EdgeMesh::fromElementMesh(surface.mesh, 30.0, front);
            objects[i].sealed = mesh.sealed();
            for (int edge : mesh.sharpEdges()) {
                const MeshEdge& me = mesh.edges()[edge];
                objects[i].sharpEdges.emplace_back(
                    Vec3(surface.worldFromObject * glm::dvec4(mesh.positions()[me.v0], 1.0)),
                    Vec3(surface.worldFromObject * glm::dvec4(mesh.positions()[me.v1], 1.0)));
            }
        }
    }
};

/// The contact lines on element e, clipped to it. `unclipped`, when given, receives them
/// before clipping (in the element's plane): a point on one of those is on a contact whether
/// or not the clip kept it (a contact along the element's edge may fall either way).
std::vector<Discontinuity> contactsOn(
    const Discretization& disc, int e, const ElementGeometry& g, const ContactIndex& index,
    double contactFraction, std::vector<std::pair<glm::dvec2, glm::dvec2>>* unclipped = nullptr) {
    const Element& el = disc.elements()[e];
    const double delta = contactFraction * std::sqrt(el.area);
    Vec3 lo(1e300), hi(-1e300);
    for (const Vec3& p : g.poly) {
        lo = glm::min(lo, p - Vec3(delta));
        hi = glm::max(hi, p + Vec3(delta));
    }
    std::vector<Discontinuity> out;
    const double inf = std::numeric_limits<double>::infinity();
    for (std::size_t o = 0; o < index.objects.size(); ++o) {
        if (static_cast<int>(o) == el.object) continue;
        const ContactIndex::Object& obj = index.objects[o];
        if (obj.polygons.empty() || obj.hi.x < lo.x || obj.lo.x > hi.x || obj.hi.y < lo.y ||
            obj.lo.y > hi.y || obj.hi.z < lo.z || obj.lo.z > hi.z)
            continue;
        auto height = [&](const Vec3& p) { return glm::dot(p - g.frame.origin, el.normal); };
        auto keep = [&](const Vec3& p, const Vec3& q) {
            glm::dvec2 a = g.frame.to2(p), b = g.frame.to2(q);
            if (unclipped) unclipped->emplace_back(a, b);
            if (clipSegment(g.poly2, a, b)) out.push_back({g.frame.to3(a), g.frame.to3(b), inf});
        };
        // Where a polygon crosses the plane (an object standing through it): it has corners
        // on both sides, and the crossing runs between the points where its edges pass from
        // one side to the other and its corners on the plane.
        for (const auto& q : obj.polygons) {
            std::vector<Vec3> crossing;
            bool above = false, below = false;
            for (std::size_t i = 0, n = q.size(); i < n; ++i) {
                const Vec3& p0 = q[i];
                const Vec3& p1 = q[(i + 1) % n];
                const double h0 = height(p0), h1 = height(p1);
                above = above || h0 > delta;
                below = below || h0 < -delta;
                if (std::abs(h0) <= delta)
                    crossing.push_back(p0);
                else if ((h0 > delta && h1 < -delta) || (h0 < -delta && h1 > delta))
                    crossing.push_back(p0 + (h0 / (h0 - h1)) * (p1 - p0));
            }
            if (above && below && crossing.size() == 2) keep(crossing[0], crossing[1]);
            // An edge on the plane of a polygon behind it: the other object's surface passes
            // through the plane along that edge (taken from the side behind, so once; a
            // surface resting on the element from the front leaves its sharp edges below).
            if (below && !above && crossing.size() == 2) keep(crossing[0], crossing[1]);
        }
        // The parts of sharp edges within δ of the plane (resting on it, or nearly).
        for (const auto& [p0, p1] : obj.sharpEdges) {
            const double h0 = height(p0), h1 = height(p1);
            double t0 = 0, t1 = 1;
            const double dh = h1 - h0;
            if (dh == 0) {
                if (std::abs(h0) > delta) continue;
            } else {
                double ta = (-delta - h0) / dh, tb = (delta - h0) / dh;
                if (ta > tb) std::swap(ta, tb);
                t0 = std::max(t0, ta);
                t1 = std::min(t1, tb);
                if (t0 >= t1) continue;
            }
            keep(p0 + t0 * (p1 - p0), p0 + t1 * (p1 - p0));
        }
    }
    return out;
}

/// Drops segments lying on the element's boundary (they add nothing) or shorter than `minLen`.
void dropBoundarySegments(const std::vector<glm::dvec2>& poly,
                          std::vector<std::pair<glm::dvec2, glm::dvec2>>& segs, double tol) {
    auto onBoundary = [&](const glm::dvec2& a, const glm::dvec2& b) {
        for (std::size_t i = 0, n = poly.size(); i < n; ++i) {
            const glm::dvec2 p = poly[i], q = poly[(i + 1) % n];
            const glm::dvec2 d = q - p;
            const double len = glm::length(d);
            if (!(len > 0)) continue;
            auto dist = [&](const glm::dvec2& x) {
                return std::abs(d.x * (x.y - p.y) - d.y * (x.x - p.x)) / len;
            };
            if (dist(a) <= tol && dist(b) <= tol) return true;
        }
        return false;
    };
    segs.erase(std::remove_if(segs.begin(), segs.end(),
                              [&](const auto& s) {
                                  return glm::length(s.second - s.first) <= tol ||
                                         onBoundary(s.first, s.second);
                              }),
               segs.end());
}

/// What every element's meshing shares in one HifiMesh::build: the scene's shadow events and
/// contacts, the exact samples taken so far, each element's triangles, and the counters the
/// build's stats report.
struct HifiBuild {
    HifiBuild(const Discretization& d, const ExactIrradiance& x, const HifiOptions& o)
        : disc(d),
          exact(x),
          options(o),
          wedges(allWedges(d, nullptr, x.tracer())),
          wedgeIndex(wedges, d),
          contacts(d),
          perElement(d.elements().size()),
          tracer(x.tracer()) {
        for (const ContactIndex::Object& object : contacts.objects)
            sealed.push_back(object.sealed ? 1 : 0);
    }
    const Discretization& disc;
    const ExactIrradiance& exact;
    const HifiOptions& options;
    const std::vector<Wedge> wedges;
    const WedgeIndex wedgeIndex;
    const ContactIndex contacts;
    std::vector<std::vector<HifiTriangle>> perElement;
    const RayTracer* tracer;           ///< finds covered triangles (null: none is dropped)
    std::vector<std::uint8_t> sealed;  ///< per object: bounds a solid (ContactIndex)
    double absoluteTolerance = 0;      ///< refinementFloor
    double grid = 0;                   ///< sampleGrid
    double minRefineArea = 0;          ///< smallestRefinedArea
    /// An element whose squared diameter is at most this (m²) and that no segment crosses is
    /// sampled once: the squared diagonal of refinement's finest triangle on an element of the
    /// area-weighted median area.
    double singleSampleDiameter2 = 0;
    SampleCache cache;
    /// Once every sample is taken the far field is refined (refineFarFields) and pooled over
    /// neighbouring samples (poolFarField), and every triangle's interpolant fitted again;
    /// perElementKeys holds each emitted triangle's sample keys, in the order of perElement.
    bool refitFarField = false;
    /// Samples the pooling serves defer their far field (HifiOptions::farFieldRecordSpacing).
    bool deferFarField = false;
    /// Samples off their element's base triangles take its far field from them
    /// (HifiOptions::farFieldFromBase); `derived` says how, for the refit.
    bool deriveFarField = false;
    DerivedFarFields derived;
    std::vector<std::vector<std::array<SampleKey, 6>>> perElementKeys;
    std::atomic<int> done{0}, meshed{0}, shadowSegs{0}, contactSegs{0}, samples{0},
        centreSamples{0};
    std::atomic<bool> cancelled{false};
    std::atomic<int> covered{0}, buried{0}, cappedElements{0}, singleSample{0}, derivedSamples{0};
    std::atomic<long long> farRays{0};

    /// Whether the point x of element `el`'s plane lies inside another object that bounds a
    /// solid (the first surface along the normal is such an object seen from inside); false
    /// without a tracer.
    bool buriedPoint(const Element& el, const Vec3& x) const {
        return tracer && insideSolid(disc, *tracer, sealed, x + tracer->epsilon() * el.normal,
                                     el.normal, el.object);
    }
};

/// The refinement test's absolute tolerance: differences below this fraction of the
/// brightest emitter's luminance are ignored (dark corners need no subdivision).
double refinementFloor(const Discretization& disc) {
    double brightest = 0;
    for (const Material& m : disc.materials())
        brightest = std::max(brightest, luminance(m.emission));
    return 1e-4 * brightest;
}

/// Triangles smaller than this (m²) are not refined: 4^-maxRefineDepth of the median element's
/// area, as small as refinement makes a typical element's triangles. A sliver (the side of a
/// thin pole split along its length) is far smaller than that already.
double smallestRefinedArea(const Discretization& disc, int maxRefineDepth) {
    std::vector<double> areas;
    for (std::size_t e = 0; e < disc.elements().size(); ++e)
        if (disc.elementAlive(static_cast<int>(e))) areas.push_back(disc.elements()[e].area);
    if (areas.empty()) return 0;
    std::nth_element(areas.begin(), areas.begin() + areas.size() / 2, areas.end());
    return areas[areas.size() / 2] * std::pow(0.25, std::max(0, maxRefineDepth));
}

/// The area of the element that holds the median square metre of surface (elements sorted by
/// area): the scene's element size as its large surfaces have it, whatever a finely tessellated
/// mesh adds in number.
double areaWeightedMedianArea(const Discretization& disc) {
    std::vector<double> areas;
    double total = 0;
    for (std::size_t e = 0; e < disc.elements().size(); ++e)
        if (disc.elementAlive(static_cast<int>(e))) {
            areas.push_back(disc.elements()[e].area);
            total += areas.back();
        }
    std::sort(areas.begin(), areas.end());
    double below = 0;
    for (double a : areas) {
        below += a;
        if (below >= 0.5 * total) return a;
    }
    return areas.empty() ? 0 : areas.back();
}

/// The median alive element's √area (m).
double medianElementSize(const Discretization& disc) {
    return std::sqrt(smallestRefinedArea(disc, 0));
}

/// The grid sample positions are shared on (metres): far finer than any element.
double sampleGrid(const Discretization& disc) {
    Vec3 sceneLo(1e300), sceneHi(-1e300);
    for (const Element& el : disc.elements()) {
        sceneLo = glm::min(sceneLo, el.centroid);
        sceneHi = glm::max(sceneHi, el.centroid);
    }
    return 1e-9 * std::max(1.0, glm::length(sceneHi - sceneLo));
}

/// An element's discontinuities in its plane's frame, those on its boundary dropped.
struct ElementSegments {
    std::vector<std::pair<glm::dvec2, glm::dvec2>> shadow;   ///< the k strongest above w_min
    std::vector<std::pair<glm::dvec2, glm::dvec2>> contact;  ///< every contact line, clipped
    /// Every contact line before clipping: points on them sample their own side.
    std::vector<std::pair<glm::dvec2, glm::dvec2>> allContacts;
    bool capped = false;  ///< segments were dropped for HifiOptions' caps
};

/// Discontinuities on element e: the contact lines, longest first, then the k strongest shadow
/// events above w_min, at most HifiOptions::maxSegments together; a shadow segment inside
/// another solid (on a part of the element buried in it) is dropped. Counted in the build's
/// stats.
ElementSegments discontinuitiesOn(HifiBuild& b, int e, const ElementGeometry& g, double size) {
    ElementSegments s;
    int kept = 0;
    for (const Discontinuity& d : rankWedges(b.disc, e, g, b.wedges, b.wedgeIndex)) {
        if (kept >= b.options.maxDiscontinuities || d.weight < b.options.minWeight) break;
        s.shadow.emplace_back(g.frame.to2(d.a), g.frame.to2(d.b));
        ++kept;
    }
    for (const Discontinuity& d :
         contactsOn(b.disc, e, g, b.contacts, b.options.contactFraction, &s.allContacts))
        s.contact.emplace_back(g.frame.to2(d.a), g.frame.to2(d.b));
    // Points on a contact line (unclipped: those on the boundary included) sample their side.
    dropBoundarySegments(g.poly2, s.shadow, 1e-6 * size);
    dropBoundarySegments(g.poly2, s.contact, 1e-6 * size);
    // Only an element another surface crosses can be partly inside a solid.
    if (!s.contact.empty() && !s.shadow.empty()) {
        const Element& el = b.disc.elements()[e];
        auto buried = [&](const std::pair<glm::dvec2, glm::dvec2>& seg) {
            for (const glm::dvec2& q : {seg.first, seg.second, 0.5 * (seg.first + seg.second)})
                if (!b.buriedPoint(el, g.frame.to3(q))) return false;
            return true;
        };
        s.shadow.erase(std::remove_if(s.shadow.begin(), s.shadow.end(), buried), s.shadow.end());
    }
    // The cap: contact lines first (irradiance jumps across them), the longest first.
    std::stable_sort(s.contact.begin(), s.contact.end(), [](const auto& x, const auto& y) {
        return glm::length(x.second - x.first) > glm::length(y.second - y.first);
    });
    const std::size_t cap = static_cast<std::size_t>(std::max(0, b.options.maxSegments));
    if (s.contact.size() + s.shadow.size() > cap) {
        if (s.contact.size() > cap) s.contact.resize(cap);
        s.shadow.resize(std::min(s.shadow.size(), cap - s.contact.size()));
        s.capped = true;
    }
    b.shadowSegs.fetch_add(static_cast<int>(s.shadow.size()), std::memory_order_relaxed);
    b.contactSegs.fetch_add(static_cast<int>(s.contact.size()), std::memory_order_relaxed);
    return s;
}

/// The element's triangles in its plane's frame: the element as it is (a fan) when nothing
/// crosses it, else the constrained Delaunay triangulation of its outline with the shadow
/// segments and the contact lines. Past HifiOptions::maxTriangles the weaker half of the
/// shadow segments goes (then the shorter half of the contact lines) until it fits.
Triangulation2 triangulateElement(HifiBuild& b, const ElementGeometry& g, ElementSegments& s) {
    Triangulation2 tri;
    if (s.shadow.empty() && s.contact.empty()) {
        tri.points = g.poly2;
        for (std::size_t k = 1; k + 1 < g.poly2.size(); ++k)
            tri.triangles.push_back({0, static_cast<int>(k), static_cast<int>(k + 1)});
        return tri;
    }
    const std::size_t cap = static_cast<std::size_t>(std::max(1, b.options.maxTriangles));
    for (;;) {
        std::vector<std::pair<glm::dvec2, glm::dvec2>> constraints = s.contact;
        constraints.insert(constraints.end(), s.shadow.begin(), s.shadow.end());
        tri = triangulateConstrained(g.poly2, constraints);
        const bool fits = tri.triangles.size() <= cap;
        if (fits || (s.shadow.empty() && s.contact.size() <= 1)) break;
        s.capped = true;
        if (!s.shadow.empty())
            s.shadow.resize(s.shadow.size() / 2);
        else
            s.contact.resize(s.contact.size() / 2);  // longest first
    }
    b.meshed.fetch_add(1, std::memory_order_relaxed);
    return tri;
}

/// Six exact samples per triangle of one element (§2.2), each triangle refined where its
/// interpolant misses the exact part at its centre (§7.2); the results go to the element's
/// list in the build. On a contact line irradiance jumps: there each sample is moved a hair
/// towards its triangle's centre, so each side takes its own limit. Elsewhere the field is
/// continuous and a sample is shared through the build's cache.
class ElementSampler {
public:
    ElementSampler(HifiBuild& b, int e, const ElementGeometry& g, double size,
                   const std::vector<std::pair<glm::dvec2, glm::dvec2>>& allContacts)
        : mB(b),
          mE(e),
          mEl(b.disc.elements()[e]),
          mG(g),
          mSize(size),
          mAllContacts(allContacts),
          mOut(b.perElement[e]),
          mSheet(b.disc.objects()[mEl.object].isBackFace(mEl.face) ? 1 : 0) {}

    /// Samples (and refines) every non-degenerate triangle of `tri` that is not covered.
    /// Refinement goes level by level over the element, so that HifiOptions::maxTriangles,
    /// when it stops it, leaves the element evenly refined. With `once` (an element smaller
    /// than refinement's finest triangle, nothing crossing it) one sample at the element's
    /// centroid serves all six points of each triangle: a constant interpolant.
    void sampleTriangles(const Triangulation2& tri, bool once = false) {
        // The far field from the element's base triangles, whose samples cast its rays first
        // (HifiOptions::farFieldFromBase). On a contact line irradiance jumps and the far field
        // changes fast beside it: such elements cast rays at every sample.
        if (!once && mB.deriveFarField && mAllContacts.empty()) sampleBase();
        std::deque<Pending> queue;
        std::optional<std::pair<ExactIrradiance::Parts, SampleKey>> single;
        for (const auto& t : tri.triangles) {
            glm::dvec2 p[3] = {tri.points[t[0]], tri.points[t[1]], tri.points[t[2]]};
            const double cross =
                (p[1].x - p[0].x) * (p[2].y - p[0].y) - (p[1].y - p[0].y) * (p[2].x - p[0].x);
            if (std::abs(cross) <= 1e-14 * mSize * mSize) continue;  // degenerate
            if (cross < 0) std::swap(p[1], p[2]);
            const glm::dvec2 centre = (p[0] + p[1] + p[2]) / 3.0;
            // Inside another solid (the floor under a box resting on it): never seen, and
            // dropped it cannot win a depth tie along the contact line either. Behind an open
            // surface (a panel hung under a ceiling) it may be seen from the side, and stays.
            if (mB.buriedPoint(mEl, mG.frame.to3(centre))) {
                mB.covered.fetch_add(1, std::memory_order_relaxed);
                continue;
            }
            Pending pending;
            pending.p = {p[0], p[1], p[2]};
            if (once) {
                if (!single) {
                    SampleKey key;
                    const glm::dvec2 c = mG.frame.to2(mEl.centroid);
                    const ExactIrradiance::Parts r = sampleAt(c, c, key);
                    single.emplace(r, key);
                }
                pending.r.fill(single->first);
                pending.k.fill(single->second);
                emit(pending);
                continue;
            }
            const glm::dvec2 at[6] = {p[0], 0.5 * (p[0] + p[1]), p[1], 0.5 * (p[1] + p[2]),
                                      p[2], 0.5 * (p[0] + p[2])};
            for (int k = 0; k < 6; ++k) pending.r[k] = sampleAt(at[k], centre, pending.k[k]);
            queue.push_back(std::move(pending));
        }
        if (single) mB.singleSample.fetch_add(1, std::memory_order_relaxed);
        // Each split adds three triangles to the element's count.
        int count = static_cast<int>(queue.size());
        const int cap = std::max(mB.options.maxTriangles, count);
        while (!queue.empty()) {
            const Pending t = std::move(queue.front());
            queue.pop_front();
            if (count + 3 <= cap && needsSplit(t)) {
                split(t, queue);
                count += 3;
            } else {
                emit(t);
            }
        }
    }

private:
    /// A base triangle of the far field: the element's fan, counter-clockwise in its frame,
    /// with its samples' keys and far fields at A, AB, B, BC, C, CA.
    struct Base {
        std::array<glm::dvec2, 3> p;
        std::array<SampleKey, 6> k;
        std::array<Rgb, 6> far;
    };

    /// Samples the element's base triangles (its fan, as an element nothing crosses is
    /// meshed), each point with its own far field; the element's other samples derive theirs
    /// from them afterwards.
    void sampleBase() {
        std::vector<Base> bases;
        const auto& poly = mG.poly2;
        for (std::size_t k = 1; k + 1 < poly.size(); ++k) {
            Base base;
            base.p = {poly[0], poly[k], poly[k + 1]};
            const glm::dvec2 e1 = base.p[1] - base.p[0], e2 = base.p[2] - base.p[0];
            const double cross = e1.x * e2.y - e1.y * e2.x;
            if (std::abs(cross) <= 1e-14 * mSize * mSize) continue;  // degenerate
            if (cross < 0) std::swap(base.p[1], base.p[2]);
            const glm::dvec2 centre = (base.p[0] + base.p[1] + base.p[2]) / 3.0;
            const glm::dvec2 at[6] = {base.p[0], 0.5 * (base.p[0] + base.p[1]),
                                      base.p[1], 0.5 * (base.p[1] + base.p[2]),
                                      base.p[2], 0.5 * (base.p[0] + base.p[2])};
            for (int v = 0; v < 6; ++v) base.far[v] = sampleAt(at[v], centre, base.k[v]).farField;
            bases.push_back(base);
        }
        // Only now: while the base is sampled, every point casts its own rays.
        mBase = std::move(bases);
    }

    /// Whether `key` is one of the base triangles' samples.
    bool isBase(const SampleKey& key) const {
        for (const Base& base : mBase)
            for (const SampleKey& k : base.k)
                if (k == key) return true;
        return false;
    }

    /// How the far field at q (in the element's frame) follows from the base triangle that
    /// holds it (the one it is deepest inside): the quadratic's basis functions there. `far`
    /// (optional) receives that far field from the base samples' values as they stand.
    DerivedFarField derivationAt(const glm::dvec2& q, Rgb* far = nullptr) const {
        const Base* from = nullptr;
        DerivedFarField d;
        d.element = mE;
        double deepest = -1e300;
        for (const Base& base : mBase) {
            const glm::dvec2 e1 = base.p[1] - base.p[0], e2 = base.p[2] - base.p[0];
            const glm::dvec2 r = q - base.p[0];
            const double det = e1.x * e2.y - e1.y * e2.x;
            const double s = (r.x * e2.y - r.y * e2.x) / det, t = (e1.x * r.y - e1.y * r.x) / det;
            const double u = 1 - s - t;
            const double inside = std::min({u, s, t});
            if (!(inside > deepest)) continue;
            deepest = inside;
            from = &base;
            d.base = base.k;
            d.weight = {u * (2 * u - 1), 4 * u * s,       s * (2 * s - 1),
                        4 * s * t,       t * (2 * t - 1), 4 * t * u};
        }
        if (far) {
            *far = Rgb(0.0);
            if (from)
                for (int k = 0; k < 6; ++k) *far += d.weight[k] * from->far[k];
        }
        return d;
    }

    /// Files the derivation of `key`'s far field; the smallest element's stands.
    void recordDerivation(const SampleKey& key, const DerivedFarField& d) {
        DerivedFarFields::accessor entry;
        if (mB.derived.insert(entry, key) || d.element < entry->second.element) entry->second = d;
    }

    /// A triangle (counter-clockwise, in the element's frame) with its samples at A, AB, B,
    /// BC, C, CA and its refinement depth.
    struct Pending {
        std::array<glm::dvec2, 3> p;
        std::array<ExactIrradiance::Parts, 6> r;
        int depth = 0;
        std::array<SampleKey, 6> k;  ///< the samples' keys in the build's cache
    };

    /// The exact irradiance at q (2D), from the cache when another triangle took it; q moves
    /// towards `centre` when it lies on a contact line.
    ExactIrradiance::Parts sampleAt(const glm::dvec2& q, const glm::dvec2& centre, SampleKey& key) {
        bool onContact = false;
        for (const auto& [a, b] : mAllContacts)
            if (distanceToSegment(q, a, b) <= 1e-6 * mSize) {
                onContact = true;
                break;
            }
        const Vec3 x = mG.frame.to3(onContact ? q + 1e-4 * (centre - q) : q);
        key = SampleKey::at(mEl.object, mSheet, onContact ? mE : -1, x, mEl.normal, mB.grid);
        // Off the base triangles' samples the far field is theirs (farFieldFromBase). The
        // derivation is filed also where another element took the point first, so that the
        // refit's value does not depend on which did.
        const bool derive = !mBase.empty() && !onContact && !isBase(key);
        {
            SampleCache::const_accessor found;
            if (mB.cache.find(found, key)) {
                if (derive) recordDerivation(key, derivationAt(q));
                return found->second;
            }
        }
        // Evaluated outside any lock; a point two threads reach at once is evaluated
        // twice to the same value.
        mB.samples.fetch_add(1, std::memory_order_relaxed);
        ExactIrradiance::Parts value;
        if (derive) {
            value = mB.exact.irradianceParts(x, mEl.normal, false);
            const DerivedFarField d = derivationAt(q, &value.farField);
            value.farFitted = true;
            recordDerivation(key, d);
            mB.derivedSamples.fetch_add(1, std::memory_order_relaxed);
        } else if (mB.deferFarField && !onContact) {
            // The far field later, from records (fitDeferredFarFields), where it is smooth.
            value = mB.exact.irradianceParts(x, mEl.normal, false);
            if (farFieldSharable(key, value))
                mB.farRays.fetch_add(
                    mB.exact.previewFarField(x, mEl.normal, mB.options.farFieldPreviewRays, value),
                    std::memory_order_relaxed);
            else
                mB.exact.refineFarField(x, mEl.normal, 1, value);
        } else {
            value = mB.exact.irradianceParts(x, mEl.normal);
        }
        mB.farRays.fetch_add(value.farRays, std::memory_order_relaxed);
        // The first value stored wins, so every triangle sharing the point sees one.
        SampleCache::accessor stored;
        if (mB.cache.insert(stored, key)) stored->second = value;
        return stored->second;
    }

    /// The refinement test's centre sample: it lies inside one triangle (never shared) and
    /// needs only the exact part.
    Rgb centreSample(const glm::dvec2& q) {
        mB.centreSamples.fetch_add(1, std::memory_order_relaxed);
        return mB.exact.irradianceParts(mG.frame.to3(q), mEl.normal, false).gathered;
    }

    /// Whether the triangle's interpolant misses an exact sample at its centre by more than
    /// the tolerance (§7.2), below maxRefineDepth.
    bool needsSplit(const Pending& t) {
        const HifiOptions& options = mB.options;
        if (t.depth >= options.maxRefineDepth || !(options.refineTolerance > 0)) return false;
        const glm::dvec2 e1 = t.p[1] - t.p[0], e2 = t.p[2] - t.p[0];
        if (0.5 * std::abs(e1.x * e2.y - e1.y * e2.x) < mB.minRefineArea) return false;
        std::array<Rgb, 6> total, exactPart;
        for (int k = 0; k < 6; ++k) {
            total[k] = t.r[k].total();
            exactPart[k] = t.r[k].gathered;
        }
        const glm::dvec2 centre = (t.p[0] + t.p[1] + t.p[2]) / 3.0;
        const double truth = luminance(centreSample(centre));
        // The fit of the exact part: the far field's ray noise would split triangles for
        // nothing, and the far field is smooth.
        const double fitted =
            luminance(QuadraticInterpolant::fromSamples(exactPart)(1.0 / 3.0, 1.0 / 3.0));
        // Relative to the whole irradiance there (what the pixel shows).
        const double seen =
            luminance(QuadraticInterpolant::fromSamples(total)(1.0 / 3.0, 1.0 / 3.0));
        return std::abs(fitted - truth) >
               options.refineTolerance * std::abs(seen) + mB.absoluteTolerance;
    }

    /// Splits t into four at its edge midpoints, whose samples it already has.
    void split(const Pending& t, std::deque<Pending>& queue) {
        const auto& p = t.p;
        const auto& r = t.r;
        const glm::dvec2 mid[3] = {0.5 * (p[0] + p[1]), 0.5 * (p[1] + p[2]), 0.5 * (p[2] + p[0])};
        // Children: corner triangles and the middle one, counter-clockwise.
        const glm::dvec2 corners[4][3] = {{p[0], mid[0], mid[2]},
                                          {mid[0], p[1], mid[1]},
                                          {mid[2], mid[1], p[2]},
                                          {mid[0], mid[1], mid[2]}};
        // Their vertex samples in the parent's order (A, AB, B, BC, C, CA).
        const int vertex[4][3] = {{0, 1, 5}, {1, 2, 3}, {5, 3, 4}, {1, 3, 5}};
        for (int c = 0; c < 4; ++c) {
            const glm::dvec2* cp = corners[c];
            const glm::dvec2 cc = (cp[0] + cp[1] + cp[2]) / 3.0;
            Pending child;
            child.p = {cp[0], cp[1], cp[2]};
            child.depth = t.depth + 1;
            for (int v = 0; v < 3; ++v) {
                child.r[2 * v] = r[vertex[c][v]];
                child.k[2 * v] = t.k[vertex[c][v]];
                const glm::dvec2 mid = 0.5 * (cp[v] + cp[(v + 1) % 3]);
                child.r[2 * v + 1] = sampleAt(mid, cc, child.k[2 * v + 1]);
            }
            queue.push_back(std::move(child));
        }
    }

    /// The triangle as it is, with the interpolant through its six samples.
    void emit(const Pending& t) {
        std::array<Rgb, 6> total;
        for (int k = 0; k < 6; ++k) total[k] = t.r[k].total();
        HifiTriangle ht;
        ht.element = mE;
        for (int k = 0; k < 3; ++k) ht.p[k] = mG.frame.to3(t.p[k]);
        ht.irradiance = QuadraticInterpolant::fromSamples(total);
        mOut.push_back(ht);
        // With a refined or pooled far field it is fitted again once every sample is taken.
        if (mB.refitFarField) mB.perElementKeys[mE].push_back(t.k);
    }

    HifiBuild& mB;
    const int mE;
    const Element& mEl;
    const ElementGeometry& mG;
    const double mSize;  ///< √area: the element's scale for tolerances
    const std::vector<std::pair<glm::dvec2, glm::dvec2>>& mAllContacts;
    std::vector<HifiTriangle>& mOut;
    const int mSheet;  ///< 1 on a back face's element, else 0 (part of the sample key)
    std::vector<Base> mBase;  ///< farFieldFromBase: the element's base triangles (else none)
};

/// The element's squared bounding radius about `centre` (m²).
double squaredRadius(const ElementGeometry& g, const Vec3& centre) {
    double r2 = 0;
    for (const Vec3& p : g.poly) r2 = std::max(r2, glm::dot(p - centre, p - centre));
    return r2;
}

/// Whether the whole element lies inside another solid (a sofa seat's end inside its arm): its
/// centroid and points next to each corner are.
bool buriedElement(const HifiBuild& b, const Element& el, const ElementGeometry& g) {
    if (!b.buriedPoint(el, el.centroid)) return false;
    for (const Vec3& corner : g.poly)
        if (!b.buriedPoint(el, corner + 1e-3 * (el.centroid - corner))) return false;
    return true;
}

/// Meshes and samples element e into the build's list for it; nothing once the build is
/// cancelled (HifiOptions::cancelled, polled here) or for a dead element.
void meshElement(HifiBuild& b, int e) {
    b.done.fetch_add(1, std::memory_order_relaxed);
    if (b.cancelled.load(std::memory_order_relaxed)) return;
    if (b.options.cancelled && b.options.cancelled()) {
        b.cancelled.store(true, std::memory_order_relaxed);
        return;
    }
    if (!b.disc.elementAlive(e)) return;
    const Element& el = b.disc.elements()[e];
    const ElementGeometry g = geometryOf(b.disc, e);
    const double size = std::sqrt(el.area);
    if (buriedElement(b, el, g)) {
        b.buried.fetch_add(1, std::memory_order_relaxed);
        return;
    }
    // Discontinuities: the k strongest shadow events above w_min, every contact line.
    ElementSegments segs = discontinuitiesOn(b, e, g, size);
    // Triangulate (the element as it is when nothing crosses it).
    const Triangulation2 tri = triangulateElement(b, g, segs);
    // Six exact samples per triangle, refined where the interpolant misses; one for an element
    // no wider than refinement's finest triangle that nothing crosses (a face of a finely
    // tessellated mesh, a centimetre or two across): six would fit a quadratic over a few
    // pixels from samples no neighbour shares (its normal is its own).
    const bool once = segs.shadow.empty() && segs.contact.empty() &&
                      4 * squaredRadius(g, el.centroid) <= b.singleSampleDiameter2;
    ElementSampler(b, e, g, size, segs.allContacts).sampleTriangles(tri, once);
    if (segs.capped) b.cappedElements.fetch_add(1, std::memory_order_relaxed);
}

/// Runs `work`; with `progress`, on a thread of its own while this one reports done / count
/// to it every 200 ms (and 1 at the end).
template <class Work>
void runReportingProgress(Work&& work, const std::atomic<int>& done, int count,
                          const std::function<void(double)>& progress) {
    if (progress) {
        std::thread worker(work);
        while (done.load() < count) {
            progress(double(done.load()) / std::max(1, count));
            std::this_thread::sleep_for(std::chrono::milliseconds(200));
        }
        worker.join();
        progress(1.0);
    } else {
        work();
    }
}

}  // namespace

std::vector<Discontinuity> shadowDiscontinuities(const Discretization& disc, int element,
                                                 WedgeSearch search) {
    const std::vector<Wedge> wedges = allWedges(disc);
    return rankWedges(disc, element, geometryOf(disc, element), wedges,
                      search == WedgeSearch::Indexed ? WedgeIndex(wedges, disc) : WedgeIndex());
}

std::vector<Discontinuity> contactLines(const Discretization& disc, int element,
                                        double contactFraction) {
    return contactsOn(disc, element, geometryOf(disc, element), ContactIndex(disc),
                      contactFraction);
}

void HifiMesh::build(const Discretization& disc, const ExactIrradiance& exact,
                     const HifiOptions& options, const std::function<void(double)>& progress) {
    std::vector<int> todo(disc.elements().size());
    for (std::size_t e = 0; e < todo.size(); ++e) todo[e] = static_cast<int>(e);
    mesh(disc, exact, options, progress, todo, {});
}

void HifiMesh::update(const Discretization& disc, const ExactIrradiance& exact,
                      const std::vector<std::uint8_t>& remesh, const HifiOptions& options,
                      const std::function<void(double)>& progress) {
    const int built = std::max(0, static_cast<int>(mFirst.size()) - 1);
    const int elementCount = static_cast<int>(disc.elements().size());
    std::vector<int> todo;
    std::vector<std::uint8_t> keep(std::size_t(elementCount), 0);
    for (int e = 0; e < elementCount; ++e) {
        if (!disc.elementAlive(e)) continue;
        const bool flagged = e < static_cast<int>(remesh.size()) && remesh[std::size_t(e)];
        if (e < built && !flagged)
            keep[std::size_t(e)] = 1;
        else
            todo.push_back(e);
    }
    mesh(disc, exact, options, progress, todo, keep);
}

void HifiMesh::mesh(const Discretization& disc, const ExactIrradiance& exact,
                    const HifiOptions& options, const std::function<void(double)>& progress,
                    const std::vector<int>& todo, const std::vector<std::uint8_t>& keep) {
    const auto start = std::chrono::steady_clock::now();
    const int elementCount = static_cast<int>(disc.elements().size());
    HifiBuild b(disc, exact, options);
    b.absoluteTolerance = refinementFloor(disc);
    b.grid = sampleGrid(disc);
    b.minRefineArea = smallestRefinedArea(disc, options.maxRefineDepth);
    b.singleSampleDiameter2 =
        2 * areaWeightedMedianArea(disc) * std::pow(0.25, std::max(0, options.maxRefineDepth));
    const int count = static_cast<int>(todo.size());
    b.refitFarField = exact.options().farRays > 0 && exact.tracer() &&
                      (options.farFieldPoolRadius > 0 || options.farFieldRefineBudget > 0);
    if (b.refitFarField) b.perElementKeys.resize(disc.elements().size());
    b.deferFarField = b.refitFarField && farFieldByRecords(exact, options);
    b.deriveFarField = b.refitFarField && !b.deferFarField && options.farFieldFromBase;
    auto work = [&] { tbb::parallel_for(0, count, [&](int k) { meshElement(b, todo[k]); }); };
    runReportingProgress(work, b.done, count, progress);
    if (b.refitFarField && !b.cancelled.load())
        b.farRays += finishFarFields(b.cache, b.grid, exact, disc, options, medianElementSize(disc),
                                     b.perElement, b.perElementKeys,
                                     b.deriveFarField ? &b.derived : nullptr);
    // The elements' triangles in element order: kept ones from this mesh, the rest new.
    std::vector<HifiTriangle> triangles;
    std::vector<int> first(std::size_t(elementCount) + 1, 0);
    for (int e = 0; e < elementCount; ++e) {
        first[e] = static_cast<int>(triangles.size());
        if (e < static_cast<int>(keep.size()) && keep[std::size_t(e)])
            triangles.insert(triangles.end(), mTriangles.begin() + mFirst[e],
                             mTriangles.begin() + mFirst[e + 1]);
        else
            triangles.insert(triangles.end(), b.perElement[e].begin(), b.perElement[e].end());
    }
    first[elementCount] = static_cast<int>(triangles.size());
    mTriangles = std::move(triangles);
    mFirst = std::move(first);
    mStats = {};
    mStats.elements = elementCount;
    mStats.remeshed = count;
    mStats.meshedElements = b.meshed.load();
    mStats.triangles = static_cast<int>(mTriangles.size());
    mStats.shadowSegments = b.shadowSegs.load();
    mStats.contactSegments = b.contactSegs.load();
    mStats.cancelled = b.cancelled.load();
    mStats.coveredTriangles = b.covered.load();
    mStats.buriedElements = b.buried.load();
    mStats.cappedElements = b.cappedElements.load();
    mStats.singleSampleElements = b.singleSample.load();
    mStats.derivedFarFields = b.derivedSamples.load();
    mStats.samples = b.samples.load();
    mStats.centreSamples = b.centreSamples.load();
    mStats.farRays = b.farRays.load();
    mStats.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::vector<std::uint8_t> hifiRemeshElements(const Discretization& disc,
                                             const std::vector<Rgb>& before,
                                             const std::vector<Rgb>& after,
                                             const std::vector<int>& changedObjects,
                                             double threshold, const HifiOptions& options) {
    const std::size_t n = disc.elements().size();
    std::vector<std::uint8_t> remesh(n, 1);
    // A changed lamp moves every event it casts: everything is re-meshed.
    for (int o : changedObjects) {
        const auto [first, count] = disc.elementRange(o);
        if (count > 0 && disc.elementMaterial(first).isEmitter()) return remesh;
    }
    const std::vector<std::uint8_t> relit =
        changedElements(elementLuminance(before), elementLuminance(after), threshold);
    // The events the changed objects cast before and after, and their bounds (contacts).
    const std::vector<Wedge> wedges = allWedges(disc, &changedObjects);
    const WedgeIndex wedgeIndex(wedges, disc);
    std::vector<std::pair<Vec3, Vec3>> bounds;
    for (int o : changedObjects) {
        Vec3 lo(1e300), hi(-1e300);
        for (const Vec3& p : disc.objects()[std::size_t(o)].worldPositions)
            lo = glm::min(lo, p), hi = glm::max(hi, p);
        bounds.emplace_back(lo, hi);
    }
    auto unchanged = [&](std::size_t e) {
        if (relit[e]) return false;
        const int ei = static_cast<int>(e);
        const ElementGeometry g = geometryOf(disc, ei);
        // Near a changed object: its contact lines on this element may have come or gone.
        const double margin = options.contactFraction * std::sqrt(disc.elements()[e].area);
        Vec3 lo(1e300), hi(-1e300);
        for (const Vec3& p : g.poly) lo = glm::min(lo, p), hi = glm::max(hi, p);
        for (const auto& [blo, bhi] : bounds)
            if (glm::all(glm::lessThanEqual(lo - margin, bhi)) &&
                glm::all(glm::lessThanEqual(blo, hi + margin)))
                return false;
        // Crossed by an event of a changed object strong enough to be meshed, before or after
        // (the element's mean light may hold while a penumbra moves across it).
        std::vector<int> candidates;
        wedgeIndex.query(g.poly, wedges.size(), candidates);
        for (int i : candidates) {
            glm::dvec2 a, b;
            double weight = 0;
            if (wedgeOnElement(wedges[i], disc.elements()[e], g.frame, g.poly2, a, b, weight) &&
                weight >= options.minWeight)
                return false;
        }
        return true;
    };
    const std::size_t known = std::min({n, before.size(), after.size()});
    tbb::parallel_for(std::size_t(0), known, [&](std::size_t e) {
        if (disc.elementAlive(static_cast<int>(e)) && unchanged(e)) remesh[e] = 0;
    });
    return remesh;
}

int HifiMesh::locate(int element, const Vec3& x, double& s, double& t) const {
    if (element < 0 || element + 1 >= static_cast<int>(mFirst.size())) return -1;
    int best = -1;
    double bestOutside = std::numeric_limits<double>::infinity();
    for (int k = mFirst[element]; k < mFirst[element + 1]; ++k) {
        const HifiTriangle& tri = mTriangles[k];
        const Vec3 e1 = tri.p[1] - tri.p[0], e2 = tri.p[2] - tri.p[0], d = x - tri.p[0];
        const double a = glm::dot(e1, e1), b = glm::dot(e1, e2), c = glm::dot(e2, e2);
        const double p = glm::dot(d, e1), q = glm::dot(d, e2);
        const double det = a * c - b * b;
        if (!(det > 0)) continue;
        const double si = (c * p - b * q) / det, ti = (a * q - b * p) / det;
        // How far outside (0 inside): the nearest triangle wins at shared edges and cracks.
        const double outside = std::max({0.0, -si, -ti, si + ti - 1});
        if (outside < bestOutside) {
            bestOutside = outside;
            best = k;
            s = si;
            t = ti;
            if (outside == 0) break;
        }
    }
    if (best >= 0) {
        s = std::clamp(s, 0.0, 1.0);
        t = std::clamp(t, 0.0, 1.0 - s);
    }
    return best;
}

Rgb HifiMesh::radiosity(const Discretization& disc, int triangle, double s, double t) const {
    const HifiTriangle& tri = mTriangles[triangle];
    const Material& m = disc.elementMaterial(tri.element);
    const Element& el = disc.elements()[tri.element];
    const bool back = disc.objects()[el.object].isBackFace(el.face);
    return (back ? Rgb(0.0) : m.emission) + m.reflectance * tri.irradiance.irradiance(s, t);
}

Image renderInterpolants(const Discretization& disc, const RayTracer& tracer, const HifiMesh& mesh,
                         const CameraRays& rays, int samples) {
    Image image(rays.width(), rays.height());
    const int n = std::max(1, samples);
    tbb::parallel_for(0, rays.height(), [&](int y) {
        for (int x = 0; x < rays.width(); ++x) {
            Rgb sum(0.0);
            for (int k = 0; k < n * n; ++k) {
                const double jx = (k % n + 0.5) / n, jy = (k / n + 0.5) / n;
                const Vec3 dir = rays.rayDirection(x + jx, y + jy);
                const RayTracer::FirstHit hit = tracer.firstHit(rays.origin(), dir);
                if (hit.element < 0 || hit.backFace) continue;
                const Vec3 p = rays.origin() + static_cast<double>(hit.t) * dir;
                double s = 0, t = 0;
                const int tri = mesh.locate(hit.element, p, s, t);
                if (tri < 0) continue;
                sum += mesh.radiosity(disc, tri, s, t);
            }
            image.at(x, y) = sum / (M_PI * n * n);
        }
    });
    return image;
}

std::string HifiMesh::toString() const {
    std::ostringstream s;
    s << "HifiMesh{elements=" << mStats.elements << ", meshed=" << mStats.meshedElements
      << ", triangles=" << mStats.triangles << ", shadow_segments=" << mStats.shadowSegments
      << ", contact_segments=" << mStats.contactSegments << ", samples=" << mStats.samples
      << ", seconds=" << mStats.seconds << "}";
    return s.str();
}

}  // namespace penumbra
