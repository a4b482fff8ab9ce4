#include "render/holodeck/holo_server.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <queue>
#include <stdexcept>

#include "core/log.h"
#include "core/random.h"
#include "core/timing.h"
#include "render/camera_rays.h"
#include "render/display/point_shader.h"
#include "solver/ray_tracer.h"

namespace penumbra {

std::vector<BeamRequest> viewRequests(const std::vector<HoloSection>& sections,
                                      const CameraRays& camera, int raysX, int raysY,
                                      double samplesPerRay, std::uint64_t seed) {
    std::map<std::pair<int, std::int64_t>, int> hits;
    for (int j = 0; j < raysY; ++j) {
        for (int i = 0; i < raysX; ++i) {
            const std::uint64_t r = splitmix64(hashPair(seed, std::uint64_t(j) * raysX + i));
            const double px = (i + double(r & 0xffff) / 65536.0) * camera.width() / raysX;
            const double py = (j + double((r >> 16) & 0xffff) / 65536.0) * camera.height() / raysY;
            const Vec3 d = camera.rayDirection(px, py);
            for (int s = 0; s < int(sections.size()); ++s)
                if (const auto ray = sections[s].locate(camera.origin(), d)) ++hits[{s, ray->beam}];
        }
    }
    std::vector<BeamRequest> requests;
    requests.reserve(hits.size());
    for (const auto& [key, count] : hits)
        requests.push_back({key.first, key.second, count * samplesPerRay});
    return requests;
}

std::size_t HoloServer::KeyHash::operator()(const Key& k) const {
    return static_cast<std::size_t>(
        hashPair(std::uint64_t(k.section), static_cast<std::uint64_t>(k.beam)));
}

HoloServer::HoloServer(HoloFile& file, const PointShader* shader, HoloServerOptions options)
    : mFile(file), mShader(shader), mOptions(options) {
    if (mOptions.packet < 1) throw std::invalid_argument("holodeck server: packet must be >= 1");
    for (const HoloSection& s : mFile.sections()) mCodes.emplace_back(s.diagonal());
}

HoloServer::~HoloServer() {
    try {
        flush();
    } catch (const std::exception& e) {
        spdlog::error("holodeck: {}", e.what());
    }
}

HoloServer::Cached& HoloServer::touch(const Key& key) {
    auto it = mCache.find(key);
    if (it != mCache.end()) {
        mLru.splice(mLru.begin(), mLru, it->second.lru);
        return it->second;
    }
    Cached& c = mCache[key];
    c.samples = mFile.readBeam(key.section, key.beam);
    mCachedBytes += c.samples.size() * sizeof(HoloSample);
    mLru.push_front(key);
    c.lru = mLru.begin();
    return c;
}

void HoloServer::evict() {
    // Least recently used first; the most recent beam stays even when alone over the budget.
    while (mCachedBytes > mOptions.cacheBytes && mLru.size() > 1) {
        const Key key = mLru.back();
        auto it = mCache.find(key);
        if (it->second.dirty) {
            mFile.writeBeam(key.section, key.beam, it->second.samples);
            mWritten = true;
        }
        mCachedBytes -= it->second.samples.size() * sizeof(HoloSample);
        mCache.erase(it);
        mLru.pop_back();
    }
}

const std::vector<HoloSample>& HoloServer::beam(int section, std::int64_t beam) {
    Cached& c = touch({section, beam});
    evict();
    return c.samples;
}

void HoloServer::addSamples(int section, std::int64_t beam,
                            const std::vector<HoloSample>& samples) {
    if (samples.empty()) return;
    Cached& c = touch({section, beam});
    c.samples.insert(c.samples.end(), samples.begin(), samples.end());
    c.dirty = true;
    mCachedBytes += samples.size() * sizeof(HoloSample);
    evict();
}

void HoloServer::flush() {
    bool wrote = mWritten;
    for (auto& [key, c] : mCache) {
        if (!c.dirty) continue;
        mFile.writeBeam(key.section, key.beam, c.samples);
        c.dirty = false;
        wrote = true;
    }
    if (wrote) mFile.commit();
    mWritten = false;
}

std::uint32_t HoloServer::sampleCount(int section, std::int64_t beam) const {
    const auto it = mCache.find({section, beam});
    if (it != mCache.end()) return static_cast<std::uint32_t>(it->second.samples.size());
    return mFile.sampleCount(section, beam);
}

std::pair<WallPoint, WallPoint> HoloServer::sampleRay(int section, std::int64_t beam,
                                                      std::uint64_t index) const {
    // §2.3: four random bytes, the ray's positions within its entry and exit cells.
    const std::uint64_t r = splitmix64(hashPair(hashPair(mOptions.seed, std::uint64_t(section)),
                                                hashPair(std::uint64_t(beam), index)));
    const auto [entryCell, exitCell] = mFile.sections()[section].beamCells(beam);
    return {WallPoint{entryCell, decodeCellPosition(std::uint8_t(r)),
                      decodeCellPosition(std::uint8_t(r >> 8))},
            WallPoint{exitCell, decodeCellPosition(std::uint8_t(r >> 16)),
                      decodeCellPosition(std::uint8_t(r >> 24))}};
}

std::vector<HoloSample> HoloServer::shadeSamples(int section, std::int64_t beam,
                                                 std::uint64_t first, int count) const {
    const HoloSection& s = mFile.sections()[section];
    std::vector<HoloSample> out;
    out.reserve(std::size_t(count));
    for (int i = 0; i < count; ++i) {
        const std::uint64_t index = first + std::uint64_t(i);
        const auto [entry, exit] = sampleRay(section, beam, index);
        ShadeRequest request;
        request.origin = s.wallPoint(entry);
        request.direction = glm::normalize(s.wallPoint(exit) - request.origin);
        // The shader's pattern is seeded by (pixel, frame): the sample's own hash here.
        request.frame = hashPair(static_cast<std::uint64_t>(beam), index);
        request.pixel = glm::dvec2(double(section), 0.0);
        const ShadedPoint p = mShader->shade(request);
        // A miss lies "at infinity": the largest distance the code holds.
        const double distance = p.object < 0 ? 1e300 : glm::length(p.position - request.origin);
        out.push_back(encodeSample(p.radiance, entry, exit, distance, mCodes[section]));
    }
    return out;
}

std::vector<BeamRequest> HoloServer::batchRequests(double totalDesired) const {
    std::vector<BeamRequest> requests;
    double volume = 0;
    for (int s = 0; s < int(mFile.sections().size()); ++s) {
        const HoloSection& section = mFile.sections()[s];
        for (std::int64_t b = 0; b < section.beamCount(); ++b) {
            const double v = section.beamVolume(b);
            volume += v;
            requests.push_back({s, b, v});
        }
    }
    for (BeamRequest& r : requests) r.desired *= volume > 0 ? totalDesired / volume : 0;
    return requests;
}

FillStats HoloServer::fill(const std::vector<BeamRequest>& requests, std::int64_t maxSamples,
                           double seconds, double commitSeconds,
                           const std::function<void(double)>& progress) {
    if (!mShader) throw std::logic_error("holodeck: fill without a shader (display-only mode)");
    if (maxSamples <= 0 && !(seconds > 0))
        throw std::invalid_argument("holodeck: fill needs a sample count or a time limit");
    const Clock::time_point start = Clock::now();
    // The queue of §2.2: increasing computed/desired ratio (ties: request order).
    using Item = std::pair<double, std::size_t>;
    std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
    std::vector<std::uint32_t> computed(requests.size());
    for (std::size_t i = 0; i < requests.size(); ++i) {
        if (!(requests[i].desired > 0)) continue;
        computed[i] = sampleCount(requests[i].section, requests[i].beam);
        queue.emplace(computed[i] / requests[i].desired, i);
    }
    FillStats stats;
    std::vector<bool> touched(requests.size(), false);
    double lastCommit = 0;
    // Packets from the head of the queue, shaded in parallel, then stored in order.
    constexpr std::size_t kPacketsPerRound = 256;
    struct Packet {
        std::size_t request;
        int count;
        std::vector<HoloSample> samples;
    };
    std::vector<Packet> packets;
    while (!queue.empty()) {
        const double elapsed = secondsSince(start);
        if ((maxSamples > 0 && stats.samples >= maxSamples) || (seconds > 0 && elapsed >= seconds))
            break;
        packets.clear();
        std::int64_t planned = stats.samples;
        while (!queue.empty() && packets.size() < kPacketsPerRound &&
               (maxSamples <= 0 || planned < maxSamples)) {
            const std::size_t i = queue.top().second;
            queue.pop();
            // A quarter of the beam's desired samples at a time (1 to `packet`): batch filling
            // spreads over every beam before it deepens any.
            int count = std::clamp(int(std::ceil(0.25 * requests[i].desired)), 1, mOptions.packet);
            if (maxSamples > 0) count = int(std::min<std::int64_t>(count, maxSamples - planned));
            planned += count;
            packets.push_back({i, count, {}});
        }
        tbb::parallel_for(std::size_t(0), packets.size(), [&](std::size_t k) {
            const BeamRequest& r = requests[packets[k].request];
            packets[k].samples =
                shadeSamples(r.section, r.beam, computed[packets[k].request], packets[k].count);
        });
        for (Packet& p : packets) {
            const BeamRequest& r = requests[p.request];
            addSamples(r.section, r.beam, p.samples);
            computed[p.request] += std::uint32_t(p.samples.size());
            stats.samples += std::int64_t(p.samples.size());
            if (!touched[p.request]) touched[p.request] = true, ++stats.beams;
            queue.emplace(computed[p.request] / r.desired, p.request);
        }
        if (secondsSince(start) - lastCommit >= commitSeconds) {
            flush();
            lastCommit = secondsSince(start);
        }
        if (progress) {
            const double bySamples = maxSamples > 0 ? double(stats.samples) / maxSamples : 0;
            const double byTime = seconds > 0 ? secondsSince(start) / seconds : 0;
            progress(std::min(1.0, std::max(bySamples, byTime)));
        }
    }
    flush();
    stats.seconds = secondsSince(start);
    return stats;
}

Invalidation HoloServer::invalidate(const RayTracer& tracer,
                                    const std::vector<std::uint8_t>& elementChanged) {
    // Every beam holding samples: on file, and in memory only.
    std::vector<std::pair<int, std::int64_t>> beams = mFile.storedBeams();
    for (const auto& [key, c] : mCache)
        if (!c.samples.empty() && mFile.sampleCount(key.section, key.beam) == 0)
            beams.emplace_back(key.section, key.beam);
    Invalidation result;
    // In chunks, so that the samples of a chunk's beams are held at once, not the whole file.
    constexpr std::size_t kChunk = 512;
    std::vector<std::vector<HoloSample>> samples;
    std::vector<std::vector<HoloSample>> kept;
    for (std::size_t first = 0; first < beams.size(); first += kChunk) {
        const std::size_t n = std::min(kChunk, beams.size() - first);
        samples.assign(n, {});
        kept.assign(n, {});
        for (std::size_t k = 0; k < n; ++k)
            samples[k] = beam(beams[first + k].first, beams[first + k].second);
        tbb::parallel_for(std::size_t(0), n, [&](std::size_t k) {
            const auto [section, b] = beams[first + k];
            const HoloSection& s = mFile.sections()[section];
            const DistanceCode& code = mCodes[section];
            for (const HoloSample& sample : samples[k]) {
                const DecodedSample d = decodeSample(sample, s, b, code);
                const RayTracer::FirstHit hit = tracer.firstHit(d.entry, d.direction);
                const bool storedMiss = sample.distance == 0xffff;
                bool same = (hit.element < 0) == storedMiss;
                if (same && !storedMiss) {
                    // The stored distance is the hit's to within its code's step.
                    const double stored = code.decode(sample.distance);
                    const double tolerance =
                        std::max(s.diagonal() / 4096, stored / 4096) * 1.01 + 1e-6 * stored;
                    same = std::abs(double(hit.t) - stored) <= tolerance &&
                           std::size_t(hit.element) < elementChanged.size() &&
                           !elementChanged[std::size_t(hit.element)];
                }
                if (same) kept[k].push_back(sample);
            }
        });
        for (std::size_t k = 0; k < n; ++k) {
            const std::int64_t dropped = std::int64_t(samples[k].size() - kept[k].size());
            result.kept += std::int64_t(kept[k].size());
            if (dropped == 0) continue;
            result.samples += dropped;
            ++result.beams;
            // Replaced in memory and on file.
            const Key key{beams[first + k].first, beams[first + k].second};
            auto it = mCache.find(key);
            if (it != mCache.end()) {
                mCachedBytes -= it->second.samples.size() * sizeof(HoloSample);
                mLru.erase(it->second.lru);
                mCache.erase(it);
            }
            mFile.writeBeam(key.section, key.beam, kept[k]);
            mWritten = true;
        }
    }
    flush();
    return result;
}

}  // namespace penumbra
