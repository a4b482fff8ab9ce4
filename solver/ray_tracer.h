#pragma once
// The one owner of Embree: device, one geometry scene per object, a top-level scene of
// instances. A move is an instance transform update and a top-level commit.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "solver/scene.h"

struct RTCDeviceTy;
struct RTCSceneTy;

namespace penumbra {

class Discretization;

/// Which objects block a visibility query. By default the current scene (alive objects).
/// `ignoreObject` removes one object from it; `world`, when set, replaces it: exactly the
/// objects o with (*world)[o] != 0 block, alive or not (redistribution evaluates form factors
/// in the scene as it was before and after an edit).
struct Visibility {
    Visibility() = default;
    Visibility(int ignore) : ignoreObject(ignore) {}  // NOLINT: an object index converts
    int ignoreObject = -1;
    const std::vector<std::uint8_t>* world = nullptr;
    /// When ≥ 0, replaces both: exactly the objects of RayTracer::createSubset(…) `subset`
    /// block, through a small top-level scene of their own (no filter, so a query costs the
    /// subset, not the scene).
    int subset = -1;
};

struct RayHit {
    int object = -1;   ///< -1: no hit
    int element = -1;  ///< element index in the Discretization
    double t = 0;
    Vec3 position{0};
    Vec3 geometricNormal{0};  ///< world space, unit, front side of the element
    bool backFace = false;    ///< the ray arrived at the back of the surface
    /// Barycentric weights of the hit over the element's vertices (same order as
    /// Element::vertices).
    std::vector<double> weights;
};

class RayTracer {
public:
    /// Builds one instanced geometry per object of `discretization` (which must outlive this).
    explicit RayTracer(const Discretization& discretization);
    ~RayTracer();
    RayTracer(const RayTracer&) = delete;
    RayTracer& operator=(const RayTracer&) = delete;

    /// Rebuilds everything after the discretization changed (subdivision).
    void rebuild();
    /// Adds the geometry of a new object of the discretization (an object version).
    void addObject(int object);
    /// Follows ObjectSurface::alive of `object`: a dead object stops blocking current-scene
    /// queries but stays available to `Visibility::world` queries.
    void updateAlive(int object);

    /// A top-level scene holding only `objects` (any versions, alive or not), for queries
    /// that only care whether a ray meets those objects (Visibility::subset). Hits equal the
    /// history scene's for those objects: the same instances and transforms. Cheap for a few
    /// objects; kept across rebuild() until released.
    int createSubset(const std::vector<int>& objects);
    void releaseSubset(int subset);
    /// Owns a subset: released when destroyed. Move-only.
    class SubsetHandle {
    public:
        SubsetHandle() = default;
        SubsetHandle(RayTracer& tracer, const std::vector<int>& objects)
            : mTracer(&tracer), mId(tracer.createSubset(objects)) {}
        SubsetHandle(SubsetHandle&& o) noexcept : mTracer(o.mTracer), mId(o.mId) { o.mId = -1; }
        SubsetHandle& operator=(SubsetHandle&& o) noexcept {
            if (this != &o) {
                reset();
                mTracer = o.mTracer, mId = o.mId, o.mId = -1;
            }
            return *this;
        }
        SubsetHandle(const SubsetHandle&) = delete;
        SubsetHandle& operator=(const SubsetHandle&) = delete;
        ~SubsetHandle() { reset(); }
        void reset() {
            if (mTracer && mId >= 0) mTracer->releaseSubset(mId);
            mId = -1;
        }
        /// A Visibility admitting exactly the subset's objects.
        Visibility visibility() const {
            Visibility v;
            v.subset = mId;
            return v;
        }
        int id() const { return mId; }

    private:
        RayTracer* mTracer = nullptr;
        int mId = -1;
    };

    /// True when the open segment from `from` to `to` is blocked (traced as the direction
    /// to − from over t in [0, 1]; false for an empty or non-finite segment).
    bool occluded(const Vec3& from, const Vec3& to, const Visibility& visibility = {}) const;

    /// Occlusion of up to 16 segments sharing the start `from` (one coherent packet of 4, 8 or
    /// 16: rtcOccluded4/8/16): blocked[i] for the segment to to[i], as occluded() would answer.
    void occludedPacket(const Vec3& from, const Vec3* to, int count, bool* blocked,
                        const Visibility& visibility = {}) const;

    /// Nearest hit along origin + t·dir, t in (tNear, tFar).
    RayHit intersect(const Vec3& origin, const Vec3& dir, double tNear = 0.0, double tFar = 1e30,
                     const Visibility& visibility = {}) const;
    /// The element first hit along origin + t·dir (t > 0) and whether its back was hit;
    /// element -1 for a miss. The allocation-free query stochastic shooting uses.
    struct FirstHit {
        int element = -1;
        bool backFace = false;
        float t = 0;      ///< ray parameter of the hit (unit direction: distance)
        int patch = -1;   ///< the element's patch and area, from the tracer's own table
        double area = 0;  ///< (the element's record is a cache miss in large scenes)
    };
    FirstHit firstHit(const Vec3& origin, const Vec3& dir, const Visibility& visibility = {}) const;
    /// firstHit for `count` rays (any number) at once, the same answers as one call each:
    /// all rays are traced first, each prefetching the tracer's record of the triangle it
    /// hit, then the records are read. A stochastic batch's hits land anywhere in a large
    /// scene, and reading the record right after its ray was one cache miss per ray.
    void firstHits(const Vec3* origins, const Vec3* dirs, int count, FirstHit* hits,
                   const Visibility& visibility = {}) const;

    /// Rays traced since construction (occlusion and intersection), for reports.
    unsigned long long rayCount() const;
    /// Scene-size-relative offset used to leave surfaces without self-hits.
    double epsilon() const { return mEpsilon; }

private:
    struct Impl;
    std::unique_ptr<Impl> mImpl;
    const Discretization& mDisc;
    double mEpsilon = 1e-5;
};

}  // namespace penumbra
