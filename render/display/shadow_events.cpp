// Index: Light, ShadowEvent · findShadowEvents (point lights, appendix A VE/EV, concave
//        culling) · EventFrame · eventRange, eventBounds · ReceiverTree (build, intersect) ·
//        EventCoverage · clipEvent (§6.5)
#include "render/display/shadow_events.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>
#include <unordered_set>

namespace penumbra {

namespace {

Vec3 apply(const Mat4& m, const Vec3& p) { return Vec3(m * glm::dvec4(p, 1.0)); }

int signOf(double v, double eps) { return v > eps ? 1 : v < -eps ? -1 : 0; }

std::string str(const Vec3& v) {
    std::ostringstream s;
    s << '(' << v.x << ' ' << v.y << ' ' << v.z << ')';
    return s.str();
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Light, ShadowEvent

std::string Light::toString() const {
    std::ostringstream s;
    s << "Light{" << (isPoint() ? "point" : "polygon") << ", object " << object << ",";
    for (const Vec3& p : polygon) s << ' ' << str(p);
    s << '}';
    return s.str();
}

const char* shadowKindName(ShadowKind kind) {
    switch (kind) {
        case ShadowKind::Hard:
            return "hard";
        case ShadowKind::Umbra:
            return "umbra";
        case ShadowKind::Penumbra:
            return "penumbra";
    }
    return "?";
}

ShadowEvent ShadowEvent::mapped(const Mat4& m) const {
    ShadowEvent e = *this;
    e.p0 = apply(m, p0);
    e.p1 = apply(m, p1);
    e.q0 = apply(m, q0);
    e.q1 = apply(m, q1);
    return e;
}

std::string ShadowEvent::toString() const {
    std::ostringstream s;
    s << "ShadowEvent{" << (vertexEdge ? "VE" : "EV") << ' ' << shadowKindName(kind) << ", light "
      << lightFeature << ", blocker " << blockerFeature << ", P " << str(p0) << '-' << str(p1)
      << ", Q " << str(q0) << '-' << str(q1) << '}';
    return s.str();
}

// ---------------------------------------------------------------------------------------------
// findShadowEvents

bool isConcaveEdge(const EdgeMesh& mesh, int edge) {
    const MeshEdge& e = mesh.edges()[edge];
    if (e.f1 < 0) return false;
    const FacePlane& p0 = mesh.facePlanes()[e.f0];
    double best = 0;
    for (int j = mesh.faceStart()[e.f1]; j < mesh.faceStart()[e.f1 + 1]; ++j) {
        double d = p0.eval(mesh.positions()[mesh.faceVertices()[j]]);
        if (std::abs(d) > std::abs(best)) best = d;
    }
    // Clearly concave (not nearly flat), and not folded back into a knife-thin fin whose
    // inside the event would cross only within rounding of the edge.
    double len = glm::length(mesh.positions()[e.v1] - mesh.positions()[e.v0]);
    return best > 1e-2 * len && glm::dot(p0.n, mesh.facePlanes()[e.f1].n) > -0.5;
}

namespace {

/// Point light at `light` (object space): the events are the silhouettes seen from the light
/// (§6.4), all Hard VE events.
void findPointLightEvents(const EdgeTree& blocker, const Mat4& worldFromObject, const Vec3& light,
                          std::vector<ShadowEvent>& out, EdgeTreeStats* stats, bool cullHidden) {
    const EdgeMesh& mesh = blocker.mesh();
    const auto& P = mesh.positions();
    std::vector<int> edges;
    blocker.findSilhouettes(light, edges, stats);
    for (int id : edges) {
        if (cullHidden && isConcaveEdge(mesh, id)) continue;
        const MeshEdge& e = mesh.edges()[id];
        ShadowEvent ev;
        ev.p0 = ev.p1 = light;
        ev.q0 = P[e.v0];
        ev.q1 = P[e.v1];
        ev.lightFeature = 0;
        ev.blockerFeature = id;
        out.push_back(ev.mapped(worldFromObject));
    }
}

/// Relative tolerance of the area-light side tests, scaled by |N| and the light's and the
/// mesh's sizes.
constexpr double kSideRel = 1e-9;

/// VE events of blocker edge `id` and the vertices of the area light L (object space): the
/// edge a silhouette from light vertex v (eq. 1) with both light neighbours of v on one side
/// of plane(v, e).
void appendVertexEdgeEvents(const EdgeMesh& mesh, int id, const std::vector<Vec3>& L,
                            double lightSize, double meshSize, const Mat4& worldFromObject,
                            std::vector<ShadowEvent>& out) {
    const auto& P = mesh.positions();
    const int n = static_cast<int>(L.size());
    const double rel = kSideRel;
    const MeshEdge& e = mesh.edges()[id];
    const Vec3 &a = P[e.v0], &b = P[e.v1];
    for (int i = 0; i < n; ++i) {
        if (!mesh.isSilhouette(id, L[i])) continue;  // eq. 1 from v
        Vec3 N = glm::cross(a - L[i], b - L[i]);
        double len = glm::length(N);
        if (!(len > 0)) continue;
        double epsL = rel * len * (lightSize + meshSize);
        // Tangent to the light at v: its neighbours on one side.
        int sp = signOf(glm::dot(N, L[(i + n - 1) % n] - L[i]), epsL);
        int sn = signOf(glm::dot(N, L[(i + 1) % n] - L[i]), epsL);
        if (sp * sn < 0) continue;
        int lightSide = sp != 0 ? sp : sn;
        for (int k = 0; k < n && lightSide == 0; ++k)
            lightSide = signOf(glm::dot(N, L[k] - L[i]), epsL);
        if (lightSide == 0) continue;
        // Blocker side: the adjacent faces' farthest vertices (both on one side at a
        // silhouette).
        double best = 0;
        for (int f : {e.f0, e.f1}) {
            if (f < 0) continue;
            for (int j = mesh.faceStart()[f]; j < mesh.faceStart()[f + 1]; ++j) {
                double d = glm::dot(N, P[mesh.faceVertices()[j]] - L[i]);
                if (std::abs(d) > std::abs(best)) best = d;
            }
        }
        int blockerSide = signOf(best, epsL);
        if (blockerSide == 0) continue;
        ShadowEvent ev;
        ev.p0 = ev.p1 = L[i];
        ev.q0 = a;
        ev.q1 = b;
        ev.kind = lightSide == blockerSide ? ShadowKind::Umbra : ShadowKind::Penumbra;
        ev.vertexEdge = true;
        ev.lightFeature = i;
        ev.blockerFeature = id;
        out.push_back(ev.mapped(worldFromObject));
    }
}

/// EV events of the area light L's edges (L[j], L[j+1]) and the blocker vertices `vertices`
/// (sorted, distinct; object space) where the plane supports the blocker (every one-ring
/// neighbour on one side).
void appendEdgeVertexEvents(const EdgeMesh& mesh, const std::vector<int>& vertices,
                            const std::vector<Vec3>& L, double lightSize, double meshSize,
                            const Mat4& worldFromObject, std::vector<ShadowEvent>& out) {
    const auto& P = mesh.positions();
    const int n = static_cast<int>(L.size());
    const double rel = kSideRel;
    for (int w : vertices) {
        for (int j = 0; j < n; ++j) {
            const Vec3 &l0 = L[j], &l1 = L[(j + 1) % n];
            Vec3 N = glm::cross(l1 - l0, P[w] - l0);
            double len = glm::length(N);
            if (!(len > 0)) continue;
            double epsL = rel * len * (lightSize + meshSize);
            int blockerSide = 0;
            bool tangent = true;
            for (int k = mesh.neighbourStart()[w]; k < mesh.neighbourStart()[w + 1]; ++k) {
                int s = signOf(glm::dot(N, P[mesh.neighbours()[k]] - P[w]), epsL);
                if (s == 0) continue;
                if (blockerSide != 0 && s != blockerSide) {
                    tangent = false;
                    break;
                }
                blockerSide = s;
            }
            if (!tangent || blockerSide == 0) continue;
            int lightSide = 0;
            for (int k = 0; k < n && lightSide == 0; ++k)
                lightSide = signOf(glm::dot(N, L[k] - l0), epsL);
            if (lightSide == 0) continue;
            ShadowEvent ev;
            ev.p0 = l0;
            ev.p1 = l1;
            ev.q0 = ev.q1 = P[w];
            ev.kind = lightSide == blockerSide ? ShadowKind::Umbra : ShadowKind::Penumbra;
            ev.vertexEdge = false;
            ev.lightFeature = j;
            ev.blockerFeature = w;
            out.push_back(ev.mapped(worldFromObject));
        }
    }
}

}  // namespace

void findShadowEvents(const EdgeTree& blocker, const Mat4& worldFromObject,
                      const Mat4& objectFromWorld, const Light& light,
                      std::vector<ShadowEvent>& out, EdgeTreeStats* stats, bool cullHidden) {
    const EdgeMesh& mesh = blocker.mesh();
    cullHidden = cullHidden && mesh.sealed();
    std::vector<Vec3> L;
    for (const Vec3& p : light.polygon) L.push_back(apply(objectFromWorld, p));
    if (L.empty()) return;
    if (L.size() == 1) {
        findPointLightEvents(blocker, worldFromObject, L[0], out, stats, cullHidden);
        return;
    }

    // Area light (appendix A). Candidates: edges that are silhouettes from some light point.
    std::vector<int> edges;
    blocker.findSilhouetteCandidates(L, edges, stats);
    const int n = static_cast<int>(L.size());
    double lightSize = 0, meshSize = glm::length(mesh.bounds().hi - mesh.bounds().lo);
    for (int i = 0; i < n; ++i) lightSize = std::max(lightSize, glm::length(L[i] - L[0]));
    std::vector<int> vertices;
    for (int id : edges) {
        const MeshEdge& e = mesh.edges()[id];
        vertices.push_back(e.v0);
        vertices.push_back(e.v1);
        if (cullHidden && isConcaveEdge(mesh, id)) continue;
        appendVertexEdgeEvents(mesh, id, L, lightSize, meshSize, worldFromObject, out);
    }
    std::sort(vertices.begin(), vertices.end());
    vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
    appendEdgeVertexEvents(mesh, vertices, L, lightSize, meshSize, worldFromObject, out);
}

// ---------------------------------------------------------------------------------------------
// EventFrame

EventFrame::EventFrame(const ShadowEvent& ev) : vertexEdge(ev.vertexEdge) {
    Vec3 N;
    if (ev.vertexEdge) {
        const Vec3 &v = ev.p0, &q0 = ev.q0, &q1 = ev.q1;
        N = glm::cross(q0 - v, q1 - v);
        k[0] = glm::cross(N, q0 - v);  // G0: zero on the ray v→q0
        c[0] = -glm::dot(k[0], v);
        k[1] = glm::cross(q1 - v, N);  // G1: zero on the ray v→q1
        c[1] = -glm::dot(k[1], v);
        Vec3 h = glm::cross(N, q1 - q0);  // zero on the line q0 q1
        double hv = glm::dot(v - q0, h);
        if (hv == 0) return;
        k[2] = -h / hv;  // s = 1 − h(x)/h(v)
        c[2] = 1 + glm::dot(h, q0) / hv;
    } else {
        const Vec3 &p0 = ev.p0, &p1 = ev.p1, &w = ev.q0;
        N = glm::cross(p1 - p0, w - p0);
        k[0] = glm::cross(w - p0, N);  // G0: zero on the line p0 w
        c[0] = -glm::dot(k[0], p0);
        k[1] = glm::cross(N, w - p1);  // G1: zero on the line p1 w
        c[1] = -glm::dot(k[1], p1);
        Vec3 h = glm::cross(N, p1 - p0);  // zero on the light edge
        double hw = glm::dot(w - p0, h);
        if (hw == 0) return;
        k[2] = h / hw;  // s = h(x)/h(w)
        c[2] = -glm::dot(k[2], p0);
    }
    double len = glm::length(N);
    if (!(len > 0) || !std::isfinite(len)) return;
    for (int i = 0; i < 3; ++i) kLength[i] = glm::length(k[i]);
    normal = N / len;
    offset = glm::dot(normal, ev.p0);
    valid = true;
}

bool EventFrame::inRegion(const double f[3]) const {
    if (vertexEdge) return f[0] >= 0 && f[1] >= 0;
    return (f[0] >= 0 && f[1] >= 0 && f[2] >= 0) || (f[0] <= 0 && f[1] <= 0 && f[2] >= 1);
}

double EventFrame::minS(const Box3& box) const {
    // s = k2·x + c2 is smallest at the corner picked per axis by the sign of k2.
    Vec3 x((k[2].x > 0) ? box.lo.x : box.hi.x, (k[2].y > 0) ? box.lo.y : box.hi.y,
           (k[2].z > 0) ? box.lo.z : box.hi.z);
    return eval(2, x);
}

bool EventFrame::touches(const Box3& box, double eps, bool farOnly) const {
    if (!valid || box.empty()) return false;
    // Linear functions over a box: value at the centre ± the projected half extent.
    const Vec3 c = box.centre(), h = 0.5 * (box.hi - box.lo);
    auto range = [&](const Vec3& kk, double cc, double& lo, double& hi) {
        double m = glm::dot(kk, c) + cc;
        double r = std::abs(kk.x) * h.x + std::abs(kk.y) * h.y + std::abs(kk.z) * h.z;
        lo = m - r;
        hi = m + r;
    };
    // A face crosses the plane only with vertices strictly on both sides; so must the box.
    double lo, hi;
    range(normal, -offset, lo, hi);
    if (!(hi > eps) || !(lo < -eps)) return false;
    double fLo[3], fHi[3];
    for (int j = 0; j < 3; ++j) range(k[j], this->c[j], fLo[j], fHi[j]);
    const double tol0 = eps * kLength[0], tol1 = eps * kLength[1], tol2 = eps * kLength[2];
    const bool neg0 = fHi[0] < -tol0, neg1 = fHi[1] < -tol1, neg2 = fHi[2] < -tol2;
    const double farFrom = farOnly ? 1 + 1e-7 : 1 - tol2;
    const bool below1 = fHi[2] < farFrom;
    if (vertexEdge) return !(neg0 || neg1 || (farOnly && below1));
    bool nearOut = farOnly || neg0 || neg1 || neg2;
    bool farOut = fLo[0] > tol0 || fLo[1] > tol1 || below1;
    return !(nearOut && farOut);
}

// ---------------------------------------------------------------------------------------------
// eventBounds

namespace {

/// A small convex polygon (a triangle clipped by up to 6 planes has at most 9 vertices).
struct SmallPolygon {
    Vec3 v[10];
    int n = 0;
};

/// Sutherland–Hodgman clip of a convex polygon to a box; extends `out` by what remains and
/// returns it.
SmallPolygon clipToBox(const SmallPolygon& input, const Box3& clip, Box3& out) {
    SmallPolygon buffers[2];
    buffers[0] = input;
    int cur = 0;
    for (int axis = 0; axis < 3 && buffers[cur].n > 0; ++axis)
        for (int side = 0; side < 2 && buffers[cur].n > 0; ++side) {
            const SmallPolygon& poly = buffers[cur];
            SmallPolygon& next = buffers[1 - cur];
            // Inside: x[axis] >= lo (side 0) or x[axis] <= hi (side 1).
            const double bound = side == 0 ? clip.lo[axis] : clip.hi[axis];
            const double sign = side == 0 ? 1.0 : -1.0;
            next.n = 0;
            double da = sign * (poly.v[0][axis] - bound);
            for (int i = 0; i < poly.n; ++i) {
                const Vec3& a = poly.v[i];
                const Vec3& b = poly.v[i + 1 < poly.n ? i + 1 : 0];
                double db = sign * (b[axis] - bound);
                if (da >= 0) next.v[next.n++] = a;
                if ((da >= 0) != (db >= 0)) next.v[next.n++] = a + (da / (da - db)) * (b - a);
                da = db;
            }
            cur = 1 - cur;
        }
    const SmallPolygon& result = buffers[cur];
    for (int i = 0; i < result.n; ++i) out.extend(result.v[i]);
    return result;
}

/// The event's region as convex polygons (one for VE, two for EV: before and beyond the
/// vertex), long enough to leave `clip`; false when degenerate.
bool regionPolygons(const ShadowEvent& ev, const Box3& clip, SmallPolygon (&poly)[2], int& count) {
    Vec3 centre = clip.centre();
    double radius = 0.5 * glm::length(clip.hi - clip.lo);
    // Far enough along every ray of the event (s = S) every point is outside the clip box's
    // bounding sphere: S·min|Q(u) − P(u)| > |P − centre| + radius.
    double minLen = ev.vertexEdge ? distanceToSegment(ev.p0, ev.q0, ev.q1)
                                  : distanceToSegment(ev.q0, ev.p0, ev.p1);
    double reach = std::max(glm::length(ev.p0 - centre), glm::length(ev.p1 - centre)) + radius;
    if (!(minLen > 1e-12 * (reach + radius)) || !std::isfinite(reach)) return false;
    double S = 1.0 + 1.01 * reach / minLen;
    if (ev.vertexEdge) {
        const Vec3& v = ev.p0;
        poly[0].v[0] = v;
        poly[0].v[1] = v + S * (ev.q0 - v);
        poly[0].v[2] = v + S * (ev.q1 - v);
        poly[0].n = 3;
        count = 1;
    } else {
        const Vec3 &p0 = ev.p0, &p1 = ev.p1, &w = ev.q0;
        poly[0].v[0] = p0;  // light edge to vertex
        poly[0].v[1] = p1;
        poly[0].v[2] = w;
        poly[0].n = 3;
        poly[1].v[0] = w;  // beyond the vertex
        poly[1].v[1] = p1 + S * (w - p1);
        poly[1].v[2] = p0 + S * (w - p0);
        poly[1].n = 3;
        count = 2;
    }
    return true;
}

}  // namespace

bool eventRange(const ShadowEvent& ev, const EventFrame& frame, const Box3& box, double* sMin,
                double* sMax) {
    if (!frame.valid || box.empty()) return false;
    // Pad flat boxes so clipping keeps what lies on them.
    Box3 padded = box;
    Vec3 pad(1e-9 * (glm::length(box.hi - box.lo) + glm::length(box.centre())) + 1e-300);
    padded.lo -= pad;
    padded.hi += pad;
    if (!frame.touches(padded, 0.0)) return false;  // conservative O(1) test first
    SmallPolygon poly[2];
    int count = 0;
    if (!regionPolygons(ev, padded, poly, count)) {
        *sMin = -HUGE_VAL;
        *sMax = HUGE_VAL;
        return true;
    }
    Box3 inside;
    double lo = HUGE_VAL, hi = -HUGE_VAL;
    for (int i = 0; i < count; ++i) {
        Box3 part;
        SmallPolygon kept = clipToBox(poly[i], padded, part);
        for (int j = 0; j < kept.n; ++j) {
            double s = frame.eval(2, kept.v[j]);
            lo = std::min(lo, s);
            hi = std::max(hi, s);
        }
        inside.extend(part);
    }
    if (inside.empty()) return false;
    *sMin = lo;
    *sMax = hi;
    return true;
}

Box3 eventBounds(const ShadowEvent& ev, const Box3& clip) {
    Box3 out;
    if (clip.empty()) return out;
    SmallPolygon poly[2];
    int count = 0;
    if (!regionPolygons(ev, clip, poly, count)) return clip;
    for (int i = 0; i < count; ++i) clipToBox(poly[i], clip, out);
    double radius = 0.5 * glm::length(clip.hi - clip.lo);
    if (out.empty()) return out;
    Vec3 pad(1e-9 * (radius + 1e-300));
    out.lo -= pad;
    out.hi += pad;
    return out;
}

// ---------------------------------------------------------------------------------------------
// ReceiverTree

ReceiverTree::ReceiverTree(std::shared_ptr<const EdgeMesh> mesh, int leafSize)
    : mMesh(std::move(mesh)), mLeafSize(std::max(1, leafSize)) {
    mFaces.resize(mMesh->faceCount());
    for (int f = 0; f < mMesh->faceCount(); ++f) mFaces[f] = f;
    mNodes.reserve(2 * mFaces.size() / mLeafSize + 4);
    mNodes.push_back({});
    if (mFaces.empty()) {
        Node& r = mNodes[0];
        for (int k = 0; k < 3; ++k) r.nLo[k] = r.nHi[k] = 0;
        r.c = Vec3(0.0);
        r.dLo = r.dHi = 0;
        r.begin = r.end = 0;
        return;
    }
    build(0, 0, static_cast<int>(mFaces.size()));
}

void ReceiverTree::build(int slot, int begin, int end) {
    const EdgeMesh& m = *mMesh;
    Box3 box, centres;
    double nLo[3] = {1e300, 1e300, 1e300}, nHi[3] = {-1e300, -1e300, -1e300};
    for (int i = begin; i < end; ++i) {
        int f = mFaces[i];
        Vec3 c(0.0);
        int cnt = m.faceStart()[f + 1] - m.faceStart()[f];
        for (int j = m.faceStart()[f]; j < m.faceStart()[f + 1]; ++j) {
            box.extend(m.positions()[m.faceVertices()[j]]);
            c += m.positions()[m.faceVertices()[j]];
        }
        centres.extend(c / double(cnt));
        const Vec3& n = m.facePlanes()[f].n;
        for (int k = 0; k < 3; ++k) {
            nLo[k] = std::min(nLo[k], n[k]);
            nHi[k] = std::max(nHi[k], n[k]);
        }
    }
    Vec3 c = box.centre();
    double dLo = 1e300, dHi = -1e300;
    for (int i = begin; i < end; ++i) {
        const FacePlane& p = m.facePlanes()[mFaces[i]];
        double d = p.d - glm::dot(p.n, c);
        dLo = std::min(dLo, d);
        dHi = std::max(dHi, d);
    }
    {
        Node& node = mNodes[slot];
        node.box = box;
        for (int k = 0; k < 3; ++k) {
            node.nLo[k] = nLo[k];
            node.nHi[k] = nHi[k];
        }
        node.c = c;
        node.h = 0.5 * (box.hi - box.lo);
        node.dLo = dLo;
        node.dHi = dHi;
        node.begin = begin;
        node.end = end;
        node.child = -1;
    }
    if (end - begin <= mLeafSize) return;
    // Median split on the longest axis of the face centres.
    Vec3 ext = centres.hi - centres.lo;
    int axis = ext.x > ext.y ? (ext.x > ext.z ? 0 : 2) : (ext.y > ext.z ? 1 : 2);
    int mid = begin + (end - begin) / 2;
    auto centreOf = [&](int f) {
        double s = 0;
        for (int j = m.faceStart()[f]; j < m.faceStart()[f + 1]; ++j)
            s += m.positions()[m.faceVertices()[j]][axis];
        return s / (m.faceStart()[f + 1] - m.faceStart()[f]);
    };
    std::nth_element(mFaces.begin() + begin, mFaces.begin() + mid, mFaces.begin() + end,
                     [&](int a, int b) { return centreOf(a) < centreOf(b); });
    int child = static_cast<int>(mNodes.size());
    mNodes[slot].child = child;
    mNodes.push_back({});
    mNodes.push_back({});
    build(child, begin, mid);
    build(child + 1, mid, end);
}

namespace {

/// An event's linear functions bounded over a box given by its centre and half extent: the
/// value at the centre ± the projected half extent (the same bounds as EventFrame::touches,
/// on a receiver node's precomputed centre and extent).
struct FrameBoxBounds {
    FrameBoxBounds(const EventFrame& f, double tolerance)
        : frame(f),
          eps(tolerance),
          absN(glm::abs(f.normal)),
          abs0(glm::abs(f.k[0])),
          abs1(glm::abs(f.k[1])),
          abs2(glm::abs(f.k[2])),
          tol0(tolerance * f.kLength[0]),
          tol1(tolerance * f.kLength[1]),
          tol2(tolerance * f.kLength[2]) {}
    /// The box straddles the plane and meets the event's region (EventFrame::touches); sMax
    /// is the largest s over the box.
    bool meetsRegion(const Vec3& c, const Vec3& h, double sMax) const {
        double pm = glm::dot(frame.normal, c) - frame.offset, pr = glm::dot(absN, h);
        if (!(pm + pr > eps) || !(pm - pr < -eps)) return false;
        double m0 = glm::dot(frame.k[0], c) + frame.c[0], r0 = glm::dot(abs0, h);
        double m1 = glm::dot(frame.k[1], c) + frame.c[1], r1 = glm::dot(abs1, h);
        bool neg0 = m0 + r0 < -tol0, neg1 = m1 + r1 < -tol1;
        if (frame.vertexEdge) {
            if (neg0 || neg1) return false;
        } else {
            bool nearOut = neg0 || neg1 || sMax < -tol2;
            bool farOut = m0 - r0 > tol0 || m1 - r1 > tol1 || sMax < 1 - tol2;
            if (nearOut && farOut) return false;
        }
        return true;
    }
    const EventFrame& frame;
    const double eps;
    const Vec3 absN, abs0, abs1, abs2;
    const double tol0, tol1, tol2;
};

/// One ReceiverTree::intersect() call as its faces see it: the event (object space), its
/// frame, the face tolerance, and the s window [sLo, sHi) pieces must lie in when `windowed`.
struct FaceQuery {
    const ShadowEvent& event;
    const EventFrame& frame;
    double eps;
    bool cullBackFaces;
    bool windowed;
    double sLo, sHi;
};

/// Where face f crosses the event's plane: the two crossing points farthest apart, x0 and x1.
/// False when the face only touches the plane, has more than 64 vertices, or crosses it in a
/// segment no longer than eps.
bool crossPlane(const EdgeMesh& m, int f, const EventFrame& frame, double eps, Vec3& x0, Vec3& x1) {
    int fb = m.faceStart()[f], fe = m.faceStart()[f + 1], cnt = fe - fb;
    // Signed distances to the event plane; faces that only touch it are skipped.
    double dist[64];
    int sgn[64];
    if (cnt > 64) return false;
    bool pos = false, neg = false;
    for (int j = 0; j < cnt; ++j) {
        dist[j] = glm::dot(frame.normal, m.positions()[m.faceVertices()[fb + j]]) - frame.offset;
        sgn[j] = signOf(dist[j], eps);
        pos = pos || sgn[j] > 0;
        neg = neg || sgn[j] < 0;
    }
    if (!pos || !neg) return false;
    // The face's crossing points with the plane: at most one per vertex.
    Vec3 pts[64];
    int npts = 0;
    for (int j = 0; j < cnt; ++j) {
        int j2 = (j + 1) % cnt;
        const Vec3& a = m.positions()[m.faceVertices()[fb + j]];
        const Vec3& b = m.positions()[m.faceVertices()[fb + j2]];
        // A vertex on the plane, or a sign change after it: never both, so at most
        // one point per vertex.
        if (sgn[j] == 0) pts[npts++] = a;
        if (sgn[j] * sgn[j2] < 0) {
            double t = dist[j] / (dist[j] - dist[j2]);
            pts[npts++] = a + t * (b - a);
        }
    }
    if (npts < 2) return false;
    // The two crossing points farthest apart.
    x0 = pts[0];
    x1 = pts[1];
    double best = glm::length(x1 - x0);
    for (int p = 0; p < npts; ++p)
        for (int q = p + 1; q < npts; ++q) {
            double d = glm::length(pts[q] - pts[p]);
            if (d > best) {
                best = d;
                x0 = pts[p];
                x1 = pts[q];
            }
        }
    return best > eps;
}

/// Splits face f's crossing segment x0–x1 where G0, G1, s or s − 1 change sign and appends
/// the pieces in the event's region (and window) to `out`, and to `coverage` when given.
void appendCrossingPieces(const FaceQuery& q, const Vec3& x0, const Vec3& x1, int f, bool front,
                          std::vector<ReceiverTree::Crossing>& out, EventCoverage* coverage) {
    const EventFrame& frame = q.frame;
    double f0[3], f1[3];
    for (int j = 0; j < 3; ++j) {
        f0[j] = frame.eval(j, x0);
        f1[j] = frame.eval(j, x1);
    }
    double cuts[6];
    int nc = 0;
    cuts[nc++] = 0;
    cuts[nc++] = 1;
    for (int j = 0; j < 4; ++j) {
        double a = j < 3 ? f0[j] : f0[2] - 1, b = j < 3 ? f1[j] : f1[2] - 1;
        if ((a < 0) != (b < 0) && a != b) {
            double t = a / (a - b);
            if (t > 0 && t < 1) cuts[nc++] = t;
        }
    }
    for (int a = 1; a < nc; ++a)  // insertion sort of at most 6 values
        for (int b = a; b > 0 && cuts[b - 1] > cuts[b]; --b) std::swap(cuts[b - 1], cuts[b]);
    for (int j = 0; j + 1 < nc; ++j) {
        double ta = cuts[j], tb = cuts[j + 1];
        if (tb - ta < 1e-12) continue;
        double tm = 0.5 * (ta + tb), fm[3];
        for (int k = 0; k < 3; ++k) fm[k] = f0[k] + tm * (f1[k] - f0[k]);
        if (!frame.inRegion(fm)) continue;
        if (q.windowed && (fm[2] < q.sLo || fm[2] >= q.sHi)) continue;
        ReceiverTree::Crossing cr;
        cr.x0 = x0 + ta * (x1 - x0);
        cr.x1 = x0 + tb * (x1 - x0);
        for (int k = 0; k < 3; ++k) {
            cr.g[0][k] = f0[k] + ta * (f1[k] - f0[k]);
            cr.g[1][k] = f0[k] + tb * (f1[k] - f0[k]);
        }
        double da = cr.g[0][0] + cr.g[0][1], db = cr.g[1][0] + cr.g[1][1];
        if (da == 0 || db == 0) continue;
        cr.u0 = cr.g[0][0] / da;
        cr.u1 = cr.g[1][0] / db;
        if (cr.u0 > cr.u1) {
            std::swap(cr.u0, cr.u1);
            std::swap(cr.x0, cr.x1);
            for (int k = 0; k < 3; ++k) std::swap(cr.g[0][k], cr.g[1][k]);
        }
        cr.u0 = std::clamp(cr.u0, 0.0, 1.0);
        cr.u1 = std::clamp(cr.u1, 0.0, 1.0);
        if (cr.u1 - cr.u0 < 1e-12) continue;
        cr.face = f;
        cr.front = front;
        out.push_back(cr);
        if (coverage) coverage->add(cr.u0, cr.u1, std::max(cr.g[0][2], cr.g[1][2]));
    }
}

/// A leaf's faces faces[begin, end): the crossing pieces of each with the event.
void intersectFaces(const FaceQuery& q, const EdgeMesh& m, const std::vector<int>& faces, int begin,
                    int end, std::vector<ReceiverTree::Crossing>& out, EventCoverage* coverage) {
    for (int i = begin; i < end; ++i) {
        int f = faces[i];
        const FacePlane& plane = m.facePlanes()[f];
        bool front = plane.eval(q.event.p0) > 0 || plane.eval(q.event.p1) > 0;
        if (q.cullBackFaces && !front) continue;
        Vec3 x0, x1;
        if (!crossPlane(m, f, q.frame, q.eps, x0, x1)) continue;
        appendCrossingPieces(q, x0, x1, f, front, out, coverage);
    }
}

}  // namespace

bool ReceiverTree::facesAwayFromLight(const Node& node, const Box3& lightBox) {
    double hi = 0, mag = 0;
    for (int k = 0; k < 3; ++k) {
        double w0 = lightBox.lo[k] - node.c[k], w1 = lightBox.hi[k] - node.c[k];
        hi += std::max(std::max(node.nLo[k] * w0, node.nLo[k] * w1),
                       std::max(node.nHi[k] * w0, node.nHi[k] * w1));
        mag += std::max(std::abs(w0), std::abs(w1)) + std::abs(node.c[k]);
    }
    return hi - node.dLo < -1e-12 * (mag + std::abs(node.dLo) + std::abs(node.dHi));
}

void ReceiverTree::intersect(const ShadowEvent& event, bool cullBackFaces,
                             std::vector<Crossing>& out, long long* nodesVisited, double sLo,
                             double sHi, EventCoverage* coverage) const {
    EventFrame frame(event);
    if (!frame.valid || mFaces.empty()) return;
    const EdgeMesh& m = *mMesh;
    double eps = 1e-9 * glm::length(m.bounds().hi - m.bounds().lo);
    Box3 lightBox;
    lightBox.extend(event.p0);
    lightBox.extend(event.p1);
    const bool windowed = sLo > -HUGE_VAL || sHi < HUGE_VAL;
    const FaceQuery query{event, frame, eps, cullBackFaces, windowed, sLo, sHi};
    const FrameBoxBounds bounds(frame, eps);
    struct Entry {
        int node;
        double sMin, sMax;  ///< s over the node's box
    };
    auto entryOf = [&](int index) {
        const Node& n = mNodes[index];
        double mid = glm::dot(frame.k[2], n.c) + frame.c[2], r = glm::dot(bounds.abs2, n.h);
        return Entry{index, mid - r, mid + r};
    };
    long long visited = 0;
    Entry stack[128];
    int top = 0;
    stack[top++] = entryOf(0);
    while (top > 0) {
        const Entry entry = stack[--top];
        const Node& node = mNodes[entry.node];
        ++visited;
        if (coverage) {
            double t = coverage->bound();
            if (t <= coverage->hideS) break;       // decided: hidden
            if (entry.sMin > t + 1e-12) continue;  // behind what is found
        }
        if (windowed && (entry.sMax < sLo - 1e-9 || entry.sMin >= sHi + 1e-9)) continue;
        if (!bounds.meetsRegion(node.c, node.h, entry.sMax)) continue;
        // Every face below faces away from the whole light feature: skip (§6.4).
        if (cullBackFaces && facesAwayFromLight(node, lightBox)) continue;
        if (node.child >= 0) {
            Entry a = entryOf(node.child), b = entryOf(node.child + 1);
            // Nearest first when something may cut the traversal short.
            if (coverage && b.sMin < a.sMin) std::swap(a, b);
            stack[top++] = b;
            stack[top++] = a;
            continue;
        }
        intersectFaces(query, m, mFaces, node.begin, node.end, out, coverage);
    }
    if (nodesVisited) *nodesVisited += visited;
}

// ---------------------------------------------------------------------------------------------
// EventCoverage

void EventCoverage::reset(double hide) {
    mPending.clear();
    mCount = 0;
    mLength = 0;
    mThreshold = HUGE_VAL;
    mDirty = false;
    mComputedAt = 0;
    mBreaks.assign({0.0, 1.0});
    mBest.assign(1, HUGE_VAL);
    hideS = hide;
}

void EventCoverage::add(double u0, double u1, double sMax) {
    if (!(u1 - u0 >= 1e-12)) return;
    mPending.push_back({u0, u1, sMax});
    ++mCount;
    mLength += u1 - u0;
    mDirty = true;
}

double EventCoverage::bound() const {
    if (mDirty && mCount >= mComputedAt + std::max<std::size_t>(1, mComputedAt / 4))
        return threshold();
    return mThreshold;
}

void EventCoverage::fold(const Piece& p) const {
    // The index of break u, inserted if new: an interval it splits leaves its value to both
    // halves; one beyond either end of the breaks is uncovered.
    auto breakAt = [&](double u) {
        const auto it = std::lower_bound(mBreaks.begin(), mBreaks.end(), u);
        const std::size_t i = static_cast<std::size_t>(it - mBreaks.begin());
        if (it != mBreaks.end() && *it == u) return i;
        mBreaks.insert(it, u);
        if (i == 0)
            mBest.insert(mBest.begin(), HUGE_VAL);
        else if (i + 1 == mBreaks.size())
            mBest.push_back(HUGE_VAL);
        else {
            const double split = mBest[i - 1];  // the interval split keeps its value
            mBest.insert(mBest.begin() + static_cast<std::ptrdiff_t>(i), split);
        }
        return i;
    };
    const std::size_t from = breakAt(p.u0);
    const std::size_t to = breakAt(p.u1);  // after u0's insertion: u1 > u0 keeps `from`
    for (std::size_t i = from; i < to; ++i) mBest[i] = std::min(mBest[i], p.sMax);
}

double EventCoverage::threshold() const {
    // Pieces shorter in total than [0, 1] cannot cover it: skip the sweep.
    if (!mDirty || mLength < 1 - 1e-9) return mThreshold;
    mDirty = false;
    mComputedAt = mCount;
    // Per elementary interval between piece ends, the smallest sMax of a piece over it (the
    // envelope, brought up to date with the pieces since the last call); the threshold is the
    // largest of those (infinite where nothing covers). Rebuilding it from every piece at each
    // call (sorting the ends and the pieces) was a third of a shadow update after a move.
    for (const Piece& p : mPending) fold(p);
    mPending.clear();
    double t = -HUGE_VAL;
    for (std::size_t i = 0; i + 1 < mBreaks.size(); ++i) {
        if (mBreaks[i + 1] <= 0 || mBreaks[i] >= 1 || mBreaks[i + 1] - mBreaks[i] < 1e-12) continue;
        t = std::max(t, mBest[i]);
        if (t == HUGE_VAL) break;
    }
    mThreshold = t;
    return t;
}

// ---------------------------------------------------------------------------------------------
// clipEvent

namespace {

/// Parameter t along a crossing where the event parameter equals u.
double paramAt(const ReceiverTree::Crossing& c, double u) {
    double A = c.g[0][0] * (1 - u) - u * c.g[0][1];
    double B = (c.g[1][0] - c.g[0][0]) * (1 - u) - u * (c.g[1][1] - c.g[0][1]);
    if (B == 0) return 0.5;
    return std::clamp(-A / B, 0.0, 1.0);
}

}  // namespace

void clipEvent(const std::vector<ReceiverCrossings>& receivers, std::vector<EventEdge>& out) {
    clipEvent(std::span<const ReceiverCrossings>(receivers), out);
}

void clipEvent(std::span<const ReceiverCrossings> receivers, std::vector<EventEdge>& out) {
    struct Item {
        double u0, u1;
        int receiver;
        const ReceiverTree::Crossing* c;
        const Mat4* m;
    };
    // Working space kept per thread (one call per event recomputed).
    static thread_local std::vector<Item> items;
    static thread_local std::vector<double> breaks;
    static thread_local std::vector<int> active;
    items.clear();
    breaks.clear();
    active.clear();
    for (const ReceiverCrossings& r : receivers)
        for (const auto& c : r.crossings) {
            items.push_back({c.u0, c.u1, r.receiver, &c, r.worldFromObject});
            breaks.push_back(c.u0);
            breaks.push_back(c.u1);
        }
    if (items.empty()) return;
    std::sort(items.begin(), items.end(), [](const Item& a, const Item& b) { return a.u0 < b.u0; });
    std::sort(breaks.begin(), breaks.end());
    breaks.erase(std::unique(breaks.begin(), breaks.end()), breaks.end());
    std::size_t next = 0;
    const Item* lastItem = nullptr;
    double lastU = -1;
    for (std::size_t b = 0; b + 1 < breaks.size(); ++b) {
        double ua = breaks[b], ub = breaks[b + 1];
        while (next < items.size() && items[next].u0 <= ua) active.push_back(int(next++));
        active.erase(
            std::remove_if(active.begin(), active.end(), [&](int i) { return items[i].u1 <= ua; }),
            active.end());
        if (active.empty()) continue;
        if (ub - ua < 1e-12) {
            if (lastItem && lastU == ua) lastU = ub;  // too short to resolve: bridge it
            continue;
        }
        double um = 0.5 * (ua + ub), bestS = 1e300;
        const Item* best = nullptr;
        for (int i : active) {
            const Item& it = items[i];
            if (it.u0 > um || it.u1 < um) continue;
            double t = paramAt(*it.c, um);
            double s = it.c->g[0][2] + t * (it.c->g[1][2] - it.c->g[0][2]);
            if (s < bestS) {
                bestS = s;
                best = &it;
            }
        }
        // The nearest surface along the ray: a shadow edge when beyond the blocker and lit.
        if (!best || bestS <= 1 + 1e-7 || !best->c->front) {
            lastItem = nullptr;
            continue;
        }
        const auto& c = *best->c;
        Vec3 xa = c.x0 + paramAt(c, ua) * (c.x1 - c.x0);
        Vec3 xb = c.x0 + paramAt(c, ub) * (c.x1 - c.x0);
        xa = Vec3(*best->m * glm::dvec4(xa, 1.0));
        xb = Vec3(*best->m * glm::dvec4(xb, 1.0));
        if (lastItem == best && lastU == ua && !out.empty()) {
            out.back().b = xb;
        } else {
            out.push_back({xa, xb, best->receiver, c.face});
        }
        lastItem = best;
        lastU = ub;
    }
}

}  // namespace penumbra
