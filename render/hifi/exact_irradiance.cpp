#include "render/hifi/exact_irradiance.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>
#include <string>
#include <tuple>

#include "core/math.h"
#include "core/random.h"
#include "solver/discretization.h"
#include "solver/form_factor.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"

namespace penumbra {

namespace {

double cross2(const Vec2& a, const Vec2& b) { return a.x * b.y - a.y * b.x; }

/// Twice the signed area of a 2D polygon (positive counter-clockwise).
double signedArea2(const std::vector<Vec2>& p) {
    double a = 0;
    for (std::size_t i = 0, n = p.size(); i < n; ++i) a += cross2(p[i], p[(i + 1) % n]);
    return a;
}

/// The part of convex `poly` where side(p) ≥ 0 (Sutherland–Hodgman against one line), with
/// side affine in p. Writes into `out`.
template <typename P, typename Side>
void clipConvex(const std::vector<P>& poly, Side side, std::vector<P>& out) {
    out.clear();
    const std::size_t n = poly.size();
    if (n == 0) return;
    P prev = poly[n - 1];
    double sPrev = side(prev);
    for (std::size_t i = 0; i < n; ++i) {
        const P& cur = poly[i];
        const double s = side(cur);
        // A vertex on the line is kept as it is, never doubled by an intersection.
        if ((sPrev > 0 && s < 0) || (sPrev < 0 && s > 0)) {
            const double t = sPrev / (sPrev - s);
            out.push_back(prev + t * (cur - prev));
        }
        if (s >= 0) out.push_back(cur);
        prev = cur;
        sPrev = s;
    }
    if (out.size() < 3) out.clear();
}

}  // namespace

bool isConvexPolygon(const std::vector<Vec3>& polygon, const Vec3& normal) {
    const std::size_t n = polygon.size();
    if (n < 3) return false;
    double scale = 0;
    for (const Vec3& p : polygon) scale = std::max(scale, glm::length(p - polygon[0]));
    for (std::size_t i = 0; i < n; ++i) {
        const Vec3 a = polygon[(i + 1) % n] - polygon[i];
        const Vec3 b = polygon[(i + 2) % n] - polygon[(i + 1) % n];
        if (glm::dot(glm::cross(a, b), normal) < -1e-12 * scale * scale) return false;
    }
    return true;
}

// ---------------------------------------------------------------------------------------------
// PolygonSet2

PolygonSet2::PolygonSet2(std::vector<Vec2> convex) {
    const double a = signedArea2(convex);
    if (a < 0) std::reverse(convex.begin(), convex.end());
    mMinArea = std::abs(a) * 1e-12;
    if (convex.size() >= 3 && std::abs(a) > 0) mPieces.push_back(std::move(convex));
}

void PolygonSet2::subtract(const std::vector<Vec2>& convexIn) {
    if (convexIn.size() < 3 || mPieces.empty()) return;
    Vec2 lo(1e300), hi(-1e300);
    for (const Vec2& p : convexIn) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    // Drop repeated vertices: a zero-length edge has no line to peel along.
    const double tiny = 1e-24 * std::max(glm::dot(hi - lo, hi - lo), 1e-300);
    std::vector<Vec2> s;
    s.reserve(convexIn.size());
    for (const Vec2& p : convexIn) {
        if (!s.empty() && glm::dot(p - s.back(), p - s.back()) <= tiny) continue;
        s.push_back(p);
    }
    while (s.size() > 1 && glm::dot(s.front() - s.back(), s.front() - s.back()) <= tiny)
        s.pop_back();
    const double sArea = signedArea2(s);
    if (s.size() < 3 || std::abs(sArea) <= mMinArea) return;  // nothing to remove
    if (sArea < 0) std::reverse(s.begin(), s.end());
    std::vector<std::vector<Vec2>> next;
    next.reserve(mPieces.size() + 4);
    std::vector<Vec2> rest, outside, inside;
    for (std::vector<Vec2>& piece : mPieces) {
        Vec2 plo(1e300), phi(-1e300);
        for (const Vec2& p : piece) {
            plo = glm::min(plo, p);
            phi = glm::max(phi, p);
        }
        if (phi.x <= lo.x || hi.x <= plo.x || phi.y <= lo.y || hi.y <= plo.y) {
            next.push_back(std::move(piece));
            continue;
        }
        // Peel off the part outside each edge's line; what stays inside every line is the
        // overlap, which goes.
        rest = piece;
        std::vector<std::vector<Vec2>> peeled;
        bool disjoint = false;
        for (std::size_t i = 0, n = s.size(); i < n && !rest.empty(); ++i) {
            const Vec2 a = s[i], d = s[(i + 1) % n] - s[i];
            auto left = [&](const Vec2& p) { return cross2(d, p - a); };
            clipConvex(
                rest, [&](const Vec2& p) { return -left(p); }, outside);
            clipConvex(rest, left, inside);
            if (inside.empty()) {  // the piece lies outside this edge: untouched
                disjoint = true;
                break;
            }
            if (!outside.empty() && std::abs(signedArea2(outside)) > mMinArea)
                peeled.push_back(outside);
            rest.swap(inside);
        }
        if (disjoint) {
            next.push_back(std::move(piece));
            continue;
        }
        for (auto& p : peeled) next.push_back(std::move(p));
    }
    mPieces.swap(next);
}

double PolygonSet2::area() const {
    double a = 0;
    for (const auto& p : mPieces) a += 0.5 * signedArea2(p);
    return a;
}

// ---------------------------------------------------------------------------------------------
// ExactIrradiance

ExactIrradiance::ExactIrradiance(const Discretization& disc, ExactIrradianceOptions options,
                                 const RayTracer* tracer)
    : mDisc(disc), mOptions(options), mTracer(tracer) {
    rebuild();
}

namespace {

/// The convex hull of 2D points, counter-clockwise (Andrew's monotone chain).
std::vector<Vec2> convexHull(std::vector<Vec2> points) {
    std::sort(points.begin(), points.end(),
              [](const Vec2& a, const Vec2& b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
    if (points.size() < 3) return points;
    std::vector<Vec2> hull(2 * points.size());
    std::size_t k = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
        while (k >= 2 && cross2(hull[k - 1] - hull[k - 2], points[i] - hull[k - 2]) <= 0) --k;
        hull[k++] = points[i];
    }
    for (std::size_t i = points.size() - 1, lower = k + 1; i-- > 0;) {
        while (k >= lower && cross2(hull[k - 1] - hull[k - 2], points[i] - hull[k - 2]) <= 0) --k;
        hull[k++] = points[i];
    }
    hull.resize(k - 1);
    return hull;
}

}  // namespace

void ExactIrradiance::mergeCoplanarEmitters(std::vector<Source>& sources) {
    if (sources.size() < 2) return;
    // One plane and one emission: every piece's normal and plane offset agree with the first.
    const PlaneFrame frame(sources.front().polygon);
    double area = 0, extent = 0;
    for (const Source& s : sources) {
        if (s.radiosity != sources.front().radiosity) return;
        const PlaneFrame f(s.polygon);
        if (glm::dot(f.n, frame.n) < 1 - 1e-9) return;
        for (const Vec3& p : s.polygon) {
            extent = std::max(extent, glm::length(p - frame.origin));
            if (std::abs(glm::dot(p - frame.origin, frame.n)) > 1e-9 * (1 + extent)) return;
        }
        Vec3 newell(0.0);
        for (std::size_t i = 0, n = s.polygon.size(); i < n; ++i)
            newell += glm::cross(s.polygon[i], s.polygon[(i + 1) % n]);
        area += 0.5 * glm::length(newell);
    }
    // The pieces tile their convex hull (no gap, no overlap) when their areas add up to it.
    std::vector<Vec2> points;
    for (const Source& s : sources)
        for (const Vec3& p : s.polygon) points.push_back(frame.to2(p));
    const std::vector<Vec2> hull = convexHull(std::move(points));
    if (hull.size() < 3) return;
    const double hullArea = 0.5 * signedArea2(hull);
    if (std::abs(hullArea - area) > 1e-9 * area) return;
    Source merged = sources.front();
    merged.polygon.clear();
    // Counter-clockwise seen from the front, as the pieces are.
    for (const Vec2& p : hull) merged.polygon.push_back(frame.to3(p));
    sources.assign(1, std::move(merged));
}

void ExactIrradiance::rebuild() {
    mBlockers.clear();
    mObjects.clear();
    mEmitters.clear();
    mPatches.clear();
    Vec3 sceneLo(1e300), sceneHi(-1e300);
    const auto& patches = mDisc.patches();
    const auto& elements = mDisc.elements();
    // Blockers: each front-sheet patch's convex outline, or its elements.
    std::vector<std::vector<int>> patchesOf(mDisc.objects().size());
    for (std::size_t p = 0; p < patches.size(); ++p)
        if (mDisc.patchAlive(static_cast<int>(p)))
            patchesOf[patches[p].object].push_back(static_cast<int>(p));
    for (std::size_t o = 0; o < patchesOf.size(); ++o) {
        if (patchesOf[o].empty()) continue;
        const ObjectSurface& surface = mDisc.objects()[o];
        ObjectBlockers ob;
        ob.object = static_cast<int>(o);
        ob.first = static_cast<int>(mBlockers.size());
        ob.lo = Vec3(1e300);
        ob.hi = Vec3(-1e300);
        auto add = [&](std::vector<Vec3> poly) {
            Blocker b;
            b.lo = Vec3(1e300);
            b.hi = Vec3(-1e300);
            for (const Vec3& q : poly) {
                b.lo = glm::min(b.lo, q);
                b.hi = glm::max(b.hi, q);
            }
            ob.lo = glm::min(ob.lo, b.lo);
            ob.hi = glm::max(ob.hi, b.hi);
            b.normal = unitNormal(poly);
            b.polygon = std::move(poly);
            b.object = static_cast<int>(o);
            mBlockers.push_back(std::move(b));
        };
        std::vector<Source> objectEmitters;
        for (int p : patchesOf[o]) {
            const Patch& P = patches[p];
            const bool back =
                !P.elements.empty() && surface.isBackFace(elements[P.elements.front()].face);
            const bool convex = !P.outline.empty() && isConvexPolygon(P.outline, P.normal);
            // Sources: every patch (a back sheet reflects toward its own side).
            SourcePatch sp;
            sp.patch = p;
            sp.centroid = P.centroid;
            sp.radius = P.radius;
            sp.convexOutline = convex;
            mPatches.push_back(sp);
            const Material& m = mDisc.patchMaterial(p);
            if (m.isEmitter() && !back) {
                if (convex) {
                    objectEmitters.push_back({P.outline, m.emission, static_cast<int>(o)});
                } else {
                    for (int e : P.elements)
                        objectEmitters.push_back(
                            {mDisc.elementPolygon(e), m.emission, static_cast<int>(o)});
                }
            }
            if (back) continue;  // the same surface as its front sheet: blocks once
            if (convex) {
                add(P.outline);
            } else {
                for (int e : P.elements) add(mDisc.elementPolygon(e));
            }
        }
        mergeCoplanarEmitters(objectEmitters);
        for (Source& source : objectEmitters) mEmitters.push_back(std::move(source));
        ob.count = static_cast<int>(mBlockers.size()) - ob.first;
        if (ob.count > 0) {
            std::vector<Box3> boxes(ob.count);
            for (int b = 0; b < ob.count; ++b)
                boxes[b] = Box3{mBlockers[ob.first + b].lo, mBlockers[ob.first + b].hi};
            ob.tree.build(boxes);
            // The object's blockers in tree order, so that a pyramid's candidates are read
            // front to back (those with an empty box, never visited, go last).
            const std::vector<int>& order = ob.tree.items();
            std::vector<Blocker> sorted;
            sorted.reserve(ob.count);
            std::vector<char> taken(ob.count, 0);
            for (int b : order) {
                sorted.push_back(std::move(mBlockers[ob.first + b]));
                taken[b] = 1;
            }
            for (int b = 0; b < ob.count; ++b)
                if (!taken[b]) sorted.push_back(std::move(mBlockers[ob.first + b]));
            std::move(sorted.begin(), sorted.end(), mBlockers.begin() + ob.first);
            sceneLo = glm::min(sceneLo, ob.lo);
            sceneHi = glm::max(sceneHi, ob.hi);
            mObjects.push_back(std::move(ob));
        }
    }
    // An element's near radius: its bounding radius about the centroid, but no more than
    // 1.5 √area, so that a sliver (a thin pole's side split along its length) reaches as far
    // as the solid angle it subtends, not as far as its length.
    mElementRadius.assign(elements.size(), 0.0);
    for (std::size_t e = 0; e < elements.size(); ++e) {
        if (!mDisc.elementAlive(static_cast<int>(e))) continue;
        for (const Vec3& p : mDisc.elementPolygon(static_cast<int>(e)))
            mElementRadius[e] = std::max(mElementRadius[e], glm::length(p - elements[e].centroid));
        mElementRadius[e] = std::min(mElementRadius[e], 1.5 * std::sqrt(elements[e].area));
    }
    // The near-patch grid.
    mCellSize = 0;
    for (const SourcePatch& sp : mPatches)
        mCellSize = std::max(mCellSize, nearPatchRadii() * sp.radius);
    mCellSize = std::max(mCellSize, 1e-6);
    mPatchCells.clear();
    for (std::size_t i = 0; i < mPatches.size(); ++i) {
        const Vec3 c = mPatches[i].centroid / mCellSize;
        mPatchCells[cellKey(std::llround(std::floor(c.x)), std::llround(std::floor(c.y)),
                            std::llround(std::floor(c.z)))]
            .push_back(static_cast<int>(i));
    }
    buildElementCells();
    const double diag = mObjects.empty() ? 1.0 : glm::length(sceneHi - sceneLo);
    mEpsilon = 1e-9 * std::max(diag, 1e-6);
    if (!mReflected.empty()) setReflected(std::move(mReflected));
}

void ExactIrradiance::buildElementCells() {
    mElementCells.clear();
    mNearBall.clear();
    mElementPolygon.clear();
    const double k = mOptions.nearElementRadii;
    if (!(k > 0)) return;
    std::vector<int> sources;
    for (const SourcePatch& sp : mPatches)
        for (int e : mDisc.patches()[sp.patch].elements) sources.push_back(e);
    mNearBall.resize(mDisc.elements().size());
    for (std::size_t e = 0; e < mNearBall.size(); ++e)
        mNearBall[e] = {mDisc.elements()[e].centroid, k * mElementRadius[e]};
    if (sources.empty()) return;
    mElementPolygon.resize(mDisc.elements().size());
    for (int e : sources) mElementPolygon[e] = mDisc.elementPolygon(e);
    // Cells about the size of most near balls (the third quartile), so a ball covers a few
    // cells; no smaller than an eighth of the largest, so no ball covers more than 17 a side.
    std::vector<double> reach;
    for (int e : sources) reach.push_back(k * mElementRadius[e]);
    const double largest = *std::max_element(reach.begin(), reach.end());
    std::nth_element(reach.begin(), reach.begin() + reach.size() * 3 / 4, reach.end());
    mElementCellSize = std::max({reach[reach.size() * 3 / 4], largest / 8, 1e-6});
    for (int e : sources) {
        const Vec3 c = mDisc.elements()[e].centroid;
        const double r = k * mElementRadius[e];
        const Vec3 lo = glm::floor((c - r) / mElementCellSize),
                   hi = glm::floor((c + r) / mElementCellSize);
        for (long long i = std::llround(lo.x); i <= std::llround(hi.x); ++i)
            for (long long j = std::llround(lo.y); j <= std::llround(hi.y); ++j)
                for (long long m = std::llround(lo.z); m <= std::llround(hi.z); ++m)
                    mElementCells[cellKey(i, j, m)].push_back(e);
    }
}

void ExactIrradiance::setReflected(std::vector<Rgb> reflected) {
    mReflected = std::move(reflected);
    mReflected.resize(mDisc.elements().size(), Rgb(0.0));
    mPatchReflected.assign(mDisc.patches().size(), Rgb(0.0));
    for (std::size_t p = 0; p < mDisc.patches().size(); ++p) {
        const Patch& P = mDisc.patches()[p];
        Rgb sum(0.0);
        double area = 0;
        for (int e : P.elements) {
            sum += mReflected[e] * mDisc.elements()[e].area;
            area += mDisc.elements()[e].area;
        }
        mPatchReflected[p] = area > 0 ? sum / area : Rgb(0.0);
    }
}

std::vector<std::vector<Vec3>> ExactIrradiance::visiblePart(const Vec3& x,
                                                            const std::vector<Vec3>& source,
                                                            int ignoreObject) const {
    bool tooMany = false;
    return clipVisible(x, source, ignoreObject, 0, tooMany);
}

std::vector<std::vector<Vec3>> ExactIrradiance::clipVisible(const Vec3& x,
                                                            const std::vector<Vec3>& source,
                                                            int ignoreObject, int maxBlockers,
                                                            bool& tooMany) const {
    tooMany = false;
    int reaching = 0;
    std::vector<std::vector<Vec3>> out;
    if (source.size() < 3) return out;
    const PlaneFrame frame(source);
    const double hx = glm::dot(x - frame.origin, frame.n);
    if (!(hx > mEpsilon)) return out;  // behind the source (or on its plane): sees nothing
    // Scratch kept per thread: a point's sources call this many times.
    thread_local std::vector<Vec2> source2;
    thread_local std::vector<Vec3> sideNormal, clipA, clipB;
    thread_local std::vector<Vec2> shadow;
    thread_local std::vector<std::vector<Vec2>> shadows;
    thread_local std::vector<int> candidates;
    source2.clear();
    for (const Vec3& p : source) source2.push_back(frame.to2(p));
    PolygonSet2 visible(source2);
    if (visible.empty()) return out;

    // The pyramid from x over the source: side planes through x and each edge (normals
    // pointing inward) and the source's plane, slightly lifted so the source's own surface and
    // anything on its plane do not count as blockers.
    const std::size_t n = source.size();
    sideNormal.assign(n, Vec3(0.0));
    Vec3 centroid(0.0);
    for (const Vec3& p : source) centroid += p;
    centroid /= static_cast<double>(n);
    for (std::size_t i = 0; i < n; ++i) {
        Vec3 m = glm::cross(source[i] - x, source[(i + 1) % n] - x);
        if (glm::dot(m, centroid - x) < 0) m = -m;
        const double len = glm::length(m);
        sideNormal[i] = len > 0 ? m / len : m;
    }
    Vec3 lo = x, hi = x;
    for (const Vec3& p : source) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    // A box meets the pyramid only if it meets the pyramid's box and no face plane of the
    // pyramid has the whole box outside (the plane's largest value over the box < 0).
    auto boxOverlaps = [&](const Vec3& a, const Vec3& b) {
        if (!(a.x <= hi.x && lo.x <= b.x && a.y <= hi.y && lo.y <= b.y && a.z <= hi.z &&
              lo.z <= b.z))
            return false;
        const Vec3 centre = 0.5 * (a + b), half = 0.5 * (b - a);
        auto outside = [&](const Vec3& m, const Vec3& through) {
            return glm::dot(centre - through, m) + std::abs(m.x) * half.x + std::abs(m.y) * half.y +
                       std::abs(m.z) * half.z <
                   0;
        };
        if (outside(frame.n, frame.origin)) return false;  // behind the source's plane
        for (std::size_t i = 0; i < n; ++i)
            if (outside(sideNormal[i], x)) return false;
        return true;
    };
    const double lift = 1e3 * mEpsilon;
    // The pyramid's planes, positive inside: its base and its i-th side.
    auto base = [&](const Vec3& p) { return glm::dot(p - frame.origin, frame.n) - lift; };
    auto side = [&](std::size_t i) {
        return [&, i](const Vec3& p) { return glm::dot(p - x, sideNormal[i]); };
    };
    // A polygon with every corner strictly outside one of the pyramid's planes is clipped
    // away whole: tested on its corners first, without clipping.
    auto outsidePyramid = [&](const std::vector<Vec3>& polygon) {
        auto allBelow = [&](auto plane) {
            for (const Vec3& p : polygon)
                if (!(plane(p) < 0)) return false;
            return true;
        };
        if (allBelow(base)) return true;
        for (std::size_t i = 0; i < n; ++i)
            if (allBelow(side(i))) return true;
        return false;
    };
    std::size_t shadowCount = 0;
    for (const ObjectBlockers& ob : mObjects) {
        if (ob.object == ignoreObject || !boxOverlaps(ob.lo, ob.hi)) continue;
        // The blockers whose boxes meet the pyramid's, through the object's box tree.
        candidates.clear();
        ob.tree.visitLeaves([&](const Box3& box) { return boxOverlaps(box.lo, box.hi); },
                            [&](int begin, int end) {
                                for (int k = begin; k < end; ++k) candidates.push_back(k);
                            });
        for (int b : candidates) {
            if (visible.empty()) break;
            const Blocker& B = mBlockers[ob.first + b];
            if (!boxOverlaps(B.lo, B.hi)) continue;
            // A polygon whose plane passes through x cannot hide anything from x.
            if (std::abs(glm::dot(x - B.polygon[0], B.normal)) <= lift) continue;
            if (outsidePyramid(B.polygon)) continue;
            clipConvex(B.polygon, base, clipA);
            for (std::size_t i = 0; i < n && !clipA.empty(); ++i) {
                clipConvex(clipA, side(i), clipB);
                clipA.swap(clipB);
            }
            if (clipA.size() < 3) continue;
            if (maxBlockers > 0 && ++reaching > maxBlockers) {
                tooMany = true;
                return {};
            }
            // Central projection from x onto the source's plane.
            shadow.clear();
            for (const Vec3& p : clipA) {
                const double hp = glm::dot(p - frame.origin, frame.n);
                const Vec3 q = x + (p - x) * (hx / (hx - hp));
                shadow.push_back(frame.to2(q));
            }
            // With a limit, the shadows are subtracted once all are known to be within it:
            // a source given up on costs no subtraction.
            if (maxBlockers > 0) {
                if (shadows.size() <= shadowCount) shadows.emplace_back();
                shadows[shadowCount++] = shadow;
            } else {
                visible.subtract(shadow);
            }
        }
    }
    for (std::size_t k = 0; k < shadowCount && !visible.empty(); ++k) visible.subtract(shadows[k]);
    out.reserve(visible.pieces().size());
    for (const auto& piece : visible.pieces()) {
        std::vector<Vec3> poly;
        poly.reserve(piece.size());
        for (const Vec2& p : piece) poly.push_back(frame.to3(p));
        out.push_back(std::move(poly));
    }
    return out;
}

double ExactIrradiance::visibleFormFactor(const Vec3& x, const Vec3& n,
                                          const std::vector<Vec3>& source, int ignoreObject) const {
    bool sampled = false;
    return formFactor(x, n, source, ignoreObject, sampled);
}

void ExactIrradiance::addSource(const Vec3& x, const Vec3& n, const std::vector<Vec3>& source,
                                const Rgb& radiosity, Parts& parts) const {
    bool sampled = false;
    parts.gathered += radiosity * formFactor(x, n, source, -1, sampled);
}

double ExactIrradiance::formFactor(const Vec3& x, const Vec3& n, const std::vector<Vec3>& source,
                                   int ignoreObject, bool& sampled) const {
    sampled = false;
    // Unoccluded first: a source the point cannot see (behind it or below its horizon) costs
    // no clipping.
    const double unoccluded = polygonFormFactor(x, n, source);
    if (!(unoccluded > 0)) return 0.0;
    const int limit = mTracer ? mOptions.maxExactBlockers : 0;
    bool tooMany = false;
    const auto pieces = clipVisible(x, source, ignoreObject, limit, tooMany);
    if (tooMany) {
        sampled = true;
        return unoccluded * sampledVisibleFraction(x, n, source);
    }
    double f = 0;
    for (const auto& piece : pieces) f += polygonFormFactor(x, n, piece);
    return std::clamp(f, 0.0, unoccluded);
}

double ExactIrradiance::sampledVisibleFraction(const Vec3& x, const Vec3& n,
                                               const std::vector<Vec3>& source) const {
    // Fan triangles by area; stratified in the area-cumulative coordinate.
    std::vector<double> cumulative;
    double total = 0;
    for (std::size_t k = 1; k + 1 < source.size(); ++k) {
        total += 0.5 * glm::length(glm::cross(source[k] - source[0], source[k + 1] - source[0]));
        cumulative.push_back(total);
    }
    if (!(total > 0)) return 0.0;
    const Vec3 sn = unitNormal(source);
    // The same points of the source for every x: the estimate then changes with x only where
    // a ray's blocker changes, smoothly enough for the interpolants and their refinement test
    // (independent patterns would put noise between neighbouring samples).
    std::uint64_t state = 0;
    for (double c : {source[0].x, source[0].y, source[0].z, source[1].x, source[1].y, source[1].z})
        state = hashPair(state, static_cast<std::uint64_t>(std::llround(c * 1e9)));
    SplitMix random(state);
    const double eps = mTracer->epsilon();
    const Vec3 from = x + eps * n;
    const int m = std::max(1, mOptions.blockedRays);
    // The points and their weights first, then their shadow rays in packets of 16: the rays
    // share their start and reach one polygon, the coherent case Embree's packets are for.
    thread_local std::vector<Vec3> targets;
    thread_local std::vector<double> weights;
    targets.clear();
    weights.clear();
    double all = 0;
    for (int i = 0; i < m; ++i) {
        const double u = (i + random.next()) / m * total;
        const std::size_t k = std::min<std::size_t>(
            std::upper_bound(cumulative.begin(), cumulative.end(), u) - cumulative.begin(),
            cumulative.size() - 1);
        double r0 = random.next(), r1 = random.next();
        if (r0 + r1 > 1) r0 = 1 - r0, r1 = 1 - r1;
        const Vec3 y =
            source[0] + r0 * (source[k + 1] - source[0]) + r1 * (source[k + 2] - source[0]);
        const Vec3 d = y - x;
        const double r2 = glm::dot(d, d);
        const double w =
            std::max(0.0, glm::dot(n, d)) * std::max(0.0, -glm::dot(sn, d)) / (r2 * r2);
        if (!(w > 0)) continue;
        all += w;
        targets.push_back(y + eps * sn);
        weights.push_back(w);
    }
    double seen = 0;
    const int count = static_cast<int>(targets.size());
    for (int first = 0; first < count; first += 16) {
        const int width = std::min(16, count - first);
        bool blocked[16];
        mTracer->occludedPacket(from, targets.data() + first, width, blocked);
        for (int i = 0; i < width; ++i)
            if (!blocked[i]) seen += weights[std::size_t(first + i)];
    }
    return all > 0 ? seen / all : 0.0;
}

Rgb ExactIrradiance::direct(const Vec3& x, const Vec3& n) const {
    Parts parts;
    addDirect(x, n, parts);
    return parts.total();
}

void ExactIrradiance::addDirect(const Vec3& x, const Vec3& n, Parts& parts) const {
    // A planar emitter cannot hide itself; a curved one (a sphere lamp) can: no object is
    // left out of the blockers.
    for (const Source& s : mEmitters) addSource(x, n, s.polygon, s.radiosity, parts);
}

void ExactIrradiance::addSourcesOfPatch(const SourcePatch& sp, const Vec3& x,
                                        std::vector<Source>& out) const {
    const Patch& P = mDisc.patches()[sp.patch];
    const bool far = glm::length(x - sp.centroid) > mOptions.nearRadii * sp.radius;
    if (far && sp.convexOutline) {
        const Rgb b = mPatchReflected[sp.patch];
        if (b.x > 0 || b.y > 0 || b.z > 0) out.push_back({P.outline, b, P.object});
        return;
    }
    for (int e : P.elements) {
        const Rgb b = mReflected[e];
        if (b.x > 0 || b.y > 0 || b.z > 0) out.push_back({mDisc.elementPolygon(e), b, P.object});
    }
}

std::uint64_t ExactIrradiance::cellKey(long long i, long long j, long long k) const {
    return hashPair(hashPair(static_cast<std::uint64_t>(i), static_cast<std::uint64_t>(j)),
                    static_cast<std::uint64_t>(k));
}

bool ExactIrradiance::nearPatch(int patch, const Vec3& x) const {
    const Patch& P = mDisc.patches()[patch];
    return glm::length(x - P.centroid) <= nearPatchRadii() * P.radius;
}

bool ExactIrradiance::nearElement(int element, const Vec3& x) const {
    const NearBall& ball = mNearBall[element];
    return glm::length(x - ball.centre) <= ball.reach;
}

double ExactIrradiance::nearElementWeight(int element, const Vec3& x) const {
    if (!mOptions.smoothFarField) return nearElement(element, x) ? 1.0 : 0.0;
    const NearBall& ball = mNearBall[element];
    const Vec3 dx = x - ball.centre;
    const double d2 = glm::dot(dx, dx), reach = ball.reach;
    if (d2 >= reach * reach) return 0.0;
    const double d = std::sqrt(d2);
    if (d <= 0.5 * reach) return 1.0;
    const double u = 2 * (reach - d) / reach;  // 1 at half the reach, 0 at the reach
    return u * u * (3 - 2 * u);
}

Rgb ExactIrradiance::indirect(const Vec3& x, const Vec3& n) const {
    if (mReflected.empty()) return Rgb(0.0);
    Parts parts;
    addGathered(x, n, parts);
    if (sampledFarField()) addFarField(x, n, 1, parts);
    return parts.total();
}

ExactIrradiance::Parts ExactIrradiance::irradianceParts(const Vec3& x, const Vec3& n,
                                                        bool withFarField) const {
    Parts parts;
    addDirect(x, n, parts);
    if (!mOptions.indirect || mReflected.empty()) return parts;
    addGathered(x, n, parts);
    if (withFarField && sampledFarField()) addFarField(x, n, 1, parts);
    return parts;
}

void ExactIrradiance::addGathered(const Vec3& x, const Vec3& n, Parts& parts) const {
    if (mReflected.empty()) return;
    std::vector<Source> sources;
    auto gather = [&](const SourcePatch& sp) {
        sources.clear();
        addSourcesOfPatch(sp, x, sources);
        for (const Source& s : sources) addSource(x, n, s.polygon, s.radiosity, parts);
    };
    if (!sampledFarField()) {
        for (const SourcePatch& sp : mPatches) gather(sp);
        return;
    }
    if (mOptions.nearElementRadii > 0) {
        // Element by element: those whose near ball holds x are listed in x's cell.
        const Vec3 c = glm::floor(x / mElementCellSize);
        const auto it =
            mElementCells.find(cellKey(std::llround(c.x), std::llround(c.y), std::llround(c.z)));
        if (it == mElementCells.end()) return;
        for (int e : it->second) {
            const double w = nearElementWeight(e, x);
            if (!(w > 0)) continue;
            const Element& el = mDisc.elements()[e];
            if (glm::dot(el.normal, n) < 1 - 1e-9 ||
                std::abs(glm::dot(el.centroid - x, n)) > 1e3 * mEpsilon)
                parts.nearSurface = true;
            const Rgb b = mReflected[e];
            if (!(b.x > 0 || b.y > 0 || b.z > 0)) continue;
            // x on the element's plane or behind it sees none of its front (clipVisible's own
            // test, on the centroid): no form factor to compute.
            if (glm::dot(x - el.centroid, el.normal) <= 0.5 * mEpsilon) continue;
            bool sampled = false;
            const double f = formFactor(x, n, mElementPolygon[e], -1, sampled);
            parts.gathered += w * f * b;
            parts.nearIndirect += w * f * b;
            parts.nearShare += w * f;
        }
        return;
    }
    const Vec3 c = x / mCellSize;
    const long long ci = std::llround(std::floor(c.x)), cj = std::llround(std::floor(c.y)),
                    ck = std::llround(std::floor(c.z));
    for (long long i = ci - 1; i <= ci + 1; ++i)
        for (long long j = cj - 1; j <= cj + 1; ++j)
            for (long long k = ck - 1; k <= ck + 1; ++k) {
                const auto it = mPatchCells.find(cellKey(i, j, k));
                if (it == mPatchCells.end()) continue;
                for (int p : it->second)
                    if (nearPatch(mPatches[p].patch, x)) gather(mPatches[p]);
            }
}

void ExactIrradiance::refineFarField(const Vec3& x, const Vec3& n, int passes, Parts& parts) const {
    if (!sampledFarField() || mReflected.empty() || parts.farPasses >= passes) return;
    addFarField(x, n, passes, parts);
}

int ExactIrradiance::previewFarField(const Vec3& x, const Vec3& n, int rays, Parts& parts) const {
    if (!sampledFarField() || mReflected.empty()) return 0;
    Parts preview = parts;
    preview.farField = Rgb(0.0);
    preview.farError = 0;
    preview.farRays = preview.farPasses = 0;
    addFarField(x, n, 1, preview, std::max(1, rays));
    parts.farField = preview.farField;
    parts.farError = preview.farError;
    parts.farRays = parts.farPasses = 0;
    return preview.farRays;
}

void ExactIrradiance::addFarField(const Vec3& x, const Vec3& n, int passes, Parts& parts,
                                  int perPass) const {
    // Each point's jitter is its own, seeded by its position, so that its value is
    // reproducible and neighbouring points' errors are independent (they average out where
    // the build pools them).
    std::uint64_t seed = 0;
    for (double c : {x.x, x.y, x.z})
        seed = hashPair(seed, static_cast<std::uint64_t>(std::llround(c * 1e9)));
    const Vec3 origin = x + mTracer->epsilon() * n;
    FarFieldRays plan;
    plan.perPass = perPass > 0 ? perPass : mOptions.farRays;
    plan.maxPasses = passes;
    FarFieldEstimate from;
    from.value = parts.farField;
    from.standardError = parts.farError;
    from.rays = parts.farRays;
    from.passes = parts.farPasses;
    // E = ∫ (B/π) cos dω: the mean over cosine-distributed rays of what they read. No
    // tolerance: the passes run to `passes` unless one leaves no error (the build's
    // refinement picks the points by their error).
    // A pass's rays traced together, in the ray tracer's packets: they share their origin.
    const FarFieldEstimate far = estimateFarFieldBatched(
        n, seed, plan, 0,
        [&](const Vec3* dirs, int count, Rgb* out) {
            thread_local std::vector<Vec3> origins;
            thread_local std::vector<RayTracer::FirstHit> hits;
            origins.assign(std::size_t(count), origin);
            hits.resize(std::size_t(count));
            mTracer->firstHits(origins.data(), dirs, count, hits.data());
            for (int k = 0; k < count; ++k) {
                const RayTracer::FirstHit& hit = hits[std::size_t(k)];
                out[k] = Rgb(0.0);
                if (hit.element < 0 || hit.backFace) continue;
                if (mOptions.nearElementRadii > 0) {
                    // What the exact part leaves of the element.
                    const double w = nearElementWeight(hit.element, x);
                    if (w < 1) out[k] = (1 - w) * mReflected[hit.element];
                } else if (!nearPatch(hit.patch, x)) {
                    out[k] = mReflected[hit.element];
                }
            }
        },
        &from);
    parts.farField = far.value;
    parts.farError = far.standardError;
    parts.farRays = far.rays;
    parts.farPasses = far.passes;
}

std::vector<Rgb> reflectedRadiosity(const Discretization& disc, const ProgressiveSolver& solver) {
    return reflectedRadiosity(disc, solver.displayRadiosity());
}

std::vector<Rgb> reflectedRadiosity(const Discretization& disc, const std::vector<Rgb>& b) {
    std::vector<Rgb> out(b.size());
    for (std::size_t e = 0; e < b.size(); ++e)
        out[e] = glm::max(b[e] - disc.elementMaterial(static_cast<int>(e)).emission, Rgb(0.0));
    return out;
}

namespace {

/// The alive objects of `d` by id.
std::unordered_map<std::string, int> aliveObjectsById(const Discretization& d) {
    std::unordered_map<std::string, int> byId;
    for (std::size_t o = 0; o < d.objects().size(); ++o)
        if (d.objects()[o].alive) byId.emplace(d.objects()[o].id, static_cast<int>(o));
    return byId;
}

/// Per element of `disc`, its twin among the leaf solve's elements: the same face of the alive
/// object of the same id, at the same place (-1: none, as for an element adaptive subdivision
/// made). PatchGrouping keeps the front faces' order, and a back-sheet face is found through
/// its front face's twin (ObjectSurface::faceTwin), so a discretization of the same scene has
/// one.
std::vector<int> twinElements(const Discretization& disc, const Discretization& leaves) {
    const std::unordered_map<std::string, int> leafObject = aliveObjectsById(leaves);
    std::vector<int> twin(disc.elements().size(), -1);
    for (const ObjectSurface& s : disc.objects()) {
        const auto it = leafObject.find(s.id);
        if (!s.alive || it == leafObject.end()) continue;
        const ObjectSurface& t = leaves.objects()[it->second];
        // Face f of s as a face of t (-1: none).
        auto leafFace = [&](int f) {
            if (!s.isBackFace(f)) return f < t.firstBackFace ? f : -1;
            const int front = f < static_cast<int>(s.faceTwin.size()) ? s.faceTwin[f] : -1;
            return front >= 0 && front < static_cast<int>(t.faceTwin.size()) ? t.faceTwin[front]
                                                                             : -1;
        };
        for (int f = 0; f < static_cast<int>(s.faceElement.size()); ++f) {
            const int lf = leafFace(f);
            if (lf < 0 || lf >= static_cast<int>(t.faceElement.size())) continue;
            const int e = s.faceElement[f], g = t.faceElement[lf];
            if (e < 0 || g < 0) continue;
            const Element& a = disc.elements()[e];
            const Element& b = leaves.elements()[g];
            const double tol = 1e-9 * (1 + glm::length(a.centroid));
            if (glm::length(a.centroid - b.centroid) <= tol &&
                std::abs(a.area - b.area) <= 1e-9 * a.area &&
                glm::dot(a.normal, b.normal) > 1 - 1e-9)
                twin[e] = g;
        }
    }
    return twin;
}

/// An element's polygon and its radius about its centroid.
struct ElementShape {
    std::vector<Vec3> polygon;
    double radius = 0;
    ElementShape() = default;
    ElementShape(const Discretization& d, int e) : polygon(d.elementPolygon(e)) {
        for (const Vec3& p : polygon)
            radius = std::max(radius, glm::length(p - d.elements()[e].centroid));
    }
};

/// The leaf solve's elements by object and grid cell of their centroids, for carrying their
/// radiosity to elements they are not twins of.
class LeafOverlaps {
public:
    /// Cells at least as wide as `minCell` and every leaf's radius, so a polygon no wider than
    /// that meets only leaves of the 5 × 5 × 5 cells about its centroid's.
    LeafOverlaps(const Discretization& leaves, double minCell) : mLeaves(leaves) {
        mCell = std::max(minCell, 1e-9);
        mShapes.resize(leaves.elements().size());
        for (int g = 0; g < static_cast<int>(mShapes.size()); ++g) {
            if (!leaves.elementAlive(g)) continue;
            mShapes[g] = ElementShape(leaves, g);
            mCell = std::max(mCell, mShapes[g].radius);
        }
        for (int g = 0; g < static_cast<int>(mShapes.size()); ++g)
            if (leaves.elementAlive(g))
                mCells[cellOf(leaves.elements()[g].object, leaves.elements()[g].centroid)]
                    .push_back(g);
    }

    /// The mean of `value` over the leaves of leaf object `object` that face `el`'s way and
    /// overlap `shape` (its polygon), each weighted by the area of its polygon inside the
    /// element's prism, measured in the element's plane — the projection of the leaves'
    /// piecewise-constant radiosity onto the element. Of leaves stacked over one another (a
    /// thin slab's faces) only the layer nearest the element's plane counts. Where none
    /// overlaps (a sliver), the nearest such leaf's; `out` stays as it is where there is none.
    void mean(int object, const Element& el, const ElementShape& shape,
              const std::vector<Rgb>& value, Rgb& out) const {
        const std::vector<Vec3>& poly = shape.polygon;
        const std::size_t n = poly.size();
        std::vector<Vec3> inward(n);  // the prism's sides, inward
        for (std::size_t i = 0; i < n; ++i)
            inward[i] = glm::cross(el.normal, poly[(i + 1) % n] - poly[i]);
        struct Overlap {
            int leaf;
            double area, height;  ///< twice its area; its mean distance from the plane
        };
        std::vector<Overlap> overlaps;
        std::vector<Vec3> clipA, clipB;
        double nearest2 = HUGE_VAL;
        int nearest = -1;
        const auto [o, ci, cj, ck] = cellOf(object, el.centroid);
        for (long long di = -2; di <= 2; ++di)
            for (long long dj = -2; dj <= 2; ++dj)
                for (long long dk = -2; dk <= 2; ++dk) {
                    const auto it = mCells.find(Key(o, ci + di, cj + dj, ck + dk));
                    if (it == mCells.end()) continue;
                    for (int g : it->second) {
                        // Facing the element's way (not a back sheet or another side of a
                        // box), and about on its plane.
                        const Element& f = mLeaves.elements()[g];
                        const double reach = shape.radius + mShapes[g].radius;
                        const Vec3 d = f.centroid - el.centroid;
                        if (glm::dot(f.normal, el.normal) < 0.5 || glm::dot(d, d) > reach * reach ||
                            std::abs(glm::dot(d, el.normal)) > 0.25 * reach)
                            continue;
                        if (glm::dot(d, d) < nearest2) nearest2 = glm::dot(d, d), nearest = g;
                        clipA = mShapes[g].polygon;
                        for (std::size_t i = 0; i < n && !clipA.empty(); ++i) {
                            clipConvex(
                                clipA,
                                [&](const Vec3& p) { return glm::dot(p - poly[i], inward[i]); },
                                clipB);
                            clipA.swap(clipB);
                        }
                        if (clipA.empty()) continue;
                        double height = 0;
                        for (const Vec3& p : clipA)
                            height += std::abs(glm::dot(p - el.centroid, el.normal));
                        overlaps.push_back({g, std::abs(glm::dot(newellNormal(clipA), el.normal)),
                                            height / static_cast<double>(clipA.size())});
                    }
                }
        double lowest = HUGE_VAL;
        for (const Overlap& v : overlaps)
            if (v.area > 0) lowest = std::min(lowest, v.height);
        Rgb sum(0.0);
        double weight = 0;
        for (const Overlap& v : overlaps)
            if (v.area > 0 && v.height <= lowest + 0.1 * shape.radius) {
                sum += v.area * value[v.leaf];
                weight += v.area;
            }
        if (weight > 0)
            out = sum / weight;
        else if (nearest >= 0)
            out = value[nearest];
    }

private:
    using Key = std::tuple<int, long long, long long, long long>;
    Key cellOf(int object, const Vec3& c) const {
        const Vec3 q = glm::floor(c / mCell);
        return Key(object, std::llround(q.x), std::llround(q.y), std::llround(q.z));
    }

    const Discretization& mLeaves;
    double mCell = 0;
    std::vector<ElementShape> mShapes;  ///< per leaf (empty for dead ones)
    std::map<Key, std::vector<int>> mCells;
};

/// Gives each alive element of `disc` without a twin (`twin` < 0) the leaf solve's radiosity
/// averaged over it (LeafOverlaps::mean); one whose object has no leaves keeps its value in
/// `out`.
void carryOverlappingLeaves(const Discretization& disc, const Discretization& leaves,
                            const std::vector<int>& twin, const std::vector<Rgb>& leafValue,
                            std::vector<Rgb>& out) {
    std::vector<int> orphans;
    for (std::size_t e = 0; e < disc.elements().size(); ++e)
        if (twin[e] < 0 && disc.elementAlive(static_cast<int>(e)))
            orphans.push_back(static_cast<int>(e));
    if (orphans.empty()) return;
    std::vector<ElementShape> shapes;
    double widest = 0;
    for (int e : orphans) {
        shapes.emplace_back(disc, e);
        widest = std::max(widest, shapes.back().radius);
    }
    const LeafOverlaps overlaps(leaves, widest);
    const std::unordered_map<std::string, int> leafObject = aliveObjectsById(leaves);
    tbb::parallel_for(std::size_t(0), orphans.size(), [&](std::size_t k) {
        const Element& el = disc.elements()[orphans[k]];
        const auto object = leafObject.find(disc.objects()[el.object].id);
        if (object != leafObject.end())
            overlaps.mean(object->second, el, shapes[k], leafValue, out[orphans[k]]);
    });
}

/// The leaf solve: `disc`'s elements' reflected radiosity from a solve of `scene` in which every
/// element shoots, with receivers in the open. With `solved`, returns its reflected radiosity
/// instead when that solve would be the same one (patches already elements, no receiver
/// moved). `stats` (optional) receives the leaf solve's stats and unshot fraction.
std::vector<Rgb> solveLeaves(const Scene& scene, const Discretization& disc,
                             const ProgressiveSolver* solved, const SolverOptions& options,
                             double eps, std::uint64_t maxShots, LeafSolveStats* stats,
                             const std::function<void(double)>& progress) {
    std::vector<Rgb> out =
        solved ? reflectedRadiosity(disc, *solved) : std::vector<Rgb>(disc.elements().size());
    // The scene's own elements, each its own shooter.
    Discretization leaves(scene, PatchGrouping::Elements);
    RayTracer tracer(leaves);
    // Receivers in the open (SolverOptions::placeReceivers): with patches already elements
    // (grouped as the leaves are), the solve is needed only when some receiver moves.
    if (leaves.placeReceivers(tracer) == 0 &&
        scene.settings.patchSize <= scene.settings.elementSize && solved) {
        if (stats) *stats = {solved->stats(), solved->unshotFraction()};
        return out;
    }
    // Receivers are placed already: the solver need not place them again.
    SolverOptions leafOptions = options;
    leafOptions.placeReceivers = false;
    ProgressiveSolver solver(leaves, tracer, leafOptions);
    solver.converge(eps, maxShots, progress);
    if (stats) *stats = {solver.stats(), solver.unshotFraction()};
    const std::vector<Rgb> leafReflected = reflectedRadiosity(leaves, solver);
    // Each element takes its twin's value; one adaptive subdivision made takes the leaves'
    // that overlap it.
    const std::vector<int> twin = twinElements(disc, leaves);
    for (std::size_t e = 0; e < disc.elements().size(); ++e)
        if (twin[e] >= 0) out[e] = leafReflected[twin[e]];
    carryOverlappingLeaves(disc, leaves, twin, leafReflected, out);
    return out;
}

}  // namespace

std::vector<Rgb> leafReflectedRadiosity(const Scene& scene, const Discretization& disc,
                                        const ProgressiveSolver& solved,
                                        const SolverOptions& options, double eps,
                                        std::uint64_t maxShots) {
    return solveLeaves(scene, disc, &solved, options, eps, maxShots, nullptr, {});
}

std::vector<Rgb> leafReflectedRadiosity(const Scene& scene, const Discretization& disc,
                                        const SolverOptions& options, double eps,
                                        std::uint64_t maxShots, LeafSolveStats* stats,
                                        const std::function<void(double)>& progress) {
    return solveLeaves(scene, disc, nullptr, options, eps, maxShots, stats, progress);
}

std::string ExactIrradiance::toString() const {
    std::ostringstream s;
    s << "ExactIrradiance{blockers=" << mBlockers.size() << ", emitters=" << mEmitters.size()
      << ", sources=" << mPatches.size() << ", indirect=" << (mReflected.empty() ? "no" : "yes")
      << "}";
    return s.str();
}

}  // namespace penumbra
