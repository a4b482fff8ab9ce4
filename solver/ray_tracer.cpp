#include "solver/ray_tracer.h"

#include <embree3/rtcore.h>
#include <tbb/enumerable_thread_specific.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "solver/discretization.h"

namespace penumbra {

namespace {

void reportEmbreeError(void*, RTCError code, const char* message) {
    std::fprintf(stderr, "penumbra: Embree error %d: %s\n", static_cast<int>(code),
                 message ? message : "");
}

/// Context carrying the object to ignore into the filter function.
struct IgnoreContext {
    RTCIntersectContext context;
    unsigned ignoreInstance;
};

void ignoreFilter(const RTCFilterFunctionNArguments* args) {
    const auto* ctx = reinterpret_cast<const IgnoreContext*>(args->context);
    for (unsigned i = 0; i < args->N; ++i) {
        if (args->valid[i] != -1) continue;
        if (RTCHitN_instID(args->hit, args->N, i, 0) == ctx->ignoreInstance) args->valid[i] = 0;
    }
}

}  // namespace

struct RayTracer::Impl {
    RTCDevice device = nullptr;
    RTCScene top = nullptr;
    std::vector<RTCScene> objectScenes;
    /// Per object: Embree triangle -> (element face index, fan position).
    std::vector<std::vector<std::pair<int, int>>> triangleFace;
    mutable tbb::enumerable_thread_specific<unsigned long long> rays{0ull};

    void release() {
        for (RTCScene s : objectScenes) rtcReleaseScene(s);
        objectScenes.clear();
        if (top) rtcReleaseScene(top);
        top = nullptr;
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
    im.triangleFace.assign(mDisc.objects().size(), {});
    im.top = rtcNewScene(im.device);
    rtcSetSceneFlags(im.top, RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
    Vec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());

    for (std::size_t o = 0; o < mDisc.objects().size(); ++o) {
        const ObjectSurface& s = mDisc.objects()[o];
        RTCScene scene = rtcNewScene(im.device);
        rtcSetSceneFlags(scene, RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
        im.objectScenes.push_back(scene);

        // Object-space vertices and fan triangles of every element polygon.
        RTCGeometry geom = rtcNewGeometry(im.device, RTC_GEOMETRY_TYPE_TRIANGLE);
        const std::size_t nv = s.mesh.n_vertices();
        auto* verts = static_cast<float*>(rtcSetNewGeometryBuffer(
            geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), nv));
        for (auto v : s.mesh.vertices()) {
            const auto& p = s.mesh.point(v);
            for (int k = 0; k < 3; ++k) verts[3 * v.idx() + k] = p[k];
        }
        for (const Vec3& w : s.worldPositions) lo = glm::min(lo, w), hi = glm::max(hi, w);
        auto& map = im.triangleFace[o];
        for (std::size_t f = 0; f < s.faceElement.size(); ++f) {
            int e = s.faceElement[f];
            if (e < 0) continue;
            const auto& vs = mDisc.elements()[e].vertices;
            for (std::size_t k = 1; k + 1 < vs.size(); ++k) map.push_back({static_cast<int>(f), static_cast<int>(k)});
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
        rtcCommitGeometry(geom);
        rtcAttachGeometry(scene, geom);
        rtcReleaseGeometry(geom);
        rtcCommitScene(scene);

        // One instance per object: a move is a transform update.
        RTCGeometry inst = rtcNewGeometry(im.device, RTC_GEOMETRY_TYPE_INSTANCE);
        rtcSetGeometryInstancedScene(inst, scene);
        float xf[12];
        for (int c = 0; c < 4; ++c)
            for (int r = 0; r < 3; ++r) xf[3 * c + r] = static_cast<float>(s.worldFromObject[c][r]);
        rtcSetGeometryTransform(inst, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, xf);
        rtcCommitGeometry(inst);
        rtcAttachGeometryByID(im.top, inst, static_cast<unsigned>(o));
        rtcReleaseGeometry(inst);
    }
    rtcCommitScene(im.top);
    double diag = mDisc.objects().empty() ? 1.0 : glm::length(hi - lo);
    mEpsilon = std::max(1e-6, 2e-6 * diag);
}

bool RayTracer::occluded(const Vec3& from, const Vec3& to, int ignoreObject) const {
    Vec3 d = to - from;
    double len = glm::length(d);
    if (!(len > 0)) return false;
    d /= len;
    IgnoreContext ctx;
    rtcInitIntersectContext(&ctx.context);
    ctx.ignoreInstance = static_cast<unsigned>(ignoreObject);
    if (ignoreObject >= 0) ctx.context.filter = ignoreFilter;
    RTCRay ray;
    ray.org_x = static_cast<float>(from.x);
    ray.org_y = static_cast<float>(from.y);
    ray.org_z = static_cast<float>(from.z);
    ray.dir_x = static_cast<float>(d.x);
    ray.dir_y = static_cast<float>(d.y);
    ray.dir_z = static_cast<float>(d.z);
    ray.tnear = 0.0f;
    ray.tfar = static_cast<float>(len);
    ray.time = 0.0f;
    ray.mask = 0xffffffffu;
    ray.id = 0;
    ray.flags = 0;
    rtcOccluded1(mImpl->top, &ctx.context, &ray);
    ++mImpl->rays.local();
    return ray.tfar < 0.0f;
}

RayHit RayTracer::intersect(const Vec3& origin, const Vec3& dir, double tNear, double tFar,
                            int ignoreObject) const {
    IgnoreContext ctx;
    rtcInitIntersectContext(&ctx.context);
    ctx.ignoreInstance = static_cast<unsigned>(ignoreObject);
    if (ignoreObject >= 0) ctx.context.filter = ignoreFilter;
    RTCRayHit rh;
    rh.ray.org_x = static_cast<float>(origin.x);
    rh.ray.org_y = static_cast<float>(origin.y);
    rh.ray.org_z = static_cast<float>(origin.z);
    rh.ray.dir_x = static_cast<float>(dir.x);
    rh.ray.dir_y = static_cast<float>(dir.y);
    rh.ray.dir_z = static_cast<float>(dir.z);
    rh.ray.tnear = static_cast<float>(tNear);
    rh.ray.tfar = static_cast<float>(std::min(tFar, 1e30));
    rh.ray.time = 0.0f;
    rh.ray.mask = 0xffffffffu;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(mImpl->top, &ctx.context, &rh);
    ++mImpl->rays.local();
    RayHit hit;
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return hit;
    int object = static_cast<int>(rh.hit.instID[0]);
    const auto& [face, k] = mImpl->triangleFace[object][rh.hit.primID];
    const ObjectSurface& s = mDisc.objects()[object];
    hit.object = object;
    hit.element = s.faceElement[face];
    hit.t = rh.ray.tfar;
    hit.position = origin + dir * hit.t;
    const Element& el = mDisc.elements()[hit.element];
    hit.geometricNormal = el.normal;
    hit.backFace = glm::dot(dir, el.normal) > 0;
    hit.weights.assign(el.vertices.size(), 0.0);
    double u = rh.hit.u, v = rh.hit.v;
    hit.weights[0] += 1.0 - u - v;
    hit.weights[k] += u;
    hit.weights[k + 1] += v;
    return hit;
}

unsigned long long RayTracer::rayCount() const {
    unsigned long long total = 0;
    for (auto c : mImpl->rays) total += c;
    return total;
}

}  // namespace penumbra
