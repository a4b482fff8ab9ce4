// The holodeck server: its LRU cache stays within the memory budget and hands back evicted
// beams from the file unchanged; filling follows the computed/desired order of §2.2; and every
// stored sample, decoded, is what the point shader gives for the same ray (within the
// encoding's bounds): a view drawn from the holodeck is a view shaded directly.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "core/random.h"
#include "holo_test_support.h"
#include "render/display/point_shader.h"
#include "render/holodeck/holo_server.h"
#include "solver/discretization.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

std::string tempFile(const std::string& name) {
    return test::holoTempFile("holo_server_test", name);
}

HoloSample marked(std::uint64_t beam, std::size_t i) {
    HoloSample s;
    s.rgbe = {std::uint8_t(beam), std::uint8_t(i), std::uint8_t(beam >> 8), 130};
    s.distance = std::uint16_t(i * 31 + beam);
    return s;
}

TEST(HoloServer, TheCacheStaysWithinItsBudgetAndEvictedBeamsComeBackUnchanged) {
    const std::string path = tempFile("lru.hdk");
    HoloFile file(path, {HoloSection(Vec3(0.0), Vec3(1.0), {4, 4, 4})});
    HoloServerOptions options;
    options.cacheBytes = 1000;  // 100 samples
    {
        HoloServer server(file, nullptr, options);
        for (int round = 0; round < 3; ++round) {
            for (std::int64_t beam = 0; beam < 60; ++beam) {
                std::vector<HoloSample> add;
                for (int i = 0; i < 4; ++i) add.push_back(marked(beam, round * 4 + i));
                server.addSamples(0, beam, add);
                ASSERT_LE(server.cachedBytes(), options.cacheBytes) << "beam " << beam;
            }
        }
        EXPECT_LT(server.cachedBeams(), 60u);
        for (std::int64_t beam = 59; beam >= 0; --beam) {
            const std::vector<HoloSample>& got = server.beam(0, beam);
            ASSERT_EQ(got.size(), 12u) << "beam " << beam;
            for (std::size_t i = 0; i < got.size(); ++i)
                EXPECT_EQ(got[i].distance, marked(beam, i).distance) << "beam " << beam;
            ASSERT_LE(server.cachedBytes(), options.cacheBytes);
        }
    }
    // The server flushed on its way out: all of it is in the file.
    HoloFile reopened(path, {});
    EXPECT_EQ(reopened.info().samples, 60 * 12);
}

using test::LitRoom;

TEST(HoloServer, FilledSamplesAreWhatTheShaderSeesAlongTheirRays) {
    LitRoom room;
    // An interior section inside the 3 m room (walls at ±1.5): 7,680 beams.
    const HoloSection section(Vec3(-1.45), Vec3(2.9), {4, 4, 4});
    const std::string path = tempFile("filled.hdk");
    HoloFile file(path, {section});
    HoloServerOptions options;
    options.packet = 2;
    HoloServer server(file, room.shader.get(), options);
    const auto requests = server.batchRequests(40000);
    const FillStats stats = server.fill(requests, 40000, 0);
    EXPECT_EQ(stats.samples, 40000);

    // §2.2's order: a beam gets a packet only while its computed/desired ratio is the lowest,
    // so before its last packet every beam's ratio was at most the lowest final one (up to the
    // packets shaded together in one round).
    double lowest = 1e300, worstBefore = 0;
    for (const BeamRequest& r : requests) {
        const double count = server.sampleCount(r.section, r.beam);
        lowest = std::min(lowest, count / r.desired);
        worstBefore = std::max(worstBefore, (count - options.packet) / r.desired);
    }
    EXPECT_GT(lowest, 0) << "a beam got nothing";
    EXPECT_LE(worstBefore, 1.1 * lowest) << "lowest " << lowest;

    // Every sample of a few hundred beams, decoded, against the shader on the same ray.
    const DistanceCode code(section.diagonal());
    int checked = 0;
    for (std::int64_t beam = 0; beam < section.beamCount() && checked < 3000; beam += 37) {
        const std::vector<HoloSample> samples = server.beam(0, beam);
        for (std::size_t i = 0; i < samples.size(); ++i) {
            const DecodedSample d = decodeSample(samples[i], section, beam, code);
            const auto [entry, exit] = server.sampleRay(0, beam, i);
            ShadeRequest request;
            request.origin = section.wallPoint(entry);
            request.direction = glm::normalize(section.wallPoint(exit) - request.origin);
            request.frame = hashPair(static_cast<std::uint64_t>(beam), i);
            request.pixel = glm::dvec2(0.0);
            const ShadedPoint p = room.shader->shade(request);
            ASSERT_LT(glm::length(d.entry - request.origin), 1e-12) << "beam " << beam;
            ASSERT_LT(glm::length(d.direction - request.direction), 1e-12) << "beam " << beam;
            const double largest = std::max({p.radiance.x, p.radiance.y, p.radiance.z});
            EXPECT_LE(glm::length(d.radiance - p.radiance), std::sqrt(3.0) * largest / 256 + 1e-12)
                << "beam " << beam << " sample " << i;
            const double distance = glm::length(p.position - request.origin);
            EXPECT_LE(glm::length(d.hit - p.position),
                      std::max(0.5 * section.diagonal() / 2048, distance / 4096) + 1e-9)
                << "beam " << beam << " sample " << i;
            ++checked;
        }
    }
    EXPECT_GT(checked, 400);
}

}  // namespace
}  // namespace penumbra
