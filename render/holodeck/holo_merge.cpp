#include "render/holodeck/holo_merge.h"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <map>
#include <queue>
#include <stdexcept>

#include "core/input_error.h"
#include "core/log.h"
#include "core/timing.h"

namespace penumbra {

namespace {

bool sameSections(const std::vector<HoloSection>& a, const std::vector<HoloSection>& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i)
        if (a[i].origin() != b[i].origin() || a[i].size() != b[i].size() ||
            a[i].grid() != b[i].grid() || a[i].kind() != b[i].kind())
            return false;
    return true;
}

/// Whether `shorter`'s samples are the first of `longer`'s, byte for byte.
bool isPrefix(const std::vector<HoloSample>& shorter, const std::vector<HoloSample>& longer) {
    return shorter.size() <= longer.size() &&
           (shorter.empty() ||
            std::memcmp(shorter.data(), longer.data(), shorter.size() * sizeof(HoloSample)) == 0);
}

bool sameFile(const std::string& a, const std::string& b) {
    std::error_code error;
    return std::filesystem::equivalent(a, b, error);
}

/// The merge's plan: a beam the target takes from a part.
struct Pick {
    int section;
    std::int64_t beam;
    std::size_t part;
};

}  // namespace

RankShare shareRequests(const std::vector<BeamRequest>& requests, std::int64_t samples, int ranks,
                        int rank) {
    if (ranks < 1 || rank < 0 || rank >= ranks)
        throw std::invalid_argument("holodeck: rank " + std::to_string(rank) + " of " +
                                    std::to_string(ranks));
    // Each request to the rank desiring the fewest samples so far.
    using Load = std::pair<double, int>;
    std::priority_queue<Load, std::vector<Load>, std::greater<Load>> least;
    for (int k = 0; k < ranks; ++k) least.emplace(0.0, k);
    std::vector<double> load(std::size_t(ranks), 0.0);
    RankShare share;
    for (const BeamRequest& r : requests) {
        if (!(r.desired > 0)) continue;
        const int k = least.top().second;
        least.pop();
        load[std::size_t(k)] += r.desired;
        least.emplace(load[std::size_t(k)], k);
        if (k == rank) share.requests.push_back(r);
    }
    // Rank k's samples: round(N·C(k+1)/C(ranks)) − round(N·C(k)/C(ranks)), C the cumulative
    // desired totals, so the shares sum to N exactly.
    std::vector<double> cumulative(std::size_t(ranks) + 1, 0.0);
    for (int k = 0; k < ranks; ++k)
        cumulative[std::size_t(k) + 1] = cumulative[std::size_t(k)] + load[std::size_t(k)];
    const double total = cumulative.back();
    if (!(total > 0)) {
        share.samples = rank == 0 ? samples : 0;
        return share;
    }
    auto upTo = [&](int k) {
        return std::int64_t(std::llround(double(samples) * cumulative[std::size_t(k)] / total));
    };
    share.samples = rank == ranks - 1 ? samples - upTo(rank) : upTo(rank + 1) - upTo(rank);
    return share;
}

std::int64_t seedPart(HoloFile& base, HoloFile& part, const std::vector<BeamRequest>& requests) {
    std::int64_t copied = 0;
    for (const BeamRequest& r : requests) {
        if (base.sampleCount(r.section, r.beam) == 0) continue;
        const std::vector<HoloSample> samples = base.readBeam(r.section, r.beam);
        if (samples.empty()) continue;
        part.writeBeam(r.section, r.beam, samples);
        copied += std::int64_t(samples.size());
    }
    part.commit();
    return copied;
}

HoloMergeStats mergeHoloParts(HoloFile& target, const std::vector<std::string>& parts) {
    const Clock::time_point start = Clock::now();
    // Open every part; each must be another file with the target's sections.
    std::vector<HoloFile> files;
    files.reserve(parts.size());
    for (const std::string& path : parts) {
        if (sameFile(path, target.path()))
            throw InputError(path, "", "is the merge's target itself");
        files.push_back(HoloFile::openReadOnly(path));
        if (!sameSections(files.back().sections(), target.sections()))
            throw InputError(path, "sections",
                             "differ from " + target.path() +
                                 "'s: a part must be filled from the same holodeck");
    }
    // Every beam a part holds, and the parts holding it.
    std::map<std::pair<int, std::int64_t>, std::vector<std::size_t>> holders;
    for (std::size_t k = 0; k < files.size(); ++k)
        for (const auto& key : files[k].storedBeams()) holders[key].push_back(k);

    // Plan: per beam, the longest holding; every other must be a prefix of it.
    HoloMergeStats stats;
    stats.parts = int(parts.size());
    std::vector<Pick> picks;
    for (const auto& [key, holding] : holders) {
        // Held by one part alone (a rank's own beam, new to the target): taken as it is.
        if (holding.size() == 1 && target.sampleCount(key.first, key.second) == 0) {
            picks.push_back({key.first, key.second, holding[0]});
            continue;
        }
        std::vector<HoloSample> longest = target.readBeam(key.first, key.second);
        const std::size_t had = longest.size();
        std::string longestName = target.path();
        std::int64_t held = 0;
        std::size_t from = files.size();
        for (const std::size_t k : holding) {
            std::vector<HoloSample> samples = files[k].readBeam(key.first, key.second);
            held += std::int64_t(samples.size());
            const bool longer = samples.size() > longest.size();
            if (!(longer ? isPrefix(longest, samples) : isPrefix(samples, longest)))
                throw InputError(
                    parts[k],
                    "section " + std::to_string(key.first) + " beam " + std::to_string(key.second),
                    "its " + std::to_string(samples.size()) + " samples disagree with the " +
                        std::to_string(longest.size()) + " of " + longestName +
                        " (another seed, scene or solution); nothing merged");
            if (longer) longest = std::move(samples), longestName = parts[k], from = k;
        }
        if (from < files.size()) picks.push_back({key.first, key.second, from});
        stats.samplesShared += held - std::int64_t(longest.size() - had);
    }
    spdlog::debug("holodeck merge: {} parts opened and {} beams planned in {:.0f} ms", parts.size(),
                  picks.size(), msSince(start));
    // Write the plan, a few megabytes of records at a time, and commit once.
    constexpr std::size_t kBatchSamples = std::size_t(1) << 20;
    std::vector<HoloFile::BeamSamples> batch;
    std::size_t batchSamples = 0;
    for (std::size_t i = 0; i < picks.size(); ++i) {
        const Pick& p = picks[i];
        const std::uint32_t had = target.sampleCount(p.section, p.beam);
        std::vector<HoloSample> samples = files[p.part].readBeam(p.section, p.beam);
        if (samples.size() > had) {  // else its record failed its checksum since
            ++stats.beams;
            stats.samplesAdded += std::int64_t(samples.size() - had);
            batchSamples += samples.size();
            batch.push_back({p.section, p.beam, std::move(samples)});
        }
        if (batchSamples >= kBatchSamples || i + 1 == picks.size()) {
            target.writeBeams(batch);
            batch.clear();
            batchSamples = 0;
        }
    }
    spdlog::debug("holodeck merge: {} beams written at {:.0f} ms", stats.beams, msSince(start));
    target.commit();
    spdlog::debug("holodeck merge: committed at {:.0f} ms", msSince(start));
    return stats;
}

}  // namespace penumbra
