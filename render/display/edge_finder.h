#pragma once
// The edge finder of Bala, Walter, Greenberg 2003 §6: per frame, silhouettes and sharp edges
// of every object from the eye; shadow edges of every (light, blocker, receiver) triple, kept
// per event and recomputed only when the light, the blocker or a receiver near the event
// moves (§6.5).
// Output: world-space segments tagged with their kind and objects, ready for projection.
//
// Index: WorldEdge · EdgeFinderStats · EdgeFinder

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "render/display/edge_tree.h"
#include "render/display/shadow_events.h"
#include "solver/discretization.h"

namespace penumbra {

enum class EdgeKind { Silhouette, Sharp, Shadow };
const char* edgeKindName(EdgeKind kind);

/// A world-space edge segment a–b.
/// Silhouette/Sharp: `object` owns the edge, `edge` is its EdgeMesh edge id.
/// Shadow: `object` is the receiver the edge lies on, `blocker` and `light` cast it, `shadow`
/// tells hard (point light), umbra or penumbra (area light), `edge` is the blocker feature
/// (EdgeMesh edge for a VE event, vertex for an EV event).
struct WorldEdge {
    Vec3 a{0.0}, b{0.0};
    EdgeKind kind = EdgeKind::Silhouette;
    ShadowKind shadow = ShadowKind::Hard;
    int object = -1;
    int edge = -1;
    int light = -1;
    int blocker = -1;
    /// Soft shadow edges (umbral and penumbral events of an area light): the width of the
    /// penumbra at a and at b, world space — the light's extent across the event's plane,
    /// times (s − 1), the blocker-to-receiver over the light-to-blocker distance along the
    /// event's rays. 0 for hard shadows, silhouettes and sharp edges.
    double penumbraA = 0, penumbraB = 0;
    std::string toString() const;
};

/// Makes room in `list` for n elements, with half as much again to spare, when it has less;
/// for lists about to be overwritten whole: growing discards the contents instead of copying
/// them. Edge lists rebuilt after every move then keep their block (and its touched pages)
/// while they grow a little.
template <class T>
void reserveForOverwrite(std::vector<T>& list, std::size_t n) {
    if (list.capacity() >= n) return;
    list.clear();
    list.reserve(n + n / 2);
}

/// Work counters (cumulative until resetStats()).
struct EdgeFinderStats {
    long long eventRecomputations = 0;   ///< (light, blocker) pairs whose events were rebuilt
    long long pairRecomputations = 0;    ///< (light, blocker) pairs with any event recomputed
    long long tripleRecomputations = 0;  ///< (light, blocker, receiver) triples recomputed
    long long eventsFound = 0;           ///< events of the pairs whose events were rebuilt
    long long eventsIntersected = 0;     ///< events intersected with receivers (all or some)
    long long eventsHidden = 0;          ///< of those: hidden whole by a surface before them
    long long receiverQueries = 0;       ///< event × receiver-tree intersections
    long long receiverNodes = 0;         ///< receiver-tree nodes those visited
    /// Events the blocker's own surface hides alone (between light and blocker at every u):
    /// hidden whatever other receivers do, never recomputed until the pair changes.
    long long eventsSelfHidden = 0;
    /// Events recomputed with the blocker's own crossings taken from the pair's cache.
    long long selfReused = 0;
    std::string toString() const;
};

struct EdgeFinderOptions {
    double sharpCutoffDeg = 85.0;  ///< §6.2
    int leafSize = 8;              ///< edges per edge-tree leaf
    /// Reference mode for tests: every receiver whose bounds meet an event is intersected
    /// whole, and no event is dropped as self-hidden (no front-to-back early outs).
    bool exhaustiveShadows = false;
};

class EdgeFinder {
public:
    using Options = EdgeFinderOptions;

    explicit EdgeFinder(Options options);
    EdgeFinder() : EdgeFinder(Options{}) {}
    /// Every object of the discretization (its element mesh, welded, with its transform and
    /// alive flag; versions of one object share one tree), and one area light per emitting
    /// planar object (the convex hull of its vertices).
    explicit EdgeFinder(const Discretization& discretization, Options options = Options{});

    /// Adds an object (object-space mesh). Objects with equal meshes share one edge tree and
    /// one receiver tree. Returns the object index.
    int addObject(std::shared_ptr<const EdgeMesh> mesh, const Mat4& worldFromObject,
                  bool twoSided = false, std::string id = "");
    /// Moves an object: its trees stay as they are (queries map into object space); the
    /// shadows involving it become stale.
    void notifyObjectMoved(int object, const Mat4& worldFromObject);
    void setObjectAlive(int object, bool alive);
    /// Adds the objects of `discretization` this finder does not know yet (new versions of
    /// moved objects reuse their trees) and follows every object's alive flag.
    void syncWith(const Discretization& discretization);

    int addLight(const Light& light);
    /// Moves or reshapes a light; its shadows become stale.
    void setLight(int light, const Light& value);
    void setLightAlive(int light, bool alive);

    /// Silhouette edges (eq. 1, boundary edges included) of every live object from `eye`.
    std::vector<WorldEdge> findSilhouettes(const Vec3& eye) const;
    /// The same silhouettes per object: `perObject` is resized to objectCount() and entry o
    /// holds object o's silhouettes (empty when not alive) in findSilhouettes(eye)'s order, so
    /// the lists concatenated are findSilhouettes(eye). Objects are queried in parallel
    /// (oneTBB) unless `parallel` is false; the lists keep their allocations across calls.
    void findSilhouettes(const Vec3& eye, std::vector<std::vector<WorldEdge>>& perObject,
                         bool parallel = true) const;
    /// Every sharp edge (§6.2; boundary edges included) of every live object.
    std::vector<WorldEdge> findSharpEdges() const;
    /// The sharp edges with at least one front-facing adjacent face seen from `eye`.
    std::vector<WorldEdge> findSharpEdges(const Vec3& eye) const;
    /// The same facing sharp edges per object, as the per-object findSilhouettes.
    void findSharpEdges(const Vec3& eye, std::vector<std::vector<WorldEdge>>& perObject,
                        bool parallel = true) const;
    /// Shadow edges of every live light. Each (light, blocker) pair keeps its events and, per
    /// event, the edges it casts (§6.5). A moved light or blocker recomputes the pair; a moved,
    /// added, removed or restored receiver recomputes only the events whose region it met
    /// before or meets now in front of what decided them (EventCoverage). Events are
    /// recomputed in parallel (oneTBB); receivers are intersected front to back along each
    /// event and the traversal stops once the event is decided. The blocker's crossings with
    /// its own events (self-shadowing) are kept with the pair: an event its blocker hides
    /// alone is never recomputed for another receiver, and the others reuse the blocker's
    /// crossings and intersect only the other receivers.
    std::vector<WorldEdge> findShadowEdges();
    /// The same into `out`, reusing its allocation (a fresh 19 MB list a move cost its page
    /// faults), the events' edge lists copied in parallel in the same order.
    void findShadowEdges(std::vector<WorldEdge>& out);

    const EdgeFinderStats& stats() const { return mStats; }
    void resetStats() { mStats = {}; }
    int objectCount() const { return static_cast<int>(mObjects.size()); }
    int lightCount() const { return static_cast<int>(mLights.size()); }
    const EdgeTree& tree(int object) const { return *mObjects[object].tree; }
    const Light& light(int index) const { return mLights[index].light; }
    bool lightAlive(int index) const { return mLights[index].alive; }
    std::string toString() const;

private:
    struct Object {
        std::string id;
        std::shared_ptr<const EdgeTree> tree;
        std::shared_ptr<const ReceiverTree> receiver;
        Mat4 worldFromObject{1.0}, objectFromWorld{1.0};
        Box3 worldBounds;
        bool twoSided = false;
        bool alive = true;
        unsigned version = 1;
    };
    struct LightEntry {
        Light light;
        bool alive = true;
        unsigned version = 1;
    };
    /// A receiver whose bounds meet an event's region, with the range of s there
    /// (eventRange).
    struct NearReceiver {
        int receiver;
        double sMin, sMax;
    };
    /// One (light, blocker) pair's events and, per event, what it casts (§6.5: kept until the
    /// light, the blocker or a receiver near the event moves).
    struct Pair {
        bool valid = false;
        unsigned lightVersion = 0, blockerVersion = 0;
        std::vector<ShadowEvent> events;
        std::vector<EventFrame> frames;
        std::vector<Box3> boxes;  ///< per event: its region clipped to mSceneBox
        Box3 bound;               ///< union of `boxes`: the shadow-volume bound
        BoxTree boxTree;          ///< over `boxes`: the events a moved receiver's bounds may meet
        /// Per event: receivers whose bounds meet it, with the smallest s there.
        std::vector<std::vector<NearReceiver>> near;
        /// Per event: the coverage threshold it was decided with (EventCoverage); receivers
        /// wholly beyond it cannot change what the event casts.
        std::vector<double> decided;
        std::vector<std::vector<WorldEdge>> eventEdges;  ///< per event: the edges it casts
        /// Per event, the blocker as its own receiver (self-shadowing), which only the light or
        /// the blocker can change: 0 not computed yet, 1 hidden by the blocker alone, 2 the
        /// blocker's crossings are in `selfCrossings` (object space; complete for any set of
        /// other receivers: only the blocker's own coverage cut its traversal short).
        std::vector<char> selfState;
        std::vector<std::vector<ReceiverTree::Crossing>> selfCrossings;
        /// Per event: the findShadowEdges() call (mGeneration) it was last computed in, 0
        /// never.
        std::vector<unsigned> computedAt;
    };
    struct Counters;
    /// Appends object `o`'s silhouettes from `eye` to `out`; `ids` is scratch.
    void appendSilhouettes(int o, const Vec3& eye, std::vector<int>& ids,
                           std::vector<WorldEdge>& out) const;
    /// Appends object `o`'s sharp edges with a front-facing adjacent face seen from `eye`.
    void appendFacingSharpEdges(int o, const Vec3& eye, std::vector<WorldEdge>& out) const;
    /// Rebuilds a pair's events, frames and boxes (not its edges).
    void computeEvents(int light, int blocker, Pair& pair) const;
    void computeEventBoxes(Pair& pair) const;
    /// Recomputes event `e` of the pair: its near receivers and the edges it casts. The near
    /// receivers of objects unchanged since the event was last computed are taken from then.
    void computeEvent(int light, int blocker, Pair& pair, int e, Counters& counters) const;
    struct EventScratch;
    struct EventQuery;
    /// computeEvent's first step: lists in pair.near[e] and scratch.order the receivers whose
    /// bounds meet event e's region, with the range of s there (those unchanged since
    /// `computedAt` taken from scratch.kept when `reuse`). Returns whether one reaches beyond
    /// the blocker: without one the event casts nothing (§6.5).
    bool gatherNearReceivers(int light, Pair& pair, int e, bool reuse, unsigned computedAt,
                             EventScratch& scratch) const;
    /// Reference mode: intersects every near receiver whole, in object order, and empties the
    /// order (no front-to-back early outs).
    void intersectEveryNear(EventQuery& q) const;
    /// The blocker first, alone (self-shadowing): between light and blocker (s < 1) its surface
    /// hides the event at every u, or its crossings are kept whole with the pair. Either stays
    /// true until the light or the blocker moves, so other receivers' changes reuse it. Adds
    /// the crossings to the coverage and takes the blocker out of the order; returns whether
    /// the blocker alone hides the event.
    bool intersectBlockerFirst(int blocker, Pair& pair, int e, EventQuery& q,
                               Counters& counters) const;
    /// The blocker's crossings with the event as seen alone into `own`: its selfState, 1 when
    /// its surface between light and blocker hides the event (`own` empty), else 2.
    char computeSelfCrossings(int blocker, double sMin, double sMax,
                              std::vector<ReceiverTree::Crossing>& own, EventQuery& q,
                              Counters& counters) const;
    /// The other receivers, nearest first: between light and blocker, then beyond it, each
    /// skipped once the surfaces found hide it at every u.
    void intersectNearestFirst(int blocker, EventQuery& q) const;
    /// Clips the event along its crossings (§6.5) and appends the shadow edges it casts, with
    /// their penumbra widths.
    void appendShadowEdges(int light, int blocker, const EventFrame& frame, EventQuery& q,
                           std::vector<WorldEdge>& edges) const;
    /// An object changed since the last findShadowEdges(): its old and new bounds (empty
    /// when not alive then / now).
    struct Change {
        int object;
        Box3 before, after;
    };
    /// Appends the events of a valid pair that the changes may affect (§6.5 moving objects):
    /// those whose region a changed receiver met before in front of what decided them, or
    /// meets now.
    void findDirtyEvents(int light, int blocker, const Pair& pair,
                         const std::vector<Change>& changes, std::vector<int>& dirty) const;
    /// Objects changed since the last findShadowEdges(): their old and new bounds (§6.5
    /// moving objects); marks them changed in this call (mChangedAt).
    std::vector<Change> collectChanges();
    /// Grows mSceneBox, padded, to hold every object and light; returns whether it grew (event
    /// regions are clipped to it, so they must be clipped again).
    bool growSceneBox();
    struct PairJob;
    /// Drops the pairs of dead lights or blockers and lists the others' work: pairs whose light
    /// or blocker changed in `jobs` (events rebuilt), the valid rest in `scans` when `rescan`
    /// (their events checked against the changes).
    void planPairJobs(bool rescan, std::vector<PairJob>& jobs, std::vector<PairJob>& scans);
    /// Rebuilds the events of stale pairs, then recomputes every dirty event, in parallel.
    void recomputePairJobs(std::vector<PairJob>& jobs, Counters& counters) const;
    /// Adds the jobs' work and the counters to mStats.
    void addJobStats(const std::vector<PairJob>& jobs, const Counters& counters);
    /// Remembers every object's version, alive flag and bounds for the next call.
    void rememberObjects();
    /// Every pair's edges into `out`, in map order and each event's in order, copied in
    /// parallel.
    void gatherShadowEdges(std::vector<WorldEdge>& out) const;

    Options mOptions;
    std::vector<Object> mObjects;
    std::vector<LightEntry> mLights;
    std::unordered_map<std::uint64_t, std::pair<std::shared_ptr<const EdgeTree>,
                                                std::shared_ptr<const ReceiverTree>>>
        mTrees;
    std::map<std::pair<int, int>, Pair> mPairs;
    /// Per object, as of the last findShadowEdges(): version, alive flag and world bounds.
    std::vector<unsigned> mSeenVersion;
    std::vector<char> mSeenAlive;
    std::vector<Box3> mSeenBounds;
    unsigned mGeneration = 0;          ///< findShadowEdges() calls so far
    std::vector<unsigned> mChangedAt;  ///< per object: the call that last saw it change
    Box3 mSceneBox;                    ///< every object and light; event regions are clipped to it
    EdgeFinderStats mStats;
};

/// An area light for an emitting planar object: the convex hull of its world vertices, counter-
/// clockwise seen from its front. Empty polygon when the object is not planar.
Light lightForObject(const Discretization& discretization, int object);

}  // namespace penumbra
