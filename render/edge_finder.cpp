// Index: names, toString · construction, objects, lights · silhouettes and sharp edges ·
//        shadow edges (pair cache, recomputation) · lightForObject
#include "render/edge_finder.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace penumbra {

namespace {

Vec3 apply(const Mat4& m, const Vec3& p) { return Vec3(m * glm::dvec4(p, 1.0)); }

/// Box–event tolerance relative to the box diagonal: below ReceiverTree's face tolerance, so
/// a box rejected here holds no face that would cross.
constexpr double kTouchEps = 1e-12;

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
      << ", triples " << tripleRecomputations << "}";
    return s.str();
}

std::string EdgeFinder::toString() const {
    std::ostringstream s;
    s << "EdgeFinder{" << mObjects.size() << " objects, " << mLights.size() << " lights, "
      << mTrees.size() << " distinct trees, " << mPairs.size() << " light-blocker pairs}";
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
        auto mesh = std::make_shared<const EdgeMesh>(
            EdgeMesh::fromElementMesh(objects[o].mesh, mOptions.sharpCutoffDeg));
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

std::vector<WorldEdge> EdgeFinder::findSilhouettes(const Vec3& eye) const {
    std::vector<WorldEdge> out;
    std::vector<int> ids;
    for (int o = 0; o < static_cast<int>(mObjects.size()); ++o) {
        const Object& obj = mObjects[o];
        if (!obj.alive) continue;
        ids.clear();
        // Object-space query (§6.5): the eye moves into the object, the tree stays.
        obj.tree->findSilhouettes(apply(obj.objectFromWorld, eye), ids);
        const EdgeMesh& mesh = obj.tree->mesh();
        for (int id : ids) {
            const MeshEdge& e = mesh.edges()[id];
            WorldEdge w;
            w.a = apply(obj.worldFromObject, mesh.positions()[e.v0]);
            w.b = apply(obj.worldFromObject, mesh.positions()[e.v1]);
            w.kind = EdgeKind::Silhouette;
            w.object = o;
            w.edge = id;
            out.push_back(w);
        }
    }
    return out;
}

std::vector<WorldEdge> EdgeFinder::findSharpEdges() const {
    std::vector<WorldEdge> out;
    for (int o = 0; o < static_cast<int>(mObjects.size()); ++o) {
        const Object& obj = mObjects[o];
        if (!obj.alive) continue;
        const EdgeMesh& mesh = obj.tree->mesh();
        for (int id : mesh.sharpEdges()) {
            const MeshEdge& e = mesh.edges()[id];
            WorldEdge w;
            w.a = apply(obj.worldFromObject, mesh.positions()[e.v0]);
            w.b = apply(obj.worldFromObject, mesh.positions()[e.v1]);
            w.kind = EdgeKind::Sharp;
            w.object = o;
            w.edge = id;
            out.push_back(w);
        }
    }
    return out;
}

std::vector<WorldEdge> EdgeFinder::findSharpEdges(const Vec3& eye) const {
    std::vector<WorldEdge> out;
    for (const WorldEdge& w : findSharpEdges()) {
        const Object& obj = mObjects[w.object];
        const EdgeMesh& mesh = obj.tree->mesh();
        const MeshEdge& e = mesh.edges()[w.edge];
        Vec3 local = apply(obj.objectFromWorld, eye);
        // Mirroring transforms flip every face's side; eq. 1's sides are taken in object space.
        bool mirrored = glm::determinant(glm::dmat3(obj.worldFromObject)) < 0;
        auto front = [&](int f) {
            return f >= 0 && ((mesh.facePlanes()[f].eval(local) > 0) != mirrored);
        };
        if (obj.twoSided || front(e.f0) || front(e.f1)) out.push_back(w);
    }
    return out;
}

// ---------------------------------------------------------------------------------------------
// Shadow edges

bool EdgeFinder::touchesEvents(const Pair& pair, const Box3& worldBox) const {
    double eps = kTouchEps * glm::length(worldBox.hi - worldBox.lo);
    for (std::size_t e = 0; e < pair.events.size(); ++e) {
        EventFrame frame(pair.events[e]);
        // A receiver matters beyond the blocker, or before it on an event that has receivers
        // beyond (it may hide them).
        if (frame.touches(worldBox, eps, true)) return true;
        if (pair.eventLive[e] && frame.touches(worldBox, eps)) return true;
    }
    return false;
}

void EdgeFinder::computePair(int lightIndex, int blockerIndex, Pair& pair,
                             bool recomputeEvents) const {
    const LightEntry& light = mLights[lightIndex];
    const Object& blocker = mObjects[blockerIndex];
    if (recomputeEvents) {
        pair.events.clear();
        findShadowEvents(*blocker.tree, blocker.worldFromObject, blocker.objectFromWorld,
                         light.light, pair.events);
        pair.lightVersion = light.version;
        pair.blockerVersion = blocker.version;
    }
    const int n = static_cast<int>(mObjects.size());
    pair.receiverVersion.resize(n);
    pair.involved.assign(n, 0);
    for (int r = 0; r < n; ++r) pair.receiverVersion[r] = mObjects[r].version;
    pair.edges.clear();
    std::vector<ReceiverCrossings> crossings;
    std::vector<EventEdge> found;
    pair.eventLive.assign(pair.events.size(), 0);
    std::vector<int> near;
    for (std::size_t ei = 0; ei < pair.events.size(); ++ei) {
        const ShadowEvent& ev = pair.events[ei];
        crossings.clear();
        EventFrame frame(ev);
        if (!frame.valid) continue;
        // Receivers beyond the blocker first: without any the event casts nothing (§6.5).
        bool live = false;
        near.clear();
        for (int r = 0; r < n; ++r) {
            const Object& rec = mObjects[r];
            if (!rec.alive || r == light.light.object) continue;
            double eps = kTouchEps * glm::length(rec.worldBounds.hi - rec.worldBounds.lo);
            if (!frame.touches(rec.worldBounds, eps)) continue;
            near.push_back(r);
            live = live || frame.touches(rec.worldBounds, eps, true);
        }
        if (!live) continue;
        pair.eventLive[ei] = 1;
        for (int r : near) {
            const Object& rec = mObjects[r];
            pair.involved[r] = 1;
            ReceiverCrossings rc;
            rc.receiver = r;
            rc.worldFromObject = &rec.worldFromObject;
            const EdgeMesh& mesh = rec.tree->mesh();
            bool cull = mesh.closed() && !rec.twoSided;
            rec.receiver->intersect(ev.mapped(rec.objectFromWorld), cull, rc.crossings);
            if (rec.twoSided)
                for (auto& c : rc.crossings) c.front = true;
            if (!rc.crossings.empty()) crossings.push_back(std::move(rc));
        }
        found.clear();
        clipEvent(crossings, found);
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
            pair.edges.push_back(w);
        }
    }
    pair.valid = true;
}

std::vector<WorldEdge> EdgeFinder::findShadowEdges() {
    struct Job {
        int light, blocker;
        Pair* pair;
        bool events;
    };
    std::vector<Job> jobs;
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
            bool events = !pair.valid || pair.lightVersion != light.version ||
                          pair.blockerVersion != blocker.version;
            bool stale = events;
            // §6.5 moving objects: a receiver that moved matters when it touched or now
            // touches one of the pair's events.
            for (int r = 0; r < n && !stale; ++r) {
                bool known = r < static_cast<int>(pair.receiverVersion.size());
                if (known && pair.receiverVersion[r] == mObjects[r].version) continue;
                if (known && pair.involved[r]) {
                    stale = true;
                } else if (mObjects[r].alive && r != light.light.object &&
                           touchesEvents(pair, mObjects[r].worldBounds)) {
                    stale = true;
                } else if (known) {
                    pair.receiverVersion[r] = mObjects[r].version;  // moved but irrelevant
                }
            }
            if (stale) jobs.push_back({l, b, &pair, events});
        }
    }
    tbb::parallel_for(std::size_t(0), jobs.size(), [&](std::size_t i) {
        computePair(jobs[i].light, jobs[i].blocker, *jobs[i].pair, jobs[i].events);
    });
    for (const Job& job : jobs) {
        mStats.eventRecomputations += job.events;
        ++mStats.pairRecomputations;
        for (char c : job.pair->involved) mStats.tripleRecomputations += c;
    }
    std::vector<WorldEdge> out;
    for (const auto& [key, pair] : mPairs)
        out.insert(out.end(), pair.edges.begin(), pair.edges.end());
    return out;
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
    for (const Element& e : discretization.elements())
        if (e.object == object) normal += e.area * e.normal;
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
