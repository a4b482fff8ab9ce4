// HifiMesh (see hifi_mesh.h): meshing and sampling each element, assembling a build's or an
// update's triangles, locating and rendering them. The discontinuities that cross an element
// (shadow events, contact lines) are found in hifi_discontinuities.cpp.
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

#include "render/camera_rays.h"
#include "render/hifi/cdt.h"
#include "render/hifi/exact_irradiance.h"
#include "render/hifi/hifi_mesh_internal.h"
#include "render/hifi/hifi_samples.h"
#include "solver/discretization.h"
#include "solver/ray_tracer.h"

namespace penumbra {

using namespace hifi_detail;

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
