// The discontinuities that cross an element (Hardt & Teller §4): the VE/EV events of every
// light outline with the objects between (wedges, found through a bounding-volume hierarchy over
// the regions they can reach) and the contact lines where another surface meets or nearly
// touches it; and the elements an edit makes HifiMesh::update re-mesh. The meshing and sampling
// that use them are in hifi_mesh.cpp.

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "render/edge_mesh.h"
#include "render/hifi/hifi_mesh.h"
#include "render/hifi/hifi_mesh_internal.h"
#include "render/light_change.h"
#include "solver/discretization.h"
#include "solver/ray_tracer.h"

namespace penumbra::hifi_detail {

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

}  // namespace

bool insideSolid(const Discretization& disc, const RayTracer& tracer,
                 const std::vector<std::uint8_t>& sealed, const Vec3& x, const Vec3& dir,
                 int self) {
    const RayTracer::FirstHit hit = tracer.firstHit(x, dir, Visibility(self));
    if (hit.element < 0) return false;
    const Element& el = disc.elements()[hit.element];
    if (el.object == self || !sealed[std::size_t(el.object)]) return false;
    return hit.backFace || disc.objects()[el.object].isBackFace(el.face);
}

std::vector<Wedge> allWedges(const Discretization& disc, const std::vector<int>* blockers,
                             const RayTracer* tracer) {
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

WedgeIndex::WedgeIndex(const std::vector<Wedge>& wedges, const Discretization& disc)
    : mIndexed(true) {
    Box3 scene;
    for (const ObjectSurface& surface : disc.objects())
        if (surface.alive)
            for (const Vec3& p : surface.worldPositions) scene.extend(p);
    if (scene.empty()) return;
    const double diagonal = glm::length(scene.hi - scene.lo);
    mPad = 1e-6 * diagonal + 1e-12;
    scene.lo -= Vec3(mPad);
    scene.hi += Vec3(mPad);
    // Slabs eight elements thick, of the element that holds the median square metre (the
    // size of the surfaces shadows fall on, however many small faces a tessellated mesh adds).
    const double slab = std::max(8 * std::sqrt(areaWeightedMedianArea(disc)), 1e-3 * diagonal);
    // Far enough along the rays to leave the box (the rays part by less than 180°).
    const double far = 1e3 * (diagonal + 1);
    for (std::size_t w = 0; w < wedges.size(); ++w) {
        const Wedge& wedge = wedges[w];
        const Vec3 d0 = glm::normalize(wedge.b[0] - wedge.a[0]);
        const Vec3 d1 = glm::normalize(wedge.b[1] - wedge.a[1]);
        const std::vector<Vec3> region = clipToBox(
            {wedge.b[0], wedge.b[1], wedge.b[1] + far * d1, wedge.b[0] + far * d0}, scene);
        Box3 whole;
        for (const Vec3& p : region) whole.extend(p);
        if (whole.empty()) continue;
        // Slabs across the region's longest extent, each piece's box padded so that pieces
        // sharing a slab face overlap.
        const Vec3 extent = whole.hi - whole.lo;
        const int axis = extent.x >= extent.y && extent.x >= extent.z ? 0
                         : extent.y >= extent.z                       ? 1
                                                                      : 2;
        const int slabs = std::clamp(static_cast<int>(std::ceil(extent[axis] / slab)), 1, 16);
        for (int k = 0; k < slabs; ++k) {
            Box3 cut = whole;
            cut.lo[axis] = whole.lo[axis] + extent[axis] * k / slabs;
            cut.hi[axis] =
                k + 1 == slabs ? whole.hi[axis] : whole.lo[axis] + extent[axis] * (k + 1) / slabs;
            Box3 box;
            for (const Vec3& p : slabs == 1 ? region : clipToBox(region, cut)) box.extend(p);
            if (box.empty()) continue;
            box.lo -= Vec3(mPad), box.hi += Vec3(mPad);
            mBoxes.push_back(box);
            mWedge.push_back(static_cast<int>(w));
        }
    }
    mTree.build(mBoxes);
}

void WedgeIndex::query(const std::vector<Vec3>& poly, std::size_t count,
                       std::vector<int>& out) const {
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
    // The pieces whose own boxes meet the element's, as their wedges, each once.
    std::size_t kept = 0;
    for (int piece : out)
        if (mBoxes[piece].overlaps(box)) out[kept++] = mWedge[piece];
    out.resize(kept);
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
}

std::vector<Vec3> WedgeIndex::clipToBox(std::vector<Vec3> poly, const Box3& box) {
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

ContactIndex::ContactIndex(const Discretization& disc) : objects(disc.objects().size()) {
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
        const int front = std::min(surface.firstBackFace, static_cast<int>(surface.mesh.n_faces()));
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

std::vector<Discontinuity> contactsOn(const Discretization& disc, int e, const ElementGeometry& g,
                                      const ContactIndex& index, double contactFraction,
                                      std::vector<std::pair<glm::dvec2, glm::dvec2>>* unclipped) {
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

}  // namespace penumbra::hifi_detail

namespace penumbra {

using namespace hifi_detail;

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

}  // namespace penumbra
