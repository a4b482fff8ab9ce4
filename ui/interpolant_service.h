#pragma once
// The editor's high-fidelity interpolants (Hardt & Teller 1996; docs/hifi.md) as a service:
// it owns the mesh shown, the build in progress (on a thread of its own, holding the
// structure shared) and the versions edits changed since the mesh was built (it hears of
// them as an EditListener). An edit waiting for the structure or newer lighting stops the
// build between elements, so an edit waits for one element's samples, not the build; the next
// build re-meshes only what the edits and the new lighting changed (HifiMesh::update).

#include <atomic>
#include <cstdint>
#include <future>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "render/hifi/hifi_mesh.h"
#include "ui/runner_board.h"
#include "ui/shared_session.h"

namespace penumbra {

struct InterpolantServiceOptions {
    /// Far-field rays per exact irradiance sample (ExactIrradianceOptions::farRays, as
    /// `render --mode interpolant`).
    int gatherRays = 256;
    bool threaded = true;    ///< builds on a thread of their own; else in the caller's
    int backgroundNice = 0;  ///< Linux nice increment of the build thread
};

class InterpolantService : public EditListener {
public:
    InterpolantService(SharedSession& shared, RunnerBoard& board,
                       InterpolantServiceOptions options);
    /// Stops a build in progress and waits for it.
    ~InterpolantService() override;
    InterpolantService(const InterpolantService&) = delete;
    InterpolantService& operator=(const InterpolantService&) = delete;

    /// The render thread, holding the structure shared: the mesh of `light`'s lighting when
    /// one is built; otherwise starts or follows its build (once the lighting and the view are
    /// still: `still`) and says how far it got in `note`. Null meanwhile.
    const HifiMesh* landed(const PublishedLight& light, bool still, std::string& note);

    /// The versions an edit changed: the next build re-meshes them.
    void edited(const EditEvent& event) override;

private:
    /// What a build starts from: the mesh shown last (null: none, a full build), the lighting
    /// it was built of and the versions edits changed since.
    struct Base {
        std::shared_ptr<const HifiMesh> mesh;
        std::shared_ptr<const std::vector<Rgb>> radiosity;
        std::vector<int> changed;
    };
    /// The build itself (any thread, structure held shared): null when an edit came first.
    std::unique_ptr<HifiMesh> build(const std::shared_ptr<const std::vector<Rgb>>& radiosity,
                                    const Base& base);
    void land(std::unique_ptr<HifiMesh> mesh, std::uint64_t serial,
              std::shared_ptr<const std::vector<Rgb>> radiosity);
    std::string shownNote() const;

    SharedSession& mShared;
    RunnerBoard& mBoard;
    InterpolantServiceOptions mOptions;

    // The render thread's.
    std::shared_ptr<const HifiMesh> mMesh;  ///< the mesh shown, of lighting mSerial
    std::uint64_t mSerial = 0;
    std::shared_ptr<const std::vector<Rgb>> mRadiosity;  ///< the lighting mMesh was built of
    std::future<std::unique_ptr<HifiMesh>> mBuild;
    std::uint64_t mBuildSerial = 0;
    std::shared_ptr<const std::vector<Rgb>> mBuildRadiosity;
    std::size_t mBuildChanges = 0;  ///< how many of mChanged the build took in

    std::mutex mChangedMutex;
    /// The versions edits changed since mMesh was built (the solver worker appends; the render
    /// thread takes them for a build and drops those a landed build took in).
    std::vector<int> mChanged;
    std::atomic<double> mProgress{0};
    std::atomic<bool> mOutdated{false};
};

}  // namespace penumbra
