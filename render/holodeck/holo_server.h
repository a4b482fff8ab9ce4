#pragma once
// The holodeck server (Ward & Simmons 1999, §2.2–2.3): keeps the most recently used beams in
// memory under a byte budget (least recently used beams go to the file when it is full),
// answers requests for beams and fills them with new samples, shaded by the display's point
// shader, in the paper's order: the beam whose computed/desired sample ratio is lowest first.
// Batch mode desires samples in proportion to each beam's volume; a display asks for the beams
// of its view. Without a shader the server only reads (the paper's display-only mode).
//
// Index: HoloServerOptions · BeamRequest · viewRequests · Invalidation · HoloServer

#include <cstdint>
#include <functional>
#include <list>
#include <unordered_map>
#include <vector>

#include "render/holodeck/holo_file.h"

namespace penumbra {

class CameraRays;
class PointShader;
class RayTracer;

struct HoloServerOptions {
    std::size_t cacheBytes = std::size_t(64)
                             << 20;  ///< samples held in memory (the paper: 8–24 MB)
    /// The most samples computed for a beam at a time (the paper's packets hold 1 to 21); a
    /// beam takes a quarter of its desired samples at a time, at least one.
    int packet = 8;
    std::uint64_t seed = 1;  ///< sample positions depend on (seed, section, beam, index) only
};

/// A beam wanted with `desired` samples in all.
struct BeamRequest {
    int section = 0;
    std::int64_t beam = 0;
    double desired = 0;
};

/// The beams a view needs (§2.4.2): view rays on a jittered `raysX` × `raysY` grid over the
/// image, located in every section; each beam is desired `samplesPerRay` samples per view ray
/// through it (a density matched to the view's pixels). Sorted by section and beam.
std::vector<BeamRequest> viewRequests(const std::vector<HoloSection>& sections,
                                      const CameraRays& camera, int raysX, int raysY,
                                      double samplesPerRay, std::uint64_t seed = 1);

/// What an edit took from the holodeck.
struct Invalidation {
    std::int64_t beams = 0;    ///< beams that lost samples
    std::int64_t samples = 0;  ///< samples dropped
    std::int64_t kept = 0;     ///< samples checked and kept
};

/// What a fill did.
struct FillStats {
    std::int64_t samples = 0;  ///< new samples
    std::int64_t beams = 0;    ///< beams that got some
    double seconds = 0;
};

class HoloServer {
public:
    /// `file` and `shader` must outlive the server; `shader` may be null (display only).
    HoloServer(HoloFile& file, const PointShader* shader, HoloServerOptions options = {});
    /// Writes what is only in memory and commits (flush()).
    ~HoloServer();
    HoloServer(const HoloServer&) = delete;
    HoloServer& operator=(const HoloServer&) = delete;

    /// Forgets exactly what an edit changed: every stored sample's ray is traced again in the
    /// scene as it is now (`tracer`, after the edit); a sample goes when its ray now ends at
    /// another distance (geometry moved into or out of it, or its surface moved) or on an
    /// element whose lighting changed beyond the caller's threshold (`elementChanged`, indexed
    /// by the tracer's elements; elements past its end count as changed). Everything else is
    /// kept. Rays on oneTBB's threads, beam by beam; changed beams are written at once.
    Invalidation invalidate(const RayTracer& tracer,
                            const std::vector<std::uint8_t>& elementChanged);

    /// A beam's samples, loaded from the file when not in memory (it becomes the most recently
    /// used). The reference is valid until the next call that loads or adds samples.
    const std::vector<HoloSample>& beam(int section, std::int64_t beam);
    /// Appends samples to a beam (in memory; written when evicted or flushed).
    void addSamples(int section, std::int64_t beam, const std::vector<HoloSample>& samples);
    /// Writes every beam changed in memory to the file and commits it (nothing changed:
    /// nothing written, so a display-only server never writes).
    void flush();

    /// Computes samples for `requests` until `maxSamples` new samples or `seconds` have
    /// passed (either may be 0: no limit; not both), taking packets from the beam whose
    /// computed/desired ratio is lowest (§2.2), with the shader on oneTBB's threads; commits
    /// every `commitSeconds`. `progress` (may be empty) gets the fraction done.
    FillStats fill(const std::vector<BeamRequest>& requests, std::int64_t maxSamples,
                   double seconds, double commitSeconds = 5.0,
                   const std::function<void(double)>& progress = {});
    /// Batch mode: every beam of every section desired in proportion to its volume, so that
    /// `totalDesired` samples over all beams would meet every target.
    std::vector<BeamRequest> batchRequests(double totalDesired) const;

    /// The ray of sample `index` of a beam: its entry and exit positions (byte-exact, so the
    /// stored sample places them without error).
    std::pair<WallPoint, WallPoint> sampleRay(int section, std::int64_t beam,
                                              std::uint64_t index) const;
    /// Samples of a beam, in memory or on file.
    std::uint32_t sampleCount(int section, std::int64_t beam) const;
    /// Bytes of samples held in memory; at most options.cacheBytes after every call (one beam
    /// larger than the budget is held alone).
    std::size_t cachedBytes() const { return mCachedBytes; }
    std::size_t cachedBeams() const { return mCache.size(); }
    HoloFile& file() { return mFile; }
    /// The distance code of a section (its diagonal's), shared by everything that decodes it.
    const DistanceCode& distanceCode(int section) const { return mCodes[std::size_t(section)]; }

private:
    struct Key {
        int section;
        std::int64_t beam;
        bool operator==(const Key& o) const { return section == o.section && beam == o.beam; }
    };
    struct KeyHash {
        std::size_t operator()(const Key& k) const;
    };
    struct Cached {
        std::vector<HoloSample> samples;
        bool dirty = false;
        std::list<Key>::iterator lru;
    };
    Cached& touch(const Key& key);
    void evict();
    /// Shades `count` new samples of a beam, from index `first` (thread-safe).
    std::vector<HoloSample> shadeSamples(int section, std::int64_t beam, std::uint64_t first,
                                         int count) const;

    HoloFile& mFile;
    const PointShader* mShader;
    HoloServerOptions mOptions;
    std::vector<DistanceCode> mCodes;  ///< per section
    std::unordered_map<Key, Cached, KeyHash> mCache;
    std::list<Key> mLru;  ///< most recently used first
    std::size_t mCachedBytes = 0;
    bool mWritten = false;  ///< beams evicted to the file since the last commit
};

}  // namespace penumbra
