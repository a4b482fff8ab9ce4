// Index: names, toString · construction, objects, lights · silhouettes and sharp edges ·
//        shadow edges (pair cache, recomputation) · lightForObject
#include "render/display/edge_finder.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <sstream>

namespace penumbra {

namespace {

/// An area light's extent across a plane of unit normal `normal`: moving the light point that
/// way by d moves a soft shadow boundary in that plane by d·(s − 1) at ray parameter s (similar
/// triangles through the blocker feature at s = 1), so the penumbra there is this × (s − 1),
/// measured across the rays (a receiver at an angle to them widens it).
double lightExtentAcross(const std::vector<Vec3>& light, const Vec3& normal) {
    if (light.size() < 2) return 0.0;
    double lo = HUGE_VAL, hi = -HUGE_VAL;
    for (const Vec3& v : light) {
        const double t = glm::dot(v, normal);
        lo = std::min(lo, t);
        hi = std::max(hi, t);
    }
    return hi - lo;
}

/// Vec3(m * dvec4(p, 1)) without the w row it would drop: glm's sums in glm's order,
/// (m0·x + m1·y) + (m2·z + m3), so the same bits. Inline: silhouettes map every found edge.
inline Vec3 apply(const Mat4& m, const Vec3& p) {
    return (Vec3(m[0]) * p.x + Vec3(m[1]) * p.y) + (Vec3(m[2]) * p.z + Vec3(m[3]));
}

/// Edge `id` of object `o` with object-space end points a, b, in world space.
WorldEdge worldEdge(const Mat4& worldFromObject, const Vec3& a, const Vec3& b, int id,
                    EdgeKind kind, int o) {
    WorldEdge w;
    w.a = apply(worldFromObject, a);
    w.b = apply(worldFromObject, b);
    w.kind = kind;
    w.object = o;
    w.edge = id;
    return w;
}

/// Mesh edge `id` of object `o` in world space.
WorldEdge meshWorldEdge(const Mat4& worldFromObject, const EdgeMesh& mesh, int id, EdgeKind kind,
                        int o) {
    const MeshEdge& e = mesh.edges()[id];
    return worldEdge(worldFromObject, mesh.positions()[e.v0], mesh.positions()[e.v1], id, kind, o);
}

/// Box–event tolerance relative to the box diagonal (reference mode): below ReceiverTree's
/// face tolerance, so a box rejected here holds no face that would cross.
constexpr double kTouchEps = 1e-12;

/// clipEvent's rule: no edge where the nearest surface has s <= kHideS.
constexpr double kHideS = 1 + 1e-7;

}  // namespace

const char* edgeKindName(EdgeKind kind) {
    switch (kind) {
        case EdgeKind::Silhouette:
            return "silhouette";
        case EdgeKind::Sharp:
            return "sharp";
        case EdgeKind::Shadow:
            return "shadow";
    }
    return "?";
}

std::string WorldEdge::toString() const {
    std::ostringstream s;
    s << "WorldEdge{" << edgeKindName(kind);
    if (kind == EdgeKind::Shadow)
        s << ' ' << shadowKindName(shadow) << ", light " << light << ", blocker " << blocker;
    s << ", object " << object << ", edge " << edge << ", (" << a.x << ' ' << a.y << ' ' << a.z
      << ") - (" << b.x << ' ' << b.y << ' ' << b.z << ")}";
    return s.str();
}

std::string EdgeFinderStats::toString() const {
    std::ostringstream s;
    s << "EdgeFinderStats{events " << eventRecomputations << ", pairs " << pairRecomputations
      << ", triples " << tripleRecomputations << ", events found " << eventsFound
      << ", intersected " << eventsIntersected << ", hidden " << eventsHidden
      << ", receiver queries " << receiverQueries << " visiting " << receiverNodes
      << " nodes, self-hidden " << eventsSelfHidden << ", self reused " << selfReused << '}';
    return s.str();
}

std::string EdgeFinder::toString() const {
    std::ostringstream s;
    std::size_t selfHidden = 0, selfKept = 0, crossings = 0;
    for (const auto& [key, pair] : mPairs)
        for (std::size_t e = 0; e < pair.selfState.size(); ++e) {
            selfHidden += pair.selfState[e] == 1;
            selfKept += pair.selfState[e] == 2;
            crossings += pair.selfCrossings[e].size();
        }
    s << "EdgeFinder{" << mObjects.size() << " objects, " << mLights.size() << " lights, "
      << mTrees.size() << " distinct trees, " << mPairs.size() << " light-blocker pairs, "
      << selfHidden << " events hidden by their blocker, " << selfKept << " keeping " << crossings
      << " self crossings (" << crossings * sizeof(ReceiverTree::Crossing) / 1024 << " KiB)}";
    return s.str();
}

// ---------------------------------------------------------------------------------------------
// Construction, objects, lights

EdgeFinder::EdgeFinder(Options options) : mOptions(options) {}

EdgeFinder::EdgeFinder(const Discretization& discretization, Options options) : mOptions(options) {
    syncWith(discretization);
    for (int o = 0; o < static_cast<int>(discretization.objects().size()); ++o) {
        bool emits = false;
        for (const Patch& p : discretization.patches())
            if (p.object == o) {
                emits = discretization.materials()[p.material].isEmitter();
                break;
            }
        if (!emits) continue;
        Light light = lightForObject(discretization, o);
        if (!light.polygon.empty()) {
            int l = addLight(light);
            setLightAlive(l, discretization.objects()[o].alive);
        }
    }
}

int EdgeFinder::addObject(std::shared_ptr<const EdgeMesh> mesh, const Mat4& worldFromObject,
                          bool twoSided, std::string id) {
    Object obj;
    obj.id = std::move(id);
    auto it = mTrees.find(mesh->contentHash());
    if (it == mTrees.end()) {
        auto tree = std::make_shared<const EdgeTree>(mesh, mOptions.leafSize);
        auto receiver = std::make_shared<const ReceiverTree>(mesh);
        it = mTrees.emplace(mesh->contentHash(), std::make_pair(tree, receiver)).first;
    }
    obj.tree = it->second.first;
    obj.receiver = it->second.second;
    obj.twoSided = twoSided;
    mObjects.push_back(std::move(obj));
    int index = static_cast<int>(mObjects.size()) - 1;
    notifyObjectMoved(index, worldFromObject);
    mObjects[index].version = 1;
    return index;
}

void EdgeFinder::notifyObjectMoved(int object, const Mat4& worldFromObject) {
    Object& o = mObjects.at(object);
    o.worldFromObject = worldFromObject;
    o.objectFromWorld = glm::inverse(worldFromObject);
    o.worldBounds = o.tree->mesh().bounds().transformed(worldFromObject);
    ++o.version;
}

void EdgeFinder::setObjectAlive(int object, bool alive) {
    Object& o = mObjects.at(object);
    if (o.alive == alive) return;
    o.alive = alive;
    ++o.version;
}

void EdgeFinder::syncWith(const Discretization& discretization) {
    const auto& objects = discretization.objects();
    for (int o = static_cast<int>(mObjects.size()); o < static_cast<int>(objects.size()); ++o) {
        auto mesh = std::make_shared<const EdgeMesh>(EdgeMesh::fromElementMesh(
            objects[o].mesh, mOptions.sharpCutoffDeg, objects[o].firstBackFace));
        addObject(mesh, objects[o].worldFromObject, objects[o].twoSided, objects[o].id);
    }
    for (int o = 0; o < static_cast<int>(objects.size()); ++o) setObjectAlive(o, objects[o].alive);
}

int EdgeFinder::addLight(const Light& light) {
    mLights.push_back({light, true, 1});
    return static_cast<int>(mLights.size()) - 1;
}

void EdgeFinder::setLight(int light, const Light& value) {
    mLights.at(light).light = value;
    ++mLights[light].version;
}

void EdgeFinder::setLightAlive(int light, bool alive) {
    if (mLights.at(light).alive == alive) return;
    mLights[light].alive = alive;
    ++mLights[light].version;
}

// ---------------------------------------------------------------------------------------------
// Silhouettes and sharp edges

void EdgeFinder::appendSilhouettes(int o, const Vec3& eye, std::vector<int>& ids,
                                   std::vector<WorldEdge>& out) const {
    const Object& obj = mObjects[o];
    if (!obj.alive) return;
    ids.clear();
    thread_local std::vector<Vec3> ends;
    ends.clear();
    // Object-space query (§6.5): the eye moves into the object, the tree stays. The end
    // points come with the ids, in the tree's order (a lookup through the mesh per edge
    // missed the cache twice: most of the time of this conversion).
    obj.tree->findSilhouettes(apply(obj.objectFromWorld, eye), ids, ends);
    out.reserve(out.size() + ids.size());
    for (std::size_t k = 0; k < ids.size(); ++k)
        out.push_back(worldEdge(obj.worldFromObject, ends[2 * k], ends[2 * k + 1], ids[k],
                                EdgeKind::Silhouette, o));
}

std::vector<WorldEdge> EdgeFinder::findSilhouettes(const Vec3& eye) const {
    std::vector<WorldEdge> out;
    std::vector<int> ids;
    for (int o = 0; o < static_cast<int>(mObjects.size()); ++o) appendSilhouettes(o, eye, ids, out);
    return out;
}

void EdgeFinder::findSilhouettes(const Vec3& eye, std::vector<std::vector<WorldEdge>>& perObject,
                                 bool parallel) const {
    const int n = static_cast<int>(mObjects.size());
    perObject.resize(mObjects.size());
    auto one = [&](int o, std::vector<int>& ids) {
        perObject[o].clear();
        appendSilhouettes(o, eye, ids, perObject[o]);
    };
    if (!parallel) {
        std::vector<int> ids;
        for (int o = 0; o < n; ++o) one(o, ids);
        return;
    }
    // One task per object (a mesh's traversal is large enough to be a task of its own).
    tbb::parallel_for(tbb::blocked_range<int>(0, n, 1), [&](const tbb::blocked_range<int>& r) {
        std::vector<int> ids;
        for (int o = r.begin(); o != r.end(); ++o) one(o, ids);
    });
}

std::vector<WorldEdge> EdgeFinder::findSharpEdges() const {
    std::vector<WorldEdge> out;
    for (int o = 0; o < static_cast<int>(mObjects.size()); ++o) {
        const Object& obj = mObjects[o];
        if (!obj.alive) continue;
        const EdgeMesh& mesh = obj.tree->mesh();
        for (int id : mesh.sharpEdges())
            out.push_back(meshWorldEdge(obj.worldFromObject, mesh, id, EdgeKind::Sharp, o));
    }
    return out;
}

void EdgeFinder::appendFacingSharpEdges(int o, const Vec3& eye, std::vector<WorldEdge>& out) const {
    const Object& obj = mObjects[o];
    if (!obj.alive) return;
    const EdgeMesh& mesh = obj.tree->mesh();
    const Vec3 local = apply(obj.objectFromWorld, eye);
    // Mirroring transforms flip every face's side; eq. 1's sides are taken in object space.
    const bool mirrored = glm::determinant(glm::dmat3(obj.worldFromObject)) < 0;
    auto front = [&](int f) {
        return f >= 0 && ((mesh.facePlanes()[f].eval(local) > 0) != mirrored);
    };
    for (int id : mesh.sharpEdges()) {
        const MeshEdge& e = mesh.edges()[id];
        if (!(obj.twoSided || front(e.f0) || front(e.f1))) continue;
        out.push_back(meshWorldEdge(obj.worldFromObject, mesh, id, EdgeKind::Sharp, o));
    }
}

std::vector<WorldEdge> EdgeFinder::findSharpEdges(const Vec3& eye) const {
    std::vector<WorldEdge> out;
    for (int o = 0; o < static_cast<int>(mObjects.size()); ++o) appendFacingSharpEdges(o, eye, out);
    return out;
}

void EdgeFinder::findSharpEdges(const Vec3& eye, std::vector<std::vector<WorldEdge>>& perObject,
                                bool parallel) const {
    const int n = static_cast<int>(mObjects.size());
    perObject.resize(mObjects.size());
    auto one = [&](int o) {
        perObject[o].clear();
        appendFacingSharpEdges(o, eye, perObject[o]);
    };
    if (!parallel) {
        for (int o = 0; o < n; ++o) one(o);
        return;
    }
    tbb::parallel_for(tbb::blocked_range<int>(0, n, 1), [&](const tbb::blocked_range<int>& r) {
        for (int o = r.begin(); o != r.end(); ++o) one(o);
    });
}

// ---------------------------------------------------------------------------------------------
// Shadow edges

struct EdgeFinder::Counters {
    std::atomic<long long> intersected{0}, hidden{0}, queries{0}, nodes{0}, selfHidden{0},
        selfReused{0};
};

/// computeEvent's working space, kept per thread across events (tens of thousands per update) so
/// that an event allocates nothing.
struct EdgeFinder::EventScratch {
    /// A receiver near the event with the range of s over its bounds there.
    struct Candidate {
        double sMin, sMax;
        int receiver;
    };
    std::vector<NearReceiver> kept;  ///< the event's near receivers that did not change
    std::vector<Candidate> order;    ///< receivers still to intersect, in the order to do so
    EventCoverage coverage;
    std::vector<EventEdge> found;
    std::vector<ReceiverCrossings> crossings;  ///< pool of receivers' crossings
};

/// One event's receivers being intersected: those with crossings are the first `used` of the
/// scratch pool (their vectors' allocations kept across events); `queries` and `nodes` count
/// the work until it is added to the Counters.
struct EdgeFinder::EventQuery {
    const std::vector<Object>& objects;
    const ShadowEvent& ev;  ///< world space
    EventScratch& scratch;
    std::size_t used = 0;
    long long queries = 0, nodes = 0;

    /// The next slot of the pool, emptied, for receiver r.
    ReceiverCrossings& slot(int r) {
        std::vector<ReceiverCrossings>& pool = scratch.crossings;
        if (used == pool.size()) pool.emplace_back();
        ReceiverCrossings& rc = pool[used];
        rc.receiver = r;
        rc.worldFromObject = &objects[r].worldFromObject;
        rc.crossings.clear();
        return rc;
    }
    /// The surfaces found so far hide the event at every u: it casts nothing.
    bool hidden() const { return scratch.coverage.threshold() <= kHideS; }
    /// Intersects receiver r where sLo <= s < sHi, its pieces added to the coverage, which
    /// cuts the traversal short.
    void intersect(int r, double sLo, double sHi) {
        const Object& rec = objects[r];
        ReceiverCrossings& rc = slot(r);
        bool cull = rec.tree->mesh().closed() && !rec.twoSided;
        rec.receiver->intersect(ev.mapped(rec.objectFromWorld), cull, rc.crossings, &nodes, sLo,
                                sHi, &scratch.coverage);
        ++queries;
        if (rec.twoSided)
            for (auto& c : rc.crossings) c.front = true;
        if (!rc.crossings.empty()) ++used;
    }
};

void EdgeFinder::computeEvents(int lightIndex, int blockerIndex, Pair& pair) const {
    const LightEntry& light = mLights[lightIndex];
    const Object& blocker = mObjects[blockerIndex];
    pair.events.clear();
    findShadowEvents(*blocker.tree, blocker.worldFromObject, blocker.objectFromWorld, light.light,
                     pair.events, nullptr, !blocker.twoSided && !mOptions.exhaustiveShadows);
    pair.lightVersion = light.version;
    pair.blockerVersion = blocker.version;
    pair.frames.clear();
    pair.frames.reserve(pair.events.size());
    for (const ShadowEvent& ev : pair.events) pair.frames.emplace_back(ev);
    computeEventBoxes(pair);
    pair.near.assign(pair.events.size(), {});
    pair.decided.assign(pair.events.size(), HUGE_VAL);
    pair.eventEdges.assign(pair.events.size(), {});
    pair.selfState.assign(pair.events.size(), 0);
    pair.selfCrossings.assign(pair.events.size(), {});
    pair.computedAt.assign(pair.events.size(), 0);
}

void EdgeFinder::computeEventBoxes(Pair& pair) const {
    pair.boxes.resize(pair.events.size());
    pair.bound = Box3();
    for (std::size_t e = 0; e < pair.events.size(); ++e) {
        pair.boxes[e] = pair.frames[e].valid ? eventBounds(pair.events[e], mSceneBox) : Box3();
        pair.bound.extend(pair.boxes[e]);
    }
    pair.boxTree.build(pair.boxes);
}

void EdgeFinder::computeEvent(int lightIndex, int blockerIndex, Pair& pair, int e,
                              Counters& counters) const {
    const ShadowEvent& ev = pair.events[e];
    std::vector<NearReceiver>& near = pair.near[e];
    // Receivers unchanged since the last computation meet the event as then: keep those
    // entries (`near` is in object order).
    const unsigned computedAt = pair.computedAt[e];
    pair.computedAt[e] = mGeneration;
    const bool reuse = computedAt > 0 && !mOptions.exhaustiveShadows;
    auto changed = [&](int r) { return mChangedAt[r] > computedAt; };
    static thread_local EventScratch scratch;
    std::vector<NearReceiver>& kept = scratch.kept;
    kept.clear();
    if (reuse)
        for (const NearReceiver& nr : near)
            if (!changed(nr.receiver)) kept.push_back(nr);
    near.clear();
    pair.eventEdges[e].clear();
    pair.decided[e] = HUGE_VAL;
    if (!pair.frames[e].valid || pair.boxes[e].empty()) return;
    if (!gatherNearReceivers(lightIndex, pair, e, reuse, computedAt, scratch)) return;
    counters.intersected.fetch_add(1, std::memory_order_relaxed);

    EventQuery q{mObjects, ev, scratch};
    scratch.coverage.reset(kHideS);
    if (mOptions.exhaustiveShadows) intersectEveryNear(q);
    if (intersectBlockerFirst(blockerIndex, pair, e, q, counters)) {
        // Hidden whatever else moves: no receiver can make this event stale.
        pair.decided[e] = -HUGE_VAL;
        counters.hidden.fetch_add(1, std::memory_order_relaxed);
        counters.queries.fetch_add(q.queries, std::memory_order_relaxed);
        counters.nodes.fetch_add(q.nodes, std::memory_order_relaxed);
        return;
    }
    intersectNearestFirst(blockerIndex, q);
    counters.queries.fetch_add(q.queries, std::memory_order_relaxed);
    counters.nodes.fetch_add(q.nodes, std::memory_order_relaxed);
    // Surfaces wholly beyond the threshold cannot change what this event casts (§6.5 moving
    // objects: only receivers in front of it make it stale).
    if (!mOptions.exhaustiveShadows) pair.decided[e] = scratch.coverage.threshold();
    if (q.hidden()) {
        counters.hidden.fetch_add(1, std::memory_order_relaxed);
        return;
    }
    appendShadowEdges(lightIndex, blockerIndex, pair.frames[e], q, pair.eventEdges[e]);
}

bool EdgeFinder::gatherNearReceivers(int lightIndex, Pair& pair, int e, bool reuse,
                                     unsigned computedAt, EventScratch& scratch) const {
    const LightEntry& light = mLights[lightIndex];
    const ShadowEvent& ev = pair.events[e];
    const EventFrame& frame = pair.frames[e];
    std::vector<NearReceiver>& near = pair.near[e];
    const std::vector<NearReceiver>& kept = scratch.kept;
    auto changed = [&](int r) { return mChangedAt[r] > computedAt; };
    std::vector<EventScratch::Candidate>& order = scratch.order;
    order.clear();
    bool live = false;
    const int n = static_cast<int>(mObjects.size());
    std::size_t next = 0;  // into `kept`, in object order like the loop
    for (int r = 0; r < n; ++r) {
        if (reuse && !changed(r)) {
            if (next < kept.size() && kept[next].receiver == r) {
                const NearReceiver& nr = kept[next++];
                near.push_back(nr);
                order.push_back({nr.sMin, nr.sMax, r});
                live = live || nr.sMax > kHideS;
            }
            continue;
        }
        const Object& rec = mObjects[r];
        if (!rec.alive || r == light.light.object) continue;
        if (!pair.boxes[e].overlaps(rec.worldBounds)) continue;
        EventScratch::Candidate c{0, 0, r};
        if (mOptions.exhaustiveShadows) {
            // Reference: the plain box–event test (EventFrame::touches), no s ranges.
            double eps = kTouchEps * glm::length(rec.worldBounds.hi - rec.worldBounds.lo);
            if (!frame.touches(rec.worldBounds, eps)) continue;
            c.sMax = frame.touches(rec.worldBounds, eps, true) ? HUGE_VAL : 1.0;
        } else if (!eventRange(ev, frame, rec.worldBounds, &c.sMin, &c.sMax)) {
            continue;
        }
        near.push_back({r, c.sMin, c.sMax});
        order.push_back(c);
        live = live || c.sMax > kHideS;
    }
    return live;
}

void EdgeFinder::intersectEveryNear(EventQuery& q) const {
    std::vector<EventScratch::Candidate>& order = q.scratch.order;
    for (const EventScratch::Candidate& c : order) {
        const Object& rec = mObjects[c.receiver];
        ReceiverCrossings& rc = q.slot(c.receiver);
        bool cull = rec.tree->mesh().closed() && !rec.twoSided;
        rec.receiver->intersect(q.ev.mapped(rec.objectFromWorld), cull, rc.crossings, &q.nodes);
        ++q.queries;
        if (rec.twoSided)
            for (auto& cr : rc.crossings) cr.front = true;
        if (!rc.crossings.empty()) ++q.used;
    }
    order.clear();
}

bool EdgeFinder::intersectBlockerFirst(int blockerIndex, Pair& pair, int e, EventQuery& q,
                                       Counters& counters) const {
    std::vector<EventScratch::Candidate>& order = q.scratch.order;
    auto self = std::find_if(order.begin(), order.end(), [&](const EventScratch::Candidate& c) {
        return c.receiver == blockerIndex;
    });
    if (self == order.end()) return false;
    char& state = pair.selfState[e];
    std::vector<ReceiverTree::Crossing>& own = pair.selfCrossings[e];
    if (state == 0)
        state = computeSelfCrossings(blockerIndex, self->sMin, self->sMax, own, q, counters);
    else
        counters.selfReused.fetch_add(1, std::memory_order_relaxed);
    if (state == 1) return true;
    for (const auto& c : own) q.scratch.coverage.add(c.u0, c.u1, std::max(c.g[0][2], c.g[1][2]));
    if (!own.empty()) {
        q.slot(blockerIndex).crossings.assign(own.begin(), own.end());
        ++q.used;
    }
    order.erase(self);
    return false;
}

char EdgeFinder::computeSelfCrossings(int blockerIndex, double sMin, double sMax,
                                      std::vector<ReceiverTree::Crossing>& own, EventQuery& q,
                                      Counters& counters) const {
    const Object& rec = mObjects[blockerIndex];
    char state;
    own.clear();
    EventCoverage alone;
    alone.hideS = kHideS;
    const ShadowEvent local = q.ev.mapped(rec.objectFromWorld);
    const bool cull = rec.tree->mesh().closed() && !rec.twoSided;
    if (sMin < 1) {
        rec.receiver->intersect(local, cull, own, &q.nodes, -HUGE_VAL, 1.0, &alone);
        ++q.queries;
    }
    if (alone.threshold() <= kHideS) {
        state = 1;
        own.clear();
        counters.selfHidden.fetch_add(1, std::memory_order_relaxed);
    } else {
        if (sMax >= 1) {
            rec.receiver->intersect(local, cull, own, &q.nodes, 1.0, HUGE_VAL, &alone);
            ++q.queries;
        }
        if (rec.twoSided)
            for (auto& c : own) c.front = true;
        state = 2;
    }
    own.shrink_to_fit();
    return state;
}

void EdgeFinder::intersectNearestFirst(int blockerIndex, EventQuery& q) const {
    using Candidate = EventScratch::Candidate;
    std::vector<Candidate>& order = q.scratch.order;
    const EventCoverage& coverage = q.scratch.coverage;
    // Between light and blocker (s < 1), the other receivers nearest first: surfaces there
    // hide the event (§6.5 clipping); covered at every u, it casts nothing, whatever lies
    // beyond.
    std::stable_sort(order.begin(), order.end(), [&](const Candidate& a, const Candidate& b) {
        bool ab = a.receiver == blockerIndex, bb = b.receiver == blockerIndex;
        return ab != bb ? ab : a.sMin < b.sMin;
    });
    for (const Candidate& c : order) {
        if (q.hidden()) break;
        if (c.sMin >= 1 || c.sMin > coverage.threshold() + 1e-12) continue;
        q.intersect(c.receiver, -HUGE_VAL, 1.0);
    }
    // Beyond the blocker, front to back: a receiver whose nearest point lies behind surfaces
    // already found at every u cannot show.
    std::stable_sort(order.begin(), order.end(), [](const Candidate& a, const Candidate& b) {
        return std::max(a.sMin, 1.0) < std::max(b.sMin, 1.0);
    });
    for (const Candidate& c : order) {
        if (q.hidden() || std::max(c.sMin, 1.0) > coverage.threshold() + 1e-12) break;
        if (c.sMax < 1) continue;
        q.intersect(c.receiver, 1.0, HUGE_VAL);
    }
}

void EdgeFinder::appendShadowEdges(int lightIndex, int blockerIndex, const EventFrame& frame,
                                   EventQuery& q, std::vector<WorldEdge>& edges) const {
    const ShadowEvent& ev = q.ev;
    std::vector<EventEdge>& found = q.scratch.found;
    found.clear();
    clipEvent(std::span<const ReceiverCrossings>(q.scratch.crossings.data(), q.used), found);
    const double extent = ev.kind == ShadowKind::Hard
                              ? 0.0
                              : lightExtentAcross(mLights[lightIndex].light.polygon, frame.normal);
    // The penumbra's width at x: the extent × (s − 1), 0 where s ≤ 1 (or is not a number).
    auto penumbraAt = [&](const Vec3& x) {
        const double s = frame.eval(2, x);
        return s > 1 ? extent * (s - 1) : 0.0;
    };
    for (const EventEdge& fe : found) {
        WorldEdge w;
        w.a = fe.a;
        w.b = fe.b;
        w.kind = EdgeKind::Shadow;
        w.shadow = ev.kind;
        w.object = fe.receiver;
        w.edge = ev.blockerFeature;
        w.light = lightIndex;
        w.blocker = blockerIndex;
        if (extent > 0) {
            w.penumbraA = penumbraAt(fe.a);
            w.penumbraB = penumbraAt(fe.b);
        }
        edges.push_back(w);
    }
}

void EdgeFinder::findDirtyEvents(int lightIndex, int blockerIndex, const Pair& pair,
                                 const std::vector<Change>& changes,
                                 std::vector<int>& dirtyEvents) const {
    const LightEntry& light = mLights[lightIndex];
    std::vector<int> candidates;
    std::vector<char> seen(pair.events.size(), 0), isDirty(pair.events.size(), 0);
    for (const Change& c : changes) {
        if (c.object == light.light.object || c.object == blockerIndex) continue;
        // The new bounds padded beyond eventRange's own padding, for the minS pre-test.
        Box3 padded = c.after;
        if (!padded.empty()) {
            Vec3 pad(4e-9 * (glm::length(padded.hi - padded.lo) + glm::length(padded.centre())) +
                     1e-300);
            padded.lo -= pad;
            padded.hi += pad;
        }
        if (!pair.bound.overlaps(c.before) && !pair.bound.overlaps(c.after)) continue;
        // Candidates: events whose boxes meet the old or the new bounds (an event that listed
        // the receiver as near met its old bounds).
        candidates.clear();
        pair.boxTree.query(c.before, candidates);
        pair.boxTree.query(c.after, candidates);
        for (int e : candidates) {
            if (seen[e]) continue;  // met both bounds, or already dirty
            seen[e] = 1;
            // Hidden by its own blocker: nothing else can change that.
            if (pair.selfState[e] == 1) continue;
            // Where it was: it mattered when not wholly beyond the event's threshold.
            const double limit = pair.decided[e] + 1e-12;
            bool dirty = false;
            for (const NearReceiver& nr : pair.near[e])
                dirty = dirty || (nr.receiver == c.object && nr.sMin <= limit);
            // Where it is: it matters when it meets the event in front of that (s is linear:
            // frame.minS bounds it below over the box, a cheap test before eventRange's).
            if (!dirty && pair.boxes[e].overlaps(c.after)) {
                double s0 = 0, s1 = 0;
                if (mOptions.exhaustiveShadows)
                    dirty = pair.frames[e].touches(
                        c.after, kTouchEps * glm::length(c.after.hi - c.after.lo));
                else
                    dirty = pair.frames[e].minS(padded) <= limit &&
                            eventRange(pair.events[e], pair.frames[e], c.after, &s0, &s1) &&
                            s0 <= limit;
            }
            if (dirty) {
                dirtyEvents.push_back(e);
                isDirty[e] = 1;
            }
        }
        // The next change tests every event again, except those already dirty.
        for (int e : candidates) seen[e] = isDirty[e];
    }
    std::sort(dirtyEvents.begin(), dirtyEvents.end());
}

std::vector<WorldEdge> EdgeFinder::findShadowEdges() {
    std::vector<WorldEdge> out;
    findShadowEdges(out);
    return out;
}

/// One (light, blocker) pair with work to do in findShadowEdges().
struct EdgeFinder::PairJob {
    int light, blocker;
    Pair* pair;
    bool events;             ///< rebuild the events (then every event is recomputed)
    std::vector<int> dirty;  ///< otherwise: the events to recompute
};

void EdgeFinder::findShadowEdges(std::vector<WorldEdge>& out) {
    ++mGeneration;
    mChangedAt.resize(mObjects.size(), 0);
    const std::vector<Change> changes = collectChanges();
    const bool sceneGrew = growSceneBox();
    std::vector<PairJob> jobs, scans;
    planPairJobs(sceneGrew || !changes.empty(), jobs, scans);
    // Valid pairs: which of their events the changes make stale (in parallel).
    tbb::parallel_for(std::size_t(0), scans.size(), [&](std::size_t i) {
        PairJob& job = scans[i];
        if (sceneGrew) computeEventBoxes(*job.pair);
        findDirtyEvents(job.light, job.blocker, *job.pair, changes, job.dirty);
    });
    for (PairJob& job : scans)
        if (!job.dirty.empty()) jobs.push_back(std::move(job));
    Counters counters;
    recomputePairJobs(jobs, counters);
    addJobStats(jobs, counters);
    rememberObjects();
    gatherShadowEdges(out);
}

std::vector<EdgeFinder::Change> EdgeFinder::collectChanges() {
    const int n = static_cast<int>(mObjects.size());
    std::vector<Change> changes;
    for (int o = 0; o < n; ++o) {
        const Object& obj = mObjects[o];
        bool known = o < static_cast<int>(mSeenVersion.size());
        if (known && mSeenVersion[o] == obj.version) continue;
        Change c{o, {}, {}};
        if (known && mSeenAlive[o]) c.before = mSeenBounds[o];
        if (obj.alive) c.after = obj.worldBounds;
        changes.push_back(c);
        mChangedAt[o] = mGeneration;
    }
    return changes;
}

bool EdgeFinder::growSceneBox() {
    Box3 scene;
    for (const Object& obj : mObjects) scene.extend(obj.worldBounds);
    for (const LightEntry& l : mLights)
        for (const Vec3& p : l.light.polygon) scene.extend(p);
    bool sceneGrew = !mSceneBox.contains(scene);
    if (sceneGrew) {
        mSceneBox.extend(scene);
        Vec3 pad(0.01 * glm::length(mSceneBox.hi - mSceneBox.lo) + 1e-9);
        mSceneBox.lo -= pad;
        mSceneBox.hi += pad;
    }
    return sceneGrew;
}

void EdgeFinder::planPairJobs(bool rescan, std::vector<PairJob>& jobs,
                              std::vector<PairJob>& scans) {
    const int n = static_cast<int>(mObjects.size());
    for (int l = 0; l < static_cast<int>(mLights.size()); ++l) {
        const LightEntry& light = mLights[l];
        for (int b = 0; b < n; ++b) {
            const Object& blocker = mObjects[b];
            auto key = std::make_pair(l, b);
            if (!light.alive || !blocker.alive || b == light.light.object) {
                mPairs.erase(key);
                continue;
            }
            Pair& pair = mPairs[key];
            if (!pair.valid || pair.lightVersion != light.version ||
                pair.blockerVersion != blocker.version) {
                jobs.push_back({l, b, &pair, true, {}});
                continue;
            }
            if (rescan) scans.push_back({l, b, &pair, false, {}});
        }
    }
}

void EdgeFinder::recomputePairJobs(std::vector<PairJob>& jobs, Counters& counters) const {
    // Rebuild events of stale pairs, then recompute every dirty event, all in parallel.
    tbb::parallel_for(std::size_t(0), jobs.size(), [&](std::size_t i) {
        PairJob& job = jobs[i];
        if (!job.events) return;
        computeEvents(job.light, job.blocker, *job.pair);
        job.dirty.resize(job.pair->events.size());
        for (int e = 0; e < static_cast<int>(job.dirty.size()); ++e) job.dirty[e] = e;
        job.pair->valid = true;
    });
    std::vector<std::pair<const PairJob*, int>> tasks;
    for (const PairJob& job : jobs)
        for (int e : job.dirty) tasks.push_back({&job, e});
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, tasks.size(), 16),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t i = range.begin(); i != range.end(); ++i) {
                              const PairJob& job = *tasks[i].first;
                              computeEvent(job.light, job.blocker, *job.pair, tasks[i].second,
                                           counters);
                          }
                      });
}

void EdgeFinder::addJobStats(const std::vector<PairJob>& jobs, const Counters& counters) {
    const int n = static_cast<int>(mObjects.size());
    for (const PairJob& job : jobs) {
        mStats.eventRecomputations += job.events;
        ++mStats.pairRecomputations;
        if (job.events) mStats.eventsFound += static_cast<long long>(job.pair->events.size());
        std::vector<char> involved(n, 0);
        for (int e : job.dirty)
            for (const NearReceiver& nr : job.pair->near[e]) involved[nr.receiver] = 1;
        for (char c : involved) mStats.tripleRecomputations += c;
    }
    mStats.eventsIntersected += counters.intersected.load();
    mStats.eventsHidden += counters.hidden.load();
    mStats.receiverQueries += counters.queries.load();
    mStats.receiverNodes += counters.nodes.load();
    mStats.eventsSelfHidden += counters.selfHidden.load();
    mStats.selfReused += counters.selfReused.load();
}

void EdgeFinder::rememberObjects() {
    const int n = static_cast<int>(mObjects.size());
    mSeenVersion.resize(n);
    mSeenAlive.resize(n);
    mSeenBounds.resize(n);
    for (int o = 0; o < n; ++o) {
        mSeenVersion[o] = mObjects[o].version;
        mSeenAlive[o] = mObjects[o].alive;
        mSeenBounds[o] = mObjects[o].worldBounds;
    }
}

void EdgeFinder::gatherShadowEdges(std::vector<WorldEdge>& out) const {
    // Every pair's edges in map order, each event's in order: the lists' offsets, then the
    // copies in parallel.
    std::vector<const std::vector<WorldEdge>*> lists;
    std::vector<std::size_t> offsets;
    std::size_t total = 0;
    for (const auto& [key, pair] : mPairs)
        for (const auto& ee : pair.eventEdges)
            if (!ee.empty()) {
                lists.push_back(&ee);
                offsets.push_back(total);
                total += ee.size();
            }
    // Room to grow by half: a move that adds edges would otherwise move the list into a
    // fresh block, whose first writes cost a page fault per page.
    reserveForOverwrite(out, total);
    out.resize(total);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, lists.size(), 256),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t i = range.begin(); i != range.end(); ++i)
                              std::copy(lists[i]->begin(), lists[i]->end(),
                                        out.begin() + static_cast<std::ptrdiff_t>(offsets[i]));
                      });
}

// ---------------------------------------------------------------------------------------------
// lightForObject

Light lightForObject(const Discretization& discretization, int object) {
    const ObjectSurface& surface = discretization.objects().at(object);
    Light light;
    light.object = object;
    std::vector<Vec3> pts;
    for (auto vh : surface.mesh.vertices()) {
        const auto& p = surface.mesh.point(vh);
        pts.push_back(apply(surface.worldFromObject, Vec3(p[0], p[1], p[2])));
    }
    if (pts.size() < 3) return light;
    Vec3 normal(0.0);
    for (const Element& e : discretization.elements())  // the front: emission is front-only
        if (e.object == object && !surface.isBackFace(e.face)) normal += e.area * e.normal;
    if (!(glm::length(normal) > 0)) return light;
    normal = glm::normalize(normal);
    Box3 box;
    for (const Vec3& p : pts) box.extend(p);
    double size = glm::length(box.hi - box.lo);
    for (const Vec3& p : pts)
        if (std::abs(glm::dot(normal, p - pts[0])) > 1e-6 * size) return light;  // not planar
    // Convex hull in the plane (Andrew's monotone chain), counter-clockwise about `normal`.
    Vec3 ax = glm::normalize(std::abs(normal.x) < 0.9 ? glm::cross(normal, Vec3(1, 0, 0))
                                                      : glm::cross(normal, Vec3(0, 1, 0)));
    Vec3 ay = glm::cross(normal, ax);
    std::vector<std::pair<glm::dvec2, int>> q;
    for (int i = 0; i < static_cast<int>(pts.size()); ++i)
        q.push_back({{glm::dot(pts[i], ax), glm::dot(pts[i], ay)}, i});
    std::sort(q.begin(), q.end(), [](const auto& a, const auto& b) {
        return a.first.x < b.first.x || (a.first.x == b.first.x && a.first.y < b.first.y);
    });
    auto cross2 = [](glm::dvec2 o, glm::dvec2 a, glm::dvec2 b) {
        return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
    };
    double tol = 1e-9 * size * size;
    std::vector<std::pair<glm::dvec2, int>> hull(2 * q.size());
    int k = 0;
    for (std::size_t i = 0; i < q.size(); ++i) {
        while (k >= 2 && cross2(hull[k - 2].first, hull[k - 1].first, q[i].first) <= tol) --k;
        hull[k++] = q[i];
    }
    for (int i = static_cast<int>(q.size()) - 2, t = k + 1; i >= 0; --i) {
        while (k >= t && cross2(hull[k - 2].first, hull[k - 1].first, q[i].first) <= tol) --k;
        hull[k++] = q[i];
    }
    hull.resize(std::max(0, k - 1));
    for (const auto& h : hull) light.polygon.push_back(pts[h.second]);
    if (light.polygon.size() < 3) light.polygon.clear();
    return light;
}

}  // namespace penumbra
