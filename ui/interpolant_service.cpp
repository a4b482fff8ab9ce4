#include "ui/interpolant_service.h"

#include <algorithm>
#include <cstdio>

#include "core/log.h"
#include "core/thread_priority.h"
#include "render/hifi/exact_irradiance.h"
#include "solver/discretization.h"

namespace penumbra {

InterpolantService::InterpolantService(SharedSession& shared, RunnerBoard& board,
                                       InterpolantServiceOptions options)
    : mShared(shared), mBoard(board), mOptions(options) {}

InterpolantService::~InterpolantService() {
    mOutdated = true;
    if (mBuild.valid()) mBuild.wait();
}

void InterpolantService::edited(const EditEvent& event) {
    if (event.kind == EditEvent::Kind::Solved) return;
    const std::vector<int> changed = event.changed();
    std::lock_guard<std::mutex> lock(mChangedMutex);
    mChanged.insert(mChanged.end(), changed.begin(), changed.end());
}

std::string InterpolantService::shownNote() const {
    char text[160];
    std::snprintf(text, sizeof text, "interpolants: %d triangles, %d of %d elements meshed in %.1f s",
                  mMesh->stats().triangles, mMesh->stats().remeshed, mMesh->stats().elements,
                  mMesh->stats().seconds);
    return text;
}

const HifiMesh* InterpolantService::landed(const PublishedLight& light, bool still, std::string& note) {
    if (mBuild.valid() && mBuild.wait_for(std::chrono::seconds(0)) == std::future_status::ready) {
        std::unique_ptr<HifiMesh> built = mBuild.get();
        if (built && mBuildSerial == light.serial) {
            land(std::move(built), light.serial, mBuildRadiosity);
            spdlog::debug("interpolants: {} triangles, {} elements meshed in {:.1f} s (light {})",
                          mMesh->stats().triangles, mMesh->stats().remeshed,
                          mMesh->stats().seconds, light.serial);
        } else {
            spdlog::debug("interpolants: build for light {} dropped (light {} now)", mBuildSerial,
                          light.serial);
        }
    }
    if (mMesh && mSerial == light.serial) {
        note = shownNote();
        return mMesh.get();
    }
    if (mBuild.valid()) {
        if (mBuildSerial != light.serial) mOutdated = true;  // stops at its next element
        char text[160];
        std::snprintf(text, sizeof text, "interpolants: building %.0f%% (Gouraud meanwhile)",
                      100 * mProgress.load());
        note = text;
        return nullptr;
    }
    if (!still || !light.radiosity) {
        note = "interpolants: built when the lighting and the view are still (Gouraud meanwhile)";
        return nullptr;
    }
    mBuildSerial = light.serial;
    mBuildRadiosity = light.radiosity;
    mProgress = 0;
    mOutdated = false;
    note = "interpolants: building 0% (Gouraud meanwhile)";
    Base base;
    if (mMesh && mRadiosity) {  // else nothing shown yet: a full build
        base.mesh = mMesh;
        base.radiosity = mRadiosity;
        std::lock_guard<std::mutex> lock(mChangedMutex);
        base.changed = mChanged;
    }
    mBuildChanges = base.changed.size();
    if (!mOptions.threaded) {
        // The caller holds the structure shared.
        std::unique_ptr<HifiMesh> built = build(light.radiosity, base);
        if (!built) return nullptr;
        land(std::move(built), light.serial, light.radiosity);
        note = shownNote();
        return mMesh.get();
    }
    mBuild = std::async(std::launch::async,
                        [this, radiosity = light.radiosity, base = std::move(base)] {
                            nameThisThread("hifi-build");
                            lowerThreadPriority(mOptions.backgroundNice);
                            std::shared_lock<std::shared_mutex> structure(mShared.structure);
                            return build(radiosity, base);
                        });
    return nullptr;
}

void InterpolantService::land(std::unique_ptr<HifiMesh> mesh, std::uint64_t serial,
                              std::shared_ptr<const std::vector<Rgb>> radiosity) {
    mMesh = std::move(mesh);
    mSerial = serial;
    mRadiosity = std::move(radiosity);
    // The edits the build took in are in the mesh now; later ones wait for the next build.
    std::lock_guard<std::mutex> lock(mChangedMutex);
    mChanged.erase(mChanged.begin(),
                   mChanged.begin() + std::ptrdiff_t(std::min(mBuildChanges, mChanged.size())));
}

std::unique_ptr<HifiMesh> InterpolantService::build(
    const std::shared_ptr<const std::vector<Rgb>>& radiosity, const Base& base) {
    const EditSession& session = mShared.read();
    const Discretization& disc = session.discretization();
    if (radiosity->size() != disc.elements().size()) return nullptr;
    try {
        ExactIrradiance exact(disc, ExactIrradianceOptions::forInterpolants(mOptions.gatherRays),
                              &session.tracer());
        exact.setReflected(reflectedRadiosity(disc, *radiosity));
        HifiOptions options;
        options.cancelled = [this] {
            return mShared.editsWaiting.load() > 0 || mOutdated.load();
        };
        auto progress = [this](double f) { mProgress = f; };
        std::unique_ptr<HifiMesh> mesh;
        if (base.mesh) {
            // Only what the edits and the new lighting changed (HifiMesh::update).
            mesh = std::make_unique<HifiMesh>(*base.mesh);
            mesh->update(disc, exact,
                         hifiRemeshElements(disc, *base.radiosity, *radiosity, base.changed),
                         options, progress);
        } else {
            mesh = std::make_unique<HifiMesh>();
            mesh->build(disc, exact, options, progress);
        }
        if (mesh->stats().cancelled) return nullptr;
        return mesh;
    } catch (const std::exception& e) {
        mBoard.report(std::string("interpolants: ") + e.what());
        return nullptr;
    }
}

}  // namespace penumbra
