// The editor's holodeck (SessionRunnerOptions::holodeck; docs/holodeck.md): a scene whose
// holodeck was filled for its default view opens with a first display frame that took the
// holodeck's points and is no worse than the first frame without it; after an edit the runner
// forgets exactly what a direct HoloServer::invalidate of the same edit forgets (the replay's
// computation, run here from scratch); a corrupt holodeck beside the scene is a warning, the
// scene opens and the file is left as it was; the display's converged points are stored.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "cli/cli_support.h"
#include "edit/edit_log.h"
#include "render/camera_rays.h"
#include "render/display/point_shader.h"
#include "render/holodeck/holo_view.h"
#include "runner_test_support.h"
#include "ui/editor_app.h"
#include "ui/session_runner.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

constexpr int kWidth = 160, kHeight = 120;

class RunnerHolodeck : public ::testing::Test {
protected:
    void SetUp() override {
        mDir = fs::temp_directory_path() /
               ("penumbra_runner_holodeck_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(mDir);
        fs::create_directories(mDir);
        fs::copy_file(fs::path(PENUMBRA_SOURCE_DIR) / "scenes/cube-room.json", scene());
    }
    void TearDown() override { fs::remove_all(mDir); }
    std::string scene() const { return (mDir / "cube-room.json").string(); }
    std::string holodeck() const { return (mDir / "cube-room.hdk").string(); }
    /// Fills the holodeck beside the scene for its default view at the test's size, as
    /// `penumbra holodeck fill --camera default` does (in process: the sanitizer builds' test
    /// keeps oneTBB to one thread).
    void fill(int samples) const {
        auto session = converged();
        PointShaderOptions shading = InteractiveDisplayOptions{}.shader;
        shading.threads = 0;
        PointShader shader(session->discretization(), session->tracer(),
                           interactiveSolverOptions(), shading);
        shader.updateSolution(session->solver());
        HoloFile file(holodeck(), holodeckSections(session->scene().settings,
                                                   session->discretization()));
        HoloServer server(file, &shader);
        const CameraRays view(camera(*session), kWidth, kHeight);
        const FillStats stats = server.fill(
            viewRequests(file.sections(), view, kWidth / 4, kHeight / 4, 1.0), samples, 0);
        ASSERT_EQ(stats.samples, samples);
    }
    /// The scene opened and converged as the editor's solver would leave it.
    std::unique_ptr<EditSession> converged() const {
        auto session = EditSession::open(scene(), interactiveSolverOptions());
        session->converge(1e-3);
        return session;
    }
    static Camera camera(const EditSession& session) {
        const Camera* c = session.scene().findCamera("default");
        return c ? *c : session.scene().cameras.front();
    }
    static std::unique_ptr<SessionRunner> runner(std::unique_ptr<EditSession> session,
                                                 const std::string& holodeck) {
        SessionRunnerOptions options;
        options.threaded = false;
        options.backgroundNice = 0;
        options.holodeck = holodeck;
        ViewRequest view;
        view.camera = camera(*session);
        view.width = kWidth;
        view.height = kHeight;
        view.mode = ViewMode::EdgeAndPoint;
        auto r = std::make_unique<SessionRunner>(std::move(session), options);
        r->setView(view);
        return r;
    }
    /// The first display frame of a runner over the converged scene.
    std::shared_ptr<const ViewportImage> firstFrame(SessionRunner& r) const {
        return test::pumpUntil(r, 60, [](const ViewportImage& img) {
            return img.mode == ViewMode::EdgeAndPoint;
        });
    }
    fs::path mDir;
};

TEST_F(RunnerHolodeck, FirstFrameStartsFromTheHolodeckAndIsNoWorse) {
    fill(60000);
    Image reference;
    {
        auto session = converged();
        InteractiveDisplayOptions options;
        options.width = kWidth;
        options.height = kHeight;
        InteractiveDisplay display(session->discretization(), session->tracer(),
                                   interactiveSolverOptions(), options);
        display.apply(SolutionView::of(session->solver()));
        reference = display.renderReference(CameraRays(camera(*session), kWidth, kHeight), 4);
    }
    double errors[2] = {0, 0};
    std::int64_t points[2] = {0, 0};
    for (int with = 0; with < 2; ++with) {
        auto r = runner(converged(), with ? holodeck() : "");
        const auto img = firstFrame(*r);
        ASSERT_TRUE(img && img->mode == ViewMode::EdgeAndPoint);
        errors[with] = displayRmse(img->render.radiance, reference);
        points[with] = img->holodeckPoints;
        EXPECT_TRUE(r->takeMessages().empty());
    }
    EXPECT_EQ(points[0], 0);
    EXPECT_GT(points[1], kWidth * kHeight / 4) << "holodeck points in the first frame";
    EXPECT_LE(errors[1], errors[0] * 1.02)
        << "first frame with the holodeck " << errors[1] << ", without " << errors[0];
    std::printf("first frame: %lld holodeck points, error %.4f (without: %.4f)\n",
                static_cast<long long>(points[1]), errors[1], errors[0]);
}

TEST_F(RunnerHolodeck, AMovedCameraTakesItsViewFromAHolodeckFilledForNoView) {
    // A batch fill: every beam in proportion to its volume, no camera.
    {
        auto session = converged();
        PointShaderOptions shading = InteractiveDisplayOptions{}.shader;
        shading.threads = 0;
        PointShader shader(session->discretization(), session->tracer(), interactiveSolverOptions(),
                           shading);
        shader.updateSolution(session->solver());
        HoloFile file(holodeck(),
                      holodeckSections(session->scene().settings, session->discretization()));
        HoloServer server(file, &shader);
        server.fill(server.batchRequests(4e5), 400000, 0);
    }
    auto session = converged();
    const Camera start = camera(*session);
    auto r = runner(std::move(session), holodeck());
    const auto first = firstFrame(*r);
    ASSERT_TRUE(first && first->mode == ViewMode::EdgeAndPoint);
    // The first view took its own beams' samples at once; the index of every beam's hits is
    // built after it, and the same view asks again, at half the display's resolution: most of
    // its 80 x 60 pixels. A camera turned by 3 degrees (further, it leaves the room) takes its
    // view's the same way.
    const std::int64_t ownBeams = first->holodeckPoints;
    const std::int64_t half = (kWidth / 2) * (kHeight / 2);
    auto grewBy = [&](std::int64_t from) {
        const auto img = test::pumpUntil(
            *r, 30, [&](const ViewportImage& i) { return i.holodeckPoints > from + half / 2; });
        return img ? img->holodeckPoints : 0;
    };
    const std::int64_t indexed = grewBy(ownBeams);
    EXPECT_GT(indexed, ownBeams + half / 2) << "the view again, from every beam";
    ViewRequest turned;
    turned.camera = orbitCamera(start, 3);
    turned.width = kWidth;
    turned.height = kHeight;
    turned.mode = ViewMode::EdgeAndPoint;
    r->setView(turned);
    EXPECT_GT(grewBy(indexed), indexed + half / 2) << "the turned view, from every beam";
    EXPECT_TRUE(r->takeMessages().empty());
}

TEST_F(RunnerHolodeck, AnEditForgetsWhatItChangedAndKeepsTheRest) {
    fill(60000);
    const std::int64_t before = HoloFile::openReadOnly(holodeck()).info().samples;
    const std::vector<LoggedEdit> edits =
        readEditLog(std::string(PENUMBRA_SOURCE_DIR) + "/scenes/logs/cube-room-add-cube.jsonl");
    ASSERT_FALSE(edits.empty());
    const EditCommand add = edits.front().command;

    // What the replay's computation forgets for the same edit, on a copy of the file.
    const std::string copy = (mDir / "copy.hdk").string();
    fs::copy_file(holodeck(), copy);
    Invalidation expected;
    {
        auto session = converged();
        HoloFile file(copy, {});
        HoloServer server(file, nullptr);
        const std::vector<double> lit = elementLuminance(session->solver().radiosity());
        session->apply(add);
        session->converge(1e-3);
        expected = server.invalidate(
            session->tracer(),
            changedElements(lit, elementLuminance(session->solver().radiosity()), 0.01));
    }
    ASSERT_GT(expected.samples, 0);
    ASSERT_LT(expected.samples, before / 2);

    {
        auto r = runner(converged(), holodeck());
        ASSERT_TRUE(firstFrame(*r));
        EXPECT_EQ(r->solver().holodeck.samples, before);
        r->submit(add);
        test::pumpUntil(*r, 60, [&](const ViewportImage&) {
            return r->solver().holodeck.invalidated > 0 && r->solver().idle;
        });
        const HolodeckStatus status = r->solver().holodeck;
        EXPECT_EQ(status.invalidated, expected.samples);
        EXPECT_EQ(status.samples, before - expected.samples);
        // Unsaved edits: nothing of the edited scene goes into the scene file's holodeck.
        EXPECT_EQ(status.stored, 0);
        std::printf("adding a cube: %lld of %lld samples forgotten\n",
                    static_cast<long long>(status.invalidated), static_cast<long long>(before));
    }
    EXPECT_EQ(HoloFile::openReadOnly(holodeck()).info().samples, before - expected.samples);
}

TEST_F(RunnerHolodeck, ThreadedRunnerHandsThePointsOverAndForgetsEdits) {
    // The handoff between the render and solver threads (ThreadSanitizer's part of this file).
    fill(30000);
    SessionRunnerOptions options;
    options.backgroundNice = 0;
    options.holodeck = holodeck();
    auto session = converged();
    ViewRequest view;
    view.camera = camera(*session);
    view.width = kWidth;
    view.height = kHeight;
    view.mode = ViewMode::EdgeAndPoint;
    SessionRunner r(std::move(session), options);
    r.setView(view);
    const auto img = test::waitUntil(r, 120, [](const ViewportImage& i) {
        return i.mode == ViewMode::EdgeAndPoint && i.holodeckPoints > 0;
    });
    ASSERT_TRUE(img && img->holodeckPoints > 0);
    const std::vector<LoggedEdit> edits =
        readEditLog(std::string(PENUMBRA_SOURCE_DIR) + "/scenes/logs/cube-room-add-cube.jsonl");
    r.submit(edits.front().command);
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(120);
    while (r.solver().holodeck.invalidated == 0 && std::chrono::steady_clock::now() < end)
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    EXPECT_GT(r.solver().holodeck.invalidated, 0);
    EXPECT_TRUE(r.takeMessages().empty());
}

TEST_F(RunnerHolodeck, CorruptHolodeckBesideTheSceneIsAWarning) {
    const std::string garbage(4096, 'x');
    test::writeFile(holodeck(), garbage);
    EditorOptions options;
    options.scene = scene();
    ASSERT_EQ(editorHolodeckPath(options, scene()), holodeck());
    options.noHolodeck = true;
    EXPECT_EQ(editorHolodeckPath(options, scene()), "");

    auto r = runner(converged(), holodeck());
    const auto img = firstFrame(*r);
    ASSERT_TRUE(img && img->mode == ViewMode::EdgeAndPoint) << "the scene opens without it";
    EXPECT_EQ(img->holodeckPoints, 0);
    // One warning line (spdlog), no error message; the snapshot says why.
    EXPECT_TRUE(r->takeMessages().empty());
    const HolodeckStatus status = r->solver().holodeck;
    EXPECT_FALSE(status.open);
    EXPECT_NE(status.error.find(holodeck()), std::string::npos) << status.error;
    EXPECT_EQ(status.toString(), "holodeck: not used");
    r.reset();
    EXPECT_EQ(test::readFile(holodeck()), garbage) << "left as it was";
}

TEST_F(RunnerHolodeck, TheConvergedViewIsStoredOnceItRested) {
    // No holodeck yet: named, it is created and takes the display's points.
    {
        auto r = runner(converged(), holodeck());
        test::pumpUntil(*r, 60, [&](const ViewportImage&) {
            return r->solver().holodeck.stored > 0;
        });
        EXPECT_GT(r->solver().holodeck.stored, kWidth * kHeight / 4);
    }
    const std::int64_t stored = HoloFile::openReadOnly(holodeck()).info().samples;
    EXPECT_GT(stored, kWidth * kHeight / 4);
    EXPECT_LE(stored, kWidth * kHeight) << "one sample per pixel at most";
    // The next visit starts from them, and once it rested stores only pixels they left empty.
    auto r = runner(converged(), holodeck());
    const auto img = firstFrame(*r);
    ASSERT_TRUE(img);
    EXPECT_GT(img->holodeckPoints, stored / 2);
    test::pumpUntil(*r, 30, [&](const ViewportImage& i) {
        return i.settledFrames > 2 * SessionRunnerOptions{}.settleFrames;
    });
    EXPECT_LE(r->solver().holodeck.stored, kWidth * kHeight - img->holodeckPoints);
    std::printf("stored %lld, then %lld holodeck points and %lld stored on the second visit\n",
                static_cast<long long>(stored), static_cast<long long>(img->holodeckPoints),
                static_cast<long long>(r->solver().holodeck.stored));
}

}  // namespace
}  // namespace penumbra
