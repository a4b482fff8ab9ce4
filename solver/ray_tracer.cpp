#include "solver/ray_tracer.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "core/log.h"
#include "solver/discretization.h"

namespace penumbra {

namespace {

void reportEmbreeError(void*, RTCError code, const char* message) {
    spdlog::error("Embree error {}: {}", static_cast<int>(code), message ? message : "");
}

/// Context carrying the visibility rule into the filter function.
struct FilterContext {
    RTCIntersectContext context;
    unsigned ignoreInstance;
    const std::vector<std::uint8_t>* world;
};

void visibilityFilter(const RTCFilterFunctionNArguments* args) {
    const auto* ctx = reinterpret_cast<const FilterContext*>(args->context);
    for (unsigned i = 0; i < args->N; ++i) {
        if (args->valid[i] != -1) continue;
        unsigned inst = RTCHitN_instID(args->hit, args->N, i, 0);
        bool blocks = ctx->world ? inst < ctx->world->size() && (*ctx->world)[inst] != 0
                                 : inst != ctx->ignoreInstance;
        if (!blocks) args->valid[i] = 0;
    }
}

/// A ray-hit record for rtcIntersect1 along origin + t·dir, t in [tNear, tFar].
RTCRayHit makeRayHit(const Vec3& origin, const Vec3& dir, float tNear, float tFar) {
    RTCRayHit rh;
    rh.ray.org_x = static_cast<float>(origin.x);
    rh.ray.org_y = static_cast<float>(origin.y);
    rh.ray.org_z = static_cast<float>(origin.z);
    rh.ray.dir_x = static_cast<float>(dir.x);
    rh.ray.dir_y = static_cast<float>(dir.y);
    rh.ray.dir_z = static_cast<float>(dir.z);
    rh.ray.tnear = tNear;
    rh.ray.tfar = tFar;
    rh.ray.time = 0.0f;
    rh.ray.mask = 0xffffffffu;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    return rh;
}

/// Embree's float 3×4 column-major instance transform from a world-from-object matrix.
void setInstanceTransform(RTCGeometry inst, const Mat4& worldFromObject) {
    float xf[12];
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 3; ++r) xf[3 * c + r] = static_cast<float>(worldFromObject[c][r]);
    rtcSetGeometryTransform(inst, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, xf);
}

/// A segment as Embree traces it: the unnormalized direction to − from over t in [0, 1], with
/// no square root or division. False for an empty or non-finite segment (nothing to trace).
bool segmentDirection(const Vec3& from, const Vec3& to, float& dx, float& dy, float& dz) {
    const Vec3 d = to - from;
    dx = static_cast<float>(d.x);
    dy = static_cast<float>(d.y);
    dz = static_cast<float>(d.z);
    return dx * dx + dy * dy + dz * dz > 0.0f;  // false for NaN too
}

}  // namespace

struct RayTracer::Impl {
    RTCDevice device = nullptr;
    RTCScene top = nullptr;      ///< alive objects: the current scene
    RTCScene history = nullptr;  ///< every object version, for Visibility::world queries
    std::vector<RTCScene> objectScenes;
    /// Picks the top-level scene and sets up the filter for a query.
    RTCScene prepare(FilterContext& ctx, const Visibility& v) const {
        rtcInitIntersectContext(&ctx.context);
        ctx.ignoreInstance = static_cast<unsigned>(v.ignoreObject);
        ctx.world = v.world;
        if (v.subset >= 0) return subsets[v.subset].scene;
        if (v.world || v.ignoreObject >= 0) ctx.context.filter = visibilityFilter;
        return v.world ? history : top;
    }
    struct Subset {
        std::vector<int> objects;
        RTCScene scene = nullptr;  ///< null: released
    };
    std::vector<Subset> subsets;
    /// (Re)builds the instance scene of subset s from the current object scenes.
    void buildSubset(Subset& s, const Discretization& disc) {
        if (s.scene) rtcReleaseScene(s.scene);
        s.scene = rtcNewScene(device);
        for (int o : s.objects) {
            if (o < 0) continue;
            RTCGeometry inst = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_INSTANCE);
            rtcSetGeometryInstancedScene(inst, objectScenes[o]);
            setInstanceTransform(inst, disc.objects()[o].worldFromObject);
            rtcCommitGeometry(inst);
            rtcAttachGeometryByID(s.scene, inst, static_cast<unsigned>(o));
            rtcReleaseGeometry(inst);
        }
        rtcCommitScene(s.scene);
    }
    /// Per object: Embree triangle -> (element face index, fan position).
    std::vector<std::vector<std::pair<int, int>>> triangleFace;
    /// Per object, per Embree triangle: everything firstHit needs, in one cache line (the
    /// stochastic shots' hits land anywhere in large scenes; chasing triangle -> face ->
    /// element -> normal cost three cache misses per ray).
    struct TriangleHit {
        int element;      ///< the front element
        int patch;        ///< its patch
        int twin;         ///< the element on the back of a two-sided face, or -1
        float normal[3];  ///< the element's world-space unit normal
        double area;      ///< the element's area
    };
    std::vector<std::vector<TriangleHit>> triangleHit;
    /// The answer of firstHit from a hit triangle's record (t aside): its element, or the
    /// twin behind a two-sided face seen from the back.
    static void readHit(const TriangleHit& t, const Vec3& dir, const Discretization& disc,
                        RayTracer::FirstHit& hit) {
        hit.element = t.element;
        hit.patch = t.patch;
        hit.area = t.area;
        hit.backFace = dir.x * t.normal[0] + dir.y * t.normal[1] + dir.z * t.normal[2] > 0;
        if (hit.backFace && t.twin >= 0) {
            const Element& back = disc.elements()[t.twin];  // the two-sided face's back
            hit.element = t.twin;
            hit.patch = back.patch;
            hit.area = back.area;
            hit.backFace = false;
        }
    }
    /// Ray counts in slots of their own cache line, one per thread (numbered in the order of
    /// their first ray, modulo kCounterSlots; threads that share a slot still add atomically):
    /// any thread may read the total while others trace (rayCount).
    static constexpr int kCounterSlots = 64;
    struct alignas(64) CounterSlot {
        std::atomic<unsigned long long> n{0};
    };
    mutable std::array<CounterSlot, kCounterSlots> rays;
    void countRays(unsigned long long k) const {
        static std::atomic<int> threads{0};
        thread_local const int slot =
            threads.fetch_add(1, std::memory_order_relaxed) % kCounterSlots;
        rays[slot].n.fetch_add(k, std::memory_order_relaxed);
    }

    void release() {
        for (Subset& s : subsets)
            if (s.scene) rtcReleaseScene(s.scene), s.scene = nullptr;
        for (RTCScene s : objectScenes) rtcReleaseScene(s);
        objectScenes.clear();
        if (top) rtcReleaseScene(top);
        if (history) rtcReleaseScene(history);
        top = history = nullptr;
    }
    ~Impl() {
        release();
        if (device) rtcReleaseDevice(device);
    }
};

RayTracer::RayTracer(const Discretization& discretization)
    : mImpl(std::make_unique<Impl>()), mDisc(discretization) {
    mImpl->device = rtcNewDevice(nullptr);
    if (!mImpl->device) throw std::runtime_error("cannot create Embree device");
    rtcSetDeviceErrorFunction(mImpl->device, reportEmbreeError, nullptr);
    rebuild();
}

RayTracer::~RayTracer() = default;

void RayTracer::rebuild() {
    Impl& im = *mImpl;
    im.release();
    im.triangleFace.clear();
    im.triangleHit.clear();
    im.top = rtcNewScene(im.device);
    im.history = rtcNewScene(im.device);
    rtcSetSceneFlags(im.top, RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
    rtcSetSceneFlags(im.history, RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
    for (std::size_t o = 0; o < mDisc.objects().size(); ++o) addObject(static_cast<int>(o));
    if (mDisc.objects().empty()) {
        rtcCommitScene(im.top);
        rtcCommitScene(im.history);
    }
    for (Impl::Subset& s : im.subsets)
        if (!s.objects.empty()) im.buildSubset(s, mDisc);
}

int RayTracer::createSubset(const std::vector<int>& objects) {
    Impl& im = *mImpl;
    for (int o : objects)
        if (o < 0 || o >= static_cast<int>(im.objectScenes.size()))
            throw std::invalid_argument("RayTracer::createSubset: no object " + std::to_string(o));
    std::size_t slot = 0;
    while (slot < im.subsets.size() && !im.subsets[slot].objects.empty()) ++slot;
    if (slot == im.subsets.size()) im.subsets.emplace_back();
    im.subsets[slot].objects = objects;
    if (objects.empty()) im.subsets[slot].objects.push_back(-1);  // keep the slot taken
    Impl::Subset& s = im.subsets[slot];
    s.scene = rtcNewScene(im.device);
    rtcCommitScene(s.scene);
    if (!objects.empty()) im.buildSubset(s, mDisc);
    return static_cast<int>(slot);
}

void RayTracer::releaseSubset(int subset) {
    Impl& im = *mImpl;
    if (subset < 0 || subset >= static_cast<int>(im.subsets.size())) return;
    Impl::Subset& s = im.subsets[subset];
    if (s.scene) rtcReleaseScene(s.scene);
    s.scene = nullptr;
    s.objects.clear();
}

void RayTracer::addObject(int o) {
    Impl& im = *mImpl;
    const ObjectSurface& s = mDisc.objects()[o];
    if (static_cast<int>(im.triangleFace.size()) <= o) im.triangleFace.resize(o + 1);
    if (static_cast<int>(im.triangleHit.size()) <= o) im.triangleHit.resize(o + 1);
    if (static_cast<int>(im.objectScenes.size()) <= o) im.objectScenes.resize(o + 1, nullptr);
    RTCScene scene = rtcNewScene(im.device);
    // Robust traversal: rays through a shared edge or vertex of two triangles hit one of them
    // (watertight), so primary rays find no cracks between elements.
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION | RTC_SCENE_FLAG_ROBUST);
    im.objectScenes[o] = scene;

    // Object-space vertices and fan triangles of every element polygon.
    RTCGeometry geom = rtcNewGeometry(im.device, RTC_GEOMETRY_TYPE_TRIANGLE);
    const std::size_t nv = s.mesh.n_vertices();
    auto* verts = static_cast<float*>(rtcSetNewGeometryBuffer(
        geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), nv));
    for (auto v : s.mesh.vertices()) {
        const auto& p = s.mesh.point(v);
        for (int k = 0; k < 3; ++k) verts[3 * v.idx() + k] = static_cast<float>(p[k]);
    }
    auto& map = im.triangleFace[o];
    map.clear();
    for (std::size_t f = 0; f < s.faceElement.size(); ++f) {
        int e = s.faceElement[f];
        if (e < 0 || s.isBackFace(static_cast<int>(f))) continue;  // twins are not traced
        const auto& vs = mDisc.elements()[e].vertices;
        for (std::size_t k = 1; k + 1 < vs.size(); ++k)
            map.push_back({static_cast<int>(f), static_cast<int>(k)});
    }
    auto* tris = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
        geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), map.size()));
    for (std::size_t t = 0; t < map.size(); ++t) {
        const auto& vs = mDisc.elements()[s.faceElement[map[t].first]].vertices;
        int k = map[t].second;
        tris[3 * t + 0] = vs[0];
        tris[3 * t + 1] = vs[k];
        tris[3 * t + 2] = vs[k + 1];
    }
    auto& hits = im.triangleHit[o];
    hits.resize(map.size());
    for (std::size_t t = 0; t < map.size(); ++t) {
        const int face = map[t].first;
        const int twin = s.faceTwin.empty() ? -1 : s.faceTwin[face];
        const Element& el = mDisc.elements()[s.faceElement[face]];
        hits[t] = {s.faceElement[face],
                   el.patch,
                   twin >= 0 ? s.faceElement[twin] : -1,
                   {static_cast<float>(el.normal.x), static_cast<float>(el.normal.y),
                    static_cast<float>(el.normal.z)},
                   el.area};
    }
    rtcCommitGeometry(geom);
    rtcAttachGeometry(scene, geom);
    rtcReleaseGeometry(geom);
    rtcCommitScene(scene);

    // One instance per object in each top-level scene: a move is a transform update.
    for (RTCScene top : {im.top, im.history}) {
        RTCGeometry inst = rtcNewGeometry(im.device, RTC_GEOMETRY_TYPE_INSTANCE);
        rtcSetGeometryInstancedScene(inst, scene);
        setInstanceTransform(inst, s.worldFromObject);
        rtcCommitGeometry(inst);
        rtcAttachGeometryByID(top, inst, static_cast<unsigned>(o));
        rtcReleaseGeometry(inst);
        if (top == im.top && !s.alive) rtcDisableGeometry(inst);
        rtcCommitScene(top);
    }

    // Offsets scale with the scene.
    Vec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
    for (const auto& obj : mDisc.objects())
        for (const Vec3& w : obj.worldPositions) lo = glm::min(lo, w), hi = glm::max(hi, w);
    mEpsilon = std::max(1e-6, 2e-6 * glm::length(hi - lo));
}

void RayTracer::updateAlive(int o) {
    RTCGeometry inst = rtcGetGeometry(mImpl->top, static_cast<unsigned>(o));
    if (mDisc.objects()[o].alive)
        rtcEnableGeometry(inst);
    else
        rtcDisableGeometry(inst);
    rtcCommitScene(mImpl->top);
}

bool RayTracer::occluded(const Vec3& from, const Vec3& to, const Visibility& visibility) const {
    float dx, dy, dz;
    if (!segmentDirection(from, to, dx, dy, dz)) return false;
    FilterContext ctx;
    RTCScene scene = mImpl->prepare(ctx, visibility);
    RTCRay ray;
    ray.org_x = static_cast<float>(from.x);
    ray.org_y = static_cast<float>(from.y);
    ray.org_z = static_cast<float>(from.z);
    ray.dir_x = dx;
    ray.dir_y = dy;
    ray.dir_z = dz;
    ray.tnear = 0.0f;
    ray.tfar = 1.0f;
    ray.time = 0.0f;
    ray.mask = 0xffffffffu;
    ray.id = 0;
    ray.flags = 0;
    rtcOccluded1(scene, &ctx.context, &ray);
    mImpl->countRays(1);
    return ray.tfar < 0.0f;
}

namespace {

/// Occlusion of `count` ≤ W segments from one start as one Embree packet of width W
/// (RTCRay4, 8 or 16 and `trace` its rtcOccluded4, 8 or 16); returns the number of segments
/// traced.
template <int W, class Packet, class Trace>
int tracePacket(RTCScene scene, RTCIntersectContext* context, const Vec3& from, const Vec3* to,
                int count, bool* blocked, Trace&& trace) {
    alignas(64) int valid[W];
    alignas(64) Packet ray;
    const float ox = static_cast<float>(from.x), oy = static_cast<float>(from.y),
                oz = static_cast<float>(from.z);
    for (int i = 0; i < W; ++i) {
        float dx = 0, dy = 0, dz = 0;
        valid[i] = i < count && segmentDirection(from, to[i], dx, dy, dz) ? -1 : 0;
        ray.org_x[i] = ox;
        ray.org_y[i] = oy;
        ray.org_z[i] = oz;
        ray.dir_x[i] = dx;
        ray.dir_y[i] = dy;
        ray.dir_z[i] = dz;
        ray.tnear[i] = 0.0f;
        ray.tfar[i] = valid[i] ? 1.0f : 0.0f;
        ray.time[i] = 0.0f;
        ray.mask[i] = 0xffffffffu;
        ray.id[i] = static_cast<unsigned>(i);
        ray.flags[i] = 0;
    }
    trace(valid, scene, context, &ray);
    int traced = 0;
    for (int i = 0; i < count; ++i) {
        blocked[i] = valid[i] && ray.tfar[i] < 0.0f;
        traced += valid[i] ? 1 : 0;
    }
    return traced;
}

}  // namespace

void RayTracer::occludedPacket(const Vec3& from, const Vec3* to, int count, bool* blocked,
                               const Visibility& visibility) const {
    if (count <= 0) return;
    if (count > 16) throw std::invalid_argument("RayTracer::occludedPacket: more than 16 segments");
    FilterContext ctx;
    RTCScene scene = mImpl->prepare(ctx, visibility);
    // The narrowest packet that holds them: Embree's cost is per packet, so a half-full wide
    // packet pays for lanes it does not use.
    int traced;
    if (count <= 4)
        traced =
            tracePacket<4, RTCRay4>(scene, &ctx.context, from, to, count, blocked, rtcOccluded4);
    else if (count <= 8)
        traced =
            tracePacket<8, RTCRay8>(scene, &ctx.context, from, to, count, blocked, rtcOccluded8);
    else
        traced =
            tracePacket<16, RTCRay16>(scene, &ctx.context, from, to, count, blocked, rtcOccluded16);
    mImpl->countRays(static_cast<unsigned long long>(traced));
}

RayHit RayTracer::intersect(const Vec3& origin, const Vec3& dir, double tNear, double tFar,
                            const Visibility& visibility) const {
    FilterContext ctx;
    RTCScene scene = mImpl->prepare(ctx, visibility);
    RTCRayHit rh = makeRayHit(origin, dir, static_cast<float>(tNear),
                              static_cast<float>(std::min(tFar, 1e30)));
    rtcIntersect1(scene, &ctx.context, &rh);
    mImpl->countRays(1);
    RayHit hit;
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return hit;
    int object = static_cast<int>(rh.hit.instID[0]);
    const auto& [face, k] = mImpl->triangleFace[object][rh.hit.primID];
    const ObjectSurface& s = mDisc.objects()[object];
    hit.object = object;
    hit.element = s.faceElement[face];
    hit.t = rh.ray.tfar;
    hit.position = origin + dir * hit.t;
    hit.backFace = glm::dot(dir, mDisc.elements()[hit.element].normal) > 0;
    const int nv = static_cast<int>(mDisc.elements()[hit.element].vertices.size());
    hit.weights.assign(nv, 0.0);
    double u = rh.hit.u, v = rh.hit.v;
    hit.weights[0] += 1.0 - u - v;
    hit.weights[k] += u;
    hit.weights[k + 1] += v;
    // The back of a two-sided face is its twin, whose vertices run in reverse.
    const int twin = s.faceTwin.empty() ? -1 : s.faceTwin[face];
    if (hit.backFace && twin >= 0) {
        hit.element = s.faceElement[twin];
        hit.backFace = false;
        std::reverse(hit.weights.begin(), hit.weights.end());
    }
    hit.geometricNormal = mDisc.elements()[hit.element].normal;
    return hit;
}

RayTracer::FirstHit RayTracer::firstHit(const Vec3& origin, const Vec3& dir,
                                        const Visibility& visibility) const {
    FilterContext ctx;
    RTCScene scene = mImpl->prepare(ctx, visibility);
    RTCRayHit rh = makeRayHit(origin, dir, 0.0f, std::numeric_limits<float>::infinity());
    rtcIntersect1(scene, &ctx.context, &rh);
    mImpl->countRays(1);
    FirstHit hit;
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return hit;
    Impl::readHit(mImpl->triangleHit[rh.hit.instID[0]][rh.hit.primID], dir, mDisc, hit);
    hit.t = rh.ray.tfar;
    return hit;
}

void RayTracer::firstHits(const Vec3* origins, const Vec3* dirs, int count, FirstHit* hits,
                          const Visibility& visibility) const {
    if (count <= 0) return;
    FilterContext ctx;
    RTCScene scene = mImpl->prepare(ctx, visibility);
    // Pass 1: trace in packets of sixteen (rtcIntersect16, the widest packet Embree offers:
    // coherent primary and shot rays share traversal work); keep (instance, triangle, t) in
    // the answer's own fields until pass 2. A short last packet repeats its last ray in the
    // invalid lanes so every lane holds a finite ray.
    for (int base = 0; base < count; base += 16) {
        const int n = std::min(16, count - base);
        alignas(64) int valid[16];
        alignas(64) RTCRayHit16 rh;
        for (int i = 0; i < 16; ++i) {
            const int k = base + std::min(i, n - 1);
            valid[i] = i < n ? -1 : 0;
            rh.ray.org_x[i] = static_cast<float>(origins[k].x);
            rh.ray.org_y[i] = static_cast<float>(origins[k].y);
            rh.ray.org_z[i] = static_cast<float>(origins[k].z);
            rh.ray.dir_x[i] = static_cast<float>(dirs[k].x);
            rh.ray.dir_y[i] = static_cast<float>(dirs[k].y);
            rh.ray.dir_z[i] = static_cast<float>(dirs[k].z);
            rh.ray.tnear[i] = 0.0f;
            rh.ray.tfar[i] = std::numeric_limits<float>::infinity();
            rh.ray.time[i] = 0.0f;
            rh.ray.mask[i] = 0xffffffffu;
            rh.ray.id[i] = static_cast<unsigned>(i);
            rh.ray.flags[i] = 0;
            rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
            rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
        }
        rtcIntersect16(valid, scene, &ctx.context, &rh);
        for (int i = 0; i < n; ++i) {
            FirstHit& h = hits[base + i];
            h = FirstHit{};
            if (rh.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) continue;
            h.element = static_cast<int>(rh.hit.instID[0][i]);
            h.patch = static_cast<int>(rh.hit.primID[i]);
            h.t = rh.ray.tfar[i];
            __builtin_prefetch(&mImpl->triangleHit[h.element][h.patch]);
        }
    }
    mImpl->countRays(static_cast<unsigned long long>(count));
    // Pass 2: the records, as firstHit reads them.
    for (int i = 0; i < count; ++i) {
        FirstHit& hit = hits[i];
        if (hit.element < 0) continue;
        Impl::readHit(mImpl->triangleHit[hit.element][hit.patch], dirs[i], mDisc, hit);
    }
}

unsigned long long RayTracer::rayCount() const {
    unsigned long long total = 0;
    for (const auto& slot : mImpl->rays) total += slot.n.load(std::memory_order_relaxed);
    return total;
}

}  // namespace penumbra
