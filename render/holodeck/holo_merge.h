#pragma once
// Batch filling by several processes (docs/holodeck.md, "Scale-out"): the beam requests shared
// among ranks, a rank's part file started from the target's samples of its beams, and the
// parts merged into the target without duplicate samples.
//
// Why merging never duplicates: a sample's ray depends only on (seed, section, beam, index) and
// its shading only on the solution and that ray (HoloServer::sampleRay, shadeSamples), and a
// fill continues a beam from the samples it holds. So every file filled from one holodeck with
// one seed holds, per beam, a prefix of one sequence of samples: of two holdings of a beam one
// is a prefix of the other, and the merge keeps the longer. A beam whose holdings disagree
// (another seed, another scene or solution, a display's stored points in one of them) cannot
// be merged sample for sample; the merge refuses it before writing anything.
//
// Index: RankShare · shareRequests · seedPart · HoloMergeStats · mergeHoloParts

#include <cstdint>
#include <string>
#include <vector>

#include "render/holodeck/holo_file.h"
#include "render/holodeck/holo_server.h"

namespace penumbra {

/// One rank's part of a fill.
struct RankShare {
    std::vector<BeamRequest> requests;  ///< in the order of the requests given
    std::int64_t samples = 0;           ///< its part of the total, by desired samples
};

/// Rank `rank` of `ranks`' share: each request goes, in order, to the rank whose requests
/// desire the fewest samples so far (ties: the lowest rank), so that every rank's desired total
/// is within one request of the others' and the beams interleave; `samples` is split in
/// proportion to the desired totals, summing exactly to it over the ranks. Every rank computes
/// the same split from the same requests.
RankShare shareRequests(const std::vector<BeamRequest>& requests, std::int64_t samples, int ranks,
                        int rank);

/// Copies `base`'s samples of the requested beams into `part` (which must have its sections)
/// and commits, so that a fill of `part` continues those beams where `base` ends them. Returns
/// the samples copied.
std::int64_t seedPart(HoloFile& base, HoloFile& part, const std::vector<BeamRequest>& requests);

/// What a merge did.
struct HoloMergeStats {
    int parts = 0;
    std::int64_t beams = 0;         ///< beams the target took from a part (new or longer)
    std::int64_t samplesAdded = 0;  ///< samples the target gained
    /// Samples of the parts the target already held or took from another part, kept once.
    std::int64_t samplesShared = 0;
};

/// Merges the part files at `parts` into `target` (opened writable) and commits once: for every
/// beam a part holds, the longest of the target's and the parts' holdings, which must each be a
/// prefix of it. Reads everything before writing: throws InputError naming the part, and writes
/// nothing, when a part cannot be opened, has other sections than the target, is the target
/// itself, or holds a beam that disagrees with the target's or an earlier part's. A merge killed
/// part way leaves the target as it was or with some of its beams merged; merging the same
/// parts again completes it. The parts are left as they are.
HoloMergeStats mergeHoloParts(HoloFile& target, const std::vector<std::string>& parts);

}  // namespace penumbra
