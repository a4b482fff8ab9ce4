#pragma once
// Shadow events and shadow edges (Bala, Walter, Greenberg 2003 §6.3–6.5 and appendix A):
// VE/EV events of a blocker's edge tree for point and polygonal lights, a receiver face
// hierarchy with normal intervals, event–receiver intersection front to back (EventCoverage)
// and 1D clipping along events.
//
// Index: Light · ShadowEvent · findShadowEvents, isConcaveEdge · EventCoverage · ReceiverTree ·
//        EventFrame, eventRange, eventBounds · EventEdge, clipEvent

#include <cmath>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "render/display/edge_tree.h"
#include "solver/scene.h"

namespace penumbra {

/// A light in world space: one point (a point light) or a convex planar polygon (an area
/// light, 3+ vertices in order around it). `object` is the light's own scene object (it
/// neither blocks nor receives its own shadows), -1 for none.
struct Light {
    std::vector<Vec3> polygon;
    int object = -1;
    bool isPoint() const { return polygon.size() == 1; }
    std::string toString() const;
};

/// Hard: a point light's event. Umbra/Penumbra: an area light's umbral or penumbral event
/// (§6.3: the light and the blocker on the same side of the event plane, or opposite sides).
enum class ShadowKind { Hard, Umbra, Penumbra };
const char* shadowKindName(ShadowKind kind);

/// A VE or EV event (appendix A): the part of a plane swept by rays from a light feature
/// P(u) = p0 + u (p1 − p0) through a blocker feature Q(u) = q0 + u (q1 − q0), u in [0, 1]:
/// points P(u) + s (Q(u) − P(u)), s ≥ 0. VE: a light vertex (p0 = p1) and a blocker edge;
/// EV: a light edge and a blocker vertex (q0 = q1). s < 1 lies between light and blocker,
/// s > 1 beyond the blocker, where shadow edges are. u and s are affine invariants, so an event
/// can be mapped into any object's space.
struct ShadowEvent {
    Vec3 p0{0.0}, p1{0.0};
    Vec3 q0{0.0}, q1{0.0};
    ShadowKind kind = ShadowKind::Hard;
    bool vertexEdge = true;   ///< VE (else EV)
    int lightFeature = -1;    ///< light vertex (VE) or first vertex of the light edge (EV)
    int blockerFeature = -1;  ///< blocker EdgeMesh edge (VE) or vertex (EV)
    ShadowEvent mapped(const Mat4& m) const;
    std::string toString() const;
};

/// Shadow events of one blocker for one light (world space), found through the blocker's edge
/// tree in object space (`objectFromWorld` maps the light in; events are mapped back).
/// Point light: the silhouettes seen from the light (§6.4), all Hard VE events. Area light:
/// VE events — blocker edge e a silhouette from light vertex v (eq. 1) and both light
/// neighbours of v on one side of plane(v, e); EV events — light edge l and an endpoint w of a
/// candidate edge with plane(l, w) leaving every one-ring neighbour of w on one side (the
/// plane supports the blocker at w; this replaces the appendix's walk along the shadow-volume
/// boundary and finds a superset that clipping reduces). Umbral when the light and the blocker
/// lie on the same side of the event plane, penumbral otherwise.
/// `cullHidden` (sealed blockers only, EdgeMesh::sealed(); lights outside the blocker): skip VE
/// events at concave (reflex) edges. Rays from the light vertex to such an edge run, just before
/// it, behind the back-facing face, i.e. inside the solid, so they crossed the blocker's surface on
/// the way: the blocker hides the whole event from the light and it casts nothing (§6.5 clipping
/// would find the same, at the cost of intersecting it).
void findShadowEvents(const EdgeTree& blocker, const Mat4& worldFromObject,
                      const Mat4& objectFromWorld, const Light& light,
                      std::vector<ShadowEvent>& out, EdgeTreeStats* stats = nullptr,
                      bool cullHidden = false);
/// Whether an edge is clearly concave (reflex): a vertex of one face lies in front of the
/// other face's plane by more than 1% of the edge length, and the faces are not folded into a
/// fin (normals more than 120° apart).
bool isConcaveEdge(const EdgeMesh& mesh, int edge);

/// What is known along one event while its receivers are intersected front to back (§6.5
/// clipping): the u range and largest s of every crossing piece found so far. threshold() is
/// the smallest T such that pieces with s <= T cover every u in [0, 1] (gaps shorter than
/// clipEvent resolves, 1e-12, ignored): surfaces all beyond T can never be the nearest, and
/// with T <= 1 + 1e-7 the event is hidden (casts nothing). A piece whose sMax is NaN covers
/// nothing.
class EventCoverage {
public:
    void add(double u0, double u1, double sMax);
    /// Empty again, with hideS = `hide`; allocations kept (one coverage serves many events).
    void reset(double hide = -HUGE_VAL);
    double threshold() const;
    /// An upper bound of threshold() that is cheap to call often: recomputed only after the
    /// pieces grew by a quarter since the last computation (stale values only cull less).
    double bound() const;
    /// Once threshold() <= hideS, intersect() stops: the event's outcome is decided.
    double hideS = -HUGE_VAL;

private:
    struct Piece {
        double u0, u1, sMax;
    };
    /// Folds a piece into the envelope: its ends become breaks, and every interval between
    /// them takes the smaller of its value and the piece's sMax.
    void fold(const Piece& p) const;
    mutable std::vector<Piece> mPending;  ///< pieces not yet folded into the envelope
    std::size_t mCount = 0;               ///< pieces added since reset()
    double mLength = 0;                   ///< total u length of the pieces
    mutable double mThreshold = HUGE_VAL;
    mutable bool mDirty = false;
    mutable std::size_t mComputedAt = 0;  ///< piece count at the last computation
    /// The envelope: every piece end and 0 and 1, ascending and distinct (mBreaks), and per
    /// interval between neighbours the smallest sMax of a piece covering it (mBest; infinite
    /// where none does). Built as the pieces come, so threshold() only scans it.
    mutable std::vector<double> mBreaks{0.0, 1.0};
    mutable std::vector<double> mBest{HUGE_VAL};
};

/// A bounding-volume hierarchy over an EdgeMesh's faces (object space) whose nodes also bound
/// the face normals by an interval vector and the plane offsets (§6.4 "shadow edge
/// computation"): subtrees facing away from the whole light feature are skipped on closed,
/// one-sided receivers.
class ReceiverTree {
public:
    explicit ReceiverTree(std::shared_ptr<const EdgeMesh> mesh, int leafSize = 4);

    /// One crossing of an event with a receiver face, clipped to the event region.
    struct Crossing {
        Vec3 x0, x1;     ///< object space
        double u0, u1;   ///< event parameter at x0 and x1 (u0 <= u1)
        double g[2][3];  ///< the event's linear functions (G0, G1, s) at x0 and x1
        int face = -1;
        bool front = true;  ///< the face is lit from the front by the light feature
    };
    /// Appends the crossings of `event` (in this object's space) with the faces.
    /// `cullBackFaces`: skip faces facing away from the light feature (closed one-sided
    /// meshes only: such faces are never the first surface a light ray meets).
    /// Crossings are split where s = 1; only pieces whose mid s lies in [sLo, sHi) are kept
    /// (e.g. [−inf, 1): between light and blocker), and subtrees outside that s range are
    /// skipped. With `coverage`, pieces are added to it, subtrees are visited nearest first
    /// and skipped when wholly beyond coverage->threshold(), and the traversal stops once the
    /// threshold reaches coverage->hideS (the crossings are then incomplete).
    void intersect(const ShadowEvent& event, bool cullBackFaces, std::vector<Crossing>& out,
                   long long* nodesVisited = nullptr, double sLo = -HUGE_VAL, double sHi = HUGE_VAL,
                   EventCoverage* coverage = nullptr) const;

    const EdgeMesh& mesh() const { return *mMesh; }
    const Box3& bounds() const { return mNodes[0].box; }

private:
    struct Node {
        Box3 box;
        double nLo[3]{}, nHi[3]{};
        Vec3 c{0.0};  ///< box centre
        Vec3 h{0.0};  ///< box half extent
        double dLo = 0, dHi = 0;
        int begin = 0, end = 0;
        int child = -1;
    };
    void build(int slot, int begin, int end);
    /// Every face below `node` faces away from every point of `lightBox` (the light feature's
    /// box), by the node's normal and plane-offset intervals (§6.4).
    static bool facesAwayFromLight(const Node& node, const Box3& lightBox);
    std::shared_ptr<const EdgeMesh> mMesh;
    int mLeafSize;
    std::vector<Node> mNodes;
    std::vector<int> mFaces;  ///< faces in tree order
};

/// The linear functions of an event's plane: G0 and G1 vanish on the event's side rays, s is
/// the ray parameter; u = G0 / (G0 + G1). VE region: G0, G1 ≥ 0. EV region: G0, G1 ≥ 0 with
/// s ≥ 0 (between light edge and vertex) or G0, G1 ≤ 0 (beyond the vertex).
struct EventFrame {
    EventFrame() = default;
    explicit EventFrame(const ShadowEvent& event);
    bool valid = false;
    bool vertexEdge = true;
    Vec3 normal{0.0};   ///< unit plane normal
    double offset = 0;  ///< normal·x = offset on the plane
    Vec3 k[3];          ///< G0, G1, s: f(x) = k·x + c
    double c[3]{};
    double kLength[3]{};  ///< |k|
    double eval(int i, const Vec3& x) const { return glm::dot(k[i], x) + c[i]; }
    bool inRegion(const double f[3]) const;
    /// Conservative: false only when no face inside the box can cross the event region (the
    /// box must straddle the plane by more than `eps`). `farOnly`: the part beyond the blocker
    /// (s > 1), where shadow edges lie.
    bool touches(const Box3& box, double eps, bool farOnly = false) const;
    /// Lower bound of s over a box (s is linear: its minimum over the 8 corners).
    double minS(const Box3& box) const;
};

/// Whether the event's region meets `box` (exactly, up to a 1e-9 relative padding of the
/// box), and then the range [sMin, sMax] of s over the region inside the box.
bool eventRange(const ShadowEvent& event, const EventFrame& frame, const Box3& box, double* sMin,
                double* sMax);

/// Axis-aligned bound of an event's region (both parts of an EV event) inside `clip`; empty
/// when the region misses `clip`. Used to cull receivers and to bound a pair's shadow volume.
Box3 eventBounds(const ShadowEvent& event, const Box3& clip);

/// A shadow edge found on one receiver along one event (world space).
struct EventEdge {
    Vec3 a, b;
    int receiver = -1;  ///< index into the receivers passed to clipEvent
    int face = -1;
};

/// A receiver's crossings with one event, mapped to world space.
struct ReceiverCrossings {
    int receiver = -1;
    const Mat4* worldFromObject = nullptr;
    std::vector<ReceiverTree::Crossing> crossings;
};

/// Bala et al. §6.5 "clipping": along the event (1D in u), the surface nearest the light
/// feature (smallest s) wins. Where it lies beyond the blocker (s > 1) and faces the light it is
/// a shadow edge; where something lies between light and blocker (s < 1) the event is hidden.
/// Intervals are split at crossing endpoints only (two receivers that cross inside an interval
/// are resolved at its midpoint).
void clipEvent(const std::vector<ReceiverCrossings>& receivers, std::vector<EventEdge>& out);
void clipEvent(std::span<const ReceiverCrossings> receivers, std::vector<EventEdge>& out);

}  // namespace penumbra
