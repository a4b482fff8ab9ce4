// After an edit the holodeck forgets exactly what changed. A box moves across a lit room: the
// samples whose rays met the box where it was, or meet it where it is now, before their stored
// hit (found by an analytic ray–box test, not the tracer) go, and only they. A relit floor:
// exactly the samples that hit the floor go.

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <limits>
#include <map>
#include <set>

#include "render/display/point_shader.h"
#include "render/holodeck/holo_server.h"
#include "solver/discretization.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

/// The room of makeLitRoom without its slab, and an axis-aligned box of half-size 0.3 at `at`.
Scene roomWithBox(const Vec3& at) {
    Scene scene = test::makeLitRoom("red");
    scene.objects.erase(std::remove_if(scene.objects.begin(), scene.objects.end(),
                                       [](const SceneObject& o) { return o.id == "slab"; }),
                        scene.objects.end());
    SceneObject box;
    box.id = "box";
    box.shape.type = ShapeType::Box;
    box.shape.size = Vec3(0.6);
    box.material = "white";
    box.transform.translate = at;
    scene.objects.push_back(box);
    return scene;
}

/// The parameter at which the ray enters the box [c − h, c + h] (slabs); infinity on a miss.
double rayBox(const Vec3& o, const Vec3& d, const Vec3& c, double h) {
    double t0 = 0, t1 = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
        if (d[a] == 0) {
            if (std::abs(o[a] - c[a]) > h) return std::numeric_limits<double>::infinity();
            continue;
        }
        double ta = (c[a] - h - o[a]) / d[a], tb = (c[a] + h - o[a]) / d[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    return t0 <= t1 ? t0 : std::numeric_limits<double>::infinity();
}

/// Where a ray from inside makeLitRoom's room meets its walls or its lamp (a 0.6 m square at
/// y = 1.49, facing down).
double roomHit(const Vec3& o, const Vec3& d) {
    double t = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a)
        if (d[a] != 0) t = std::min(t, ((d[a] > 0 ? 1.5 : -1.5) - o[a]) / d[a]);
    if (d.y > 0) {
        const double tl = (1.49 - o.y) / d.y;
        const Vec3 p = o + tl * d;
        if (std::abs(p.x) <= 0.3 && std::abs(p.z) <= 0.3) t = std::min(t, tl);
    }
    return t;
}

/// A lit room solved, a shader over it, and a holodeck filled from it.
struct Filled {
    Scene scene;
    Discretization disc;
    RayTracer tracer;
    SolverOptions options;
    ProgressiveSolver solver;
    std::unique_ptr<PointShader> shader;
    HoloSection section{Vec3(-1.45), Vec3(2.9), {4, 4, 4}};
    explicit Filled(Scene s)
        : scene(std::move(s)), disc(scene), tracer(disc), solver(disc, tracer, options) {
        solver.converge(1e-2, 100000);
        PointShaderOptions o;
        o.threads = 0;
        shader = std::make_unique<PointShader>(disc, tracer, options, o);
        shader->updateSolution(solver);
    }
    std::string fill(const std::string& name) {
        const fs::path dir =
            fs::temp_directory_path() / ("penumbra_holo_invalidate_" + std::to_string(::getpid()));
        fs::create_directories(dir);
        const std::string path = (dir / name).string();
        fs::remove(path);
        HoloFile file(path, {section});
        HoloServer server(file, shader.get());
        server.fill(server.batchRequests(30000), 30000, 0);
        return path;
    }
};

/// Every stored sample, decoded, by beam.
std::map<std::int64_t, std::vector<DecodedSample>> decodeAll(HoloFile& file) {
    std::map<std::int64_t, std::vector<DecodedSample>> out;
    const HoloSection& s = file.sections()[0];
    const DistanceCode code(s.diagonal());
    for (const auto& [section, beam] : file.storedBeams())
        for (const HoloSample& sample : file.readBeam(section, beam))
            out[beam].push_back(decodeSample(sample, s, beam, code));
    return out;
}

TEST(HoloInvalidate, AMovedBoxTakesExactlyTheSamplesItsOldAndNewPlacesCross) {
    const Vec3 from(-0.6, -1.2, -0.5), to(0.7, -1.2, 0.6);
    Filled before(roomWithBox(from));
    const std::string path = before.fill("moved.hdk");
    const Scene afterScene = roomWithBox(to);
    const Discretization afterDisc(afterScene);
    const RayTracer afterTracer(afterDisc);

    HoloFile file(path, {});
    const auto samples = decodeAll(file);
    // The answer, analytically: a sample goes when its ray reaches either box before (or at)
    // its stored hit. Rays grazing a box within the distance code's step are left out.
    const double step = file.sections()[0].diagonal() / 4096 * 1.5;
    std::int64_t expectedDropped = 0, total = 0, ambiguous = 0;
    std::set<std::int64_t> expectedBeams, ambiguousBeams;
    for (const auto& [beam, list] : samples) {
        for (const DecodedSample& d : list) {
            const double stored = glm::length(d.hit - d.entry);
            const double tOld = rayBox(d.entry, d.direction, from, 0.3);
            const double tNew = rayBox(d.entry, d.direction, to, 0.3);
            ++total;
            const bool crossed = std::min(tOld, tNew) <= stored + step;
            // Changes within the distance code's step cannot be seen: a ray that hit the old
            // box next to the floor it stood on now ends on the floor as far away; the new box's
            // surface lies where a ray ended.
            const double now = std::min(tNew, roomHit(d.entry, d.direction));
            if ((crossed && std::abs(now - stored) <= 2 * step) ||
                (!crossed && std::abs(tNew - stored) < 2 * step)) {
                ++ambiguous;
                ambiguousBeams.insert(beam);
                continue;
            }
            if (crossed) {
                ++expectedDropped;
                expectedBeams.insert(beam);
            }
        }
    }
    ASSERT_GT(expectedDropped, 100);
    ASSERT_LT(ambiguous, total / 100);

    HoloServer server(file, nullptr);
    const Invalidation result =
        server.invalidate(afterTracer, std::vector<std::uint8_t>(afterDisc.elements().size(), 0));
    EXPECT_GE(result.samples, expectedDropped);
    EXPECT_LE(result.samples, expectedDropped + ambiguous);
    EXPECT_EQ(result.samples + result.kept, total);
    // Beam by beam: every beam expected loses samples; no other does (ambiguous ones aside).
    const auto after = decodeAll(file);
    for (const auto& [beam, list] : samples) {
        const std::size_t left = after.count(beam) ? after.at(beam).size() : 0;
        if (expectedBeams.count(beam)) {
            EXPECT_LT(left, list.size()) << "beam " << beam << " kept everything";
        } else if (!ambiguousBeams.count(beam)) {
            EXPECT_EQ(left, list.size()) << "beam " << beam << " lost samples";
        }
    }
    EXPECT_GE(result.beams, std::int64_t(expectedBeams.size()));
}

TEST(HoloInvalidate, ARelitFloorTakesExactlyTheSamplesThatHitTheFloor) {
    Filled room(roomWithBox(Vec3(0.5, -1.2, 0.5)));
    const std::string path = room.fill("relit.hdk");
    std::vector<std::uint8_t> changed(room.disc.elements().size(), 0);
    for (std::size_t e = 0; e < changed.size(); ++e)
        changed[e] = room.disc.objects()[room.disc.elements()[e].object].id == "floor";
    HoloFile file(path, {});
    const auto samples = decodeAll(file);
    const double step = file.sections()[0].diagonal() / 4096 * 1.5;
    std::int64_t onFloor = 0, total = 0, ambiguous = 0;
    for (const auto& [beam, list] : samples) {
        for (const DecodedSample& d : list) {
            ++total;
            const bool floor = std::abs(d.hit.y + 1.5) < step;
            // Hits where the floor meets a wall or the box are left out.
            const bool corner =
                std::abs(std::abs(d.hit.x) - 1.5) < step ||
                std::abs(std::abs(d.hit.z) - 1.5) < step ||
                rayBox(d.hit, Vec3(0, 1, 0), Vec3(0.5, -1.2, 0.5), 0.3 + step) < 1e300;
            if (floor && corner) {
                ++ambiguous;
                continue;
            }
            onFloor += floor;
        }
    }
    ASSERT_GT(onFloor, 1000);
    HoloServer server(file, nullptr);
    const Invalidation result = server.invalidate(room.tracer, changed);
    EXPECT_GE(result.samples, onFloor);
    EXPECT_LE(result.samples, onFloor + ambiguous);
    EXPECT_EQ(result.samples + result.kept, total);
}

}  // namespace
}  // namespace penumbra
