#include "ui/holodeck_service.h"

#include <algorithm>

#include "core/log.h"
#include "core/timing.h"
#include "render/camera_rays.h"
#include "render/holodeck/holo_view.h"
#include "render/light_change.h"

namespace penumbra {

HolodeckService::HolodeckService(SharedSession& shared, RunnerBoard& board,
                                 HolodeckServiceOptions options)
    : mShared(shared), mBoard(board), mOptions(std::move(options)) {
    mStatus.path = mOptions.path;
    publishStatus();
}

HolodeckService::~HolodeckService() {
    stop();
    if (!mServer) return;
    std::shared_lock<std::shared_mutex> structure(mShared.structure);
    const bool dirty = mEdits > mInvalidatedEdits;
    if (!dirty && !mUnsaved && !mStores.empty()) storePoints(mStores, mBoard.lightSerial());
    // The scene file was saved with edits the holodeck did not forget yet: it forgets every
    // element's light (the converged light of those edits is not known).
    if (dirty && mBehindFile) invalidate(true, {});
    try {
        mServer->flush();
    } catch (const std::exception& e) {
        spdlog::warn("holodeck: {}", e.what());
    }
    mServer.reset();
    mFile.reset();
}

void HolodeckService::start() {
    if (!enabled()) return;
    mThread.start("holodeck", mOptions.backgroundNice, std::chrono::milliseconds(50),
                  [this] { return iterate(); });
}

void HolodeckService::stop() { mThread.stop(); }

void HolodeckService::report(const std::string& message) { mBoard.report("holodeck: " + message); }

void HolodeckService::publishStatus() { mBoard.setHolodeck(mStatus); }

// ---------------------------------------------------------------------------------------------
// Requests and notes.

std::uint64_t HolodeckService::requestView(const Camera& camera, int width, int height) {
    if (!enabled()) return 0;
    std::uint64_t id;
    {
        std::lock_guard<std::mutex> lock(mMutex);
        id = ++mReadIds;
        mRead = Read{id, camera, width, height};
    }
    mThread.wake();
    return id;
}

std::optional<std::vector<ShadedPoint>> HolodeckService::takeView(std::uint64_t id) {
    std::lock_guard<std::mutex> lock(mMutex);
    if (!mAnswer || mAnswer->id != id) return std::nullopt;
    std::optional<std::vector<ShadedPoint>> points(std::move(mAnswer->points));
    mAnswer.reset();
    return points;
}

void HolodeckService::store(std::vector<CachePoint> points, const Vec3& eye,
                            std::uint64_t lightSerial) {
    if (!enabled()) return;
    {
        std::lock_guard<std::mutex> lock(mMutex);
        mStores.push_back({std::move(points), eye, lightSerial});
    }
    mThread.wake();
}

void HolodeckService::edited(const EditEvent& event) {
    if (!enabled() || event.kind == EditEvent::Kind::Solved) return;
    // The solver worker publishes the lighting after the batch: the next serial includes it.
    const std::uint64_t next = mBoard.lightSerial() + 1;
    std::lock_guard<std::mutex> lock(mMutex);
    ++mEdits;
    mEditLight = next;
    mUnsaved = true;
}

void HolodeckService::savedHolodeckScene() {
    if (!enabled()) return;
    std::lock_guard<std::mutex> lock(mMutex);
    if (mEdits > mInvalidatedEdits) mBehindFile = true;
    mUnsaved = false;
}

// ---------------------------------------------------------------------------------------------
// The service's work.

void HolodeckService::open() {
    mTried = true;
    try {
        std::shared_lock<std::shared_mutex> structure(mShared.structure);
        // A new file gets the scene's sections; an existing one keeps its own.
        const EditSession& session = mShared.read();
        mFile.emplace(mOptions.path,
                      holodeckSections(session.scene().settings, session.discretization()));
        mServer = std::make_unique<HoloServer>(*mFile, nullptr);
        mStatus.open = true;
        mStatus.samples = mFile->info().samples;
        spdlog::debug("holodeck {}: {} samples", mOptions.path, mStatus.samples);
    } catch (const std::exception& e) {
        // A bad cache is no reason not to edit the scene.
        mServer.reset();
        mFile.reset();
        mStatus.error = e.what();
        // One warning line; the status line says "holodeck: not used".
        spdlog::warn("holodeck not used: {}", e.what());
    }
    publishStatus();
}

bool HolodeckService::iterate() {
    if (!enabled()) return false;
    if (!mTried) open();
    std::optional<Read> read;
    std::vector<Store> stores;
    std::uint64_t edits, editLight;
    bool unsaved, behindFile;
    {
        std::lock_guard<std::mutex> lock(mMutex);
        read.swap(mRead);
        stores.swap(mStores);
        edits = mEdits;
        editLight = mEditLight;
        unsaved = mUnsaved;
        behindFile = mBehindFile;
    }
    // Read after the notes: a light whose serial is below editLight predates the edits.
    const PublishedLight light = mBoard.light();
    bool worked = read.has_value() || !stores.empty();
    bool dirty = edits > mInvalidatedEdits;
    const bool converged =
        light.converged && light.convergedRadiosity && light.serial >= editLight;
    // The index, once a view was read from the view's own beams (the first read does not wait
    // for it), reads the file alone: built before the structure is taken.
    if (mIndexWanted && !read && mServer && !dirty && !mIndex) {
        const auto t0 = Clock::now();
        try {
            mIndex.emplace(*mServer);
            mIndexBuilds.fetch_add(1, std::memory_order_release);
            spdlog::debug("holodeck: hit index of {} samples in {:.1f} ms", mIndex->hits(),
                          msSince(t0));
        } catch (const std::exception& e) {
            report(e.what());
        }
        mIndexWanted = false;
        publishStatus();
    }
    // The tracer and the discretization are read with the structure shared: an edit waits for
    // this iteration's work (a read gives way to it).
    std::shared_lock<std::shared_mutex> structure(mShared.structure, std::defer_lock);
    if (mServer && (worked || (converged && (dirty || mLuminance.empty())))) structure.lock();
    if (mServer && converged) {
        if (dirty) {
            // Without the light of the solution the holodeck matched, or when the scene file
            // was saved in between and edited since, every element counts as changed.
            invalidate(mLuminance.empty() || (behindFile && unsaved),
                       elementLuminance(*light.convergedRadiosity));
            mInvalidatedEdits = edits;
            dirty = false;
            worked = true;
        } else if (mLuminance.empty()) {
            mLuminance = elementLuminance(*light.convergedRadiosity);
        }
    }
    if (read) {
        std::vector<ShadedPoint> points;
        if (mServer && !dirty && !light.dragging) points = viewPoints(*read);
        mStatus.served += std::int64_t(points.size());
        std::lock_guard<std::mutex> lock(mMutex);
        mAnswer = Answer{read->id, std::move(points)};
    }
    if (!stores.empty() && mServer && !dirty && !unsaved) storePoints(stores, light.serial);
    if (worked) publishStatus();
    return worked;
}

std::vector<ShadedPoint> HolodeckService::viewPoints(const Read& read) {
    const auto t0 = Clock::now();
    try {
        const CameraRays rays(read.camera, read.width, read.height);
        const EditSession& session = mShared.read();
        std::vector<ShadedPoint> points;
        if (mIndex) {
            // Every stored sample the view can see; an edit waiting for the structure ends the
            // read (no points).
            points = mIndex->viewPoints(session.discretization(), session.tracer(), rays, 0, 0,
                                        [this] { return mShared.editsWaiting.load() > 0; });
        } else {
            // The view's own beams, at once; the index follows for the next views.
            const auto view = viewRequests(mFile->sections(), rays, std::max(1, read.width / 4),
                                           std::max(1, read.height / 4), 1.0);
            points = holodeckViewPoints(*mServer, view, session.discretization(), session.tracer(),
                                        rays, 0, 0);
            mIndexWanted = true;
            mThread.wake();
        }
        spdlog::debug("holodeck: {} points of a {}x{} view in {:.1f} ms", points.size(),
                      read.width, read.height, msSince(t0));
        return points;
    } catch (const std::exception& e) {
        report(e.what());
        return {};
    }
}

// The structure is held shared by the caller from here on.

void HolodeckService::invalidate(bool everyElement, std::vector<double> now) {
    const auto t0 = Clock::now();
    const std::vector<std::uint8_t> changed =
        everyElement ? std::vector<std::uint8_t>(mShared.read().discretization().elements().size(), 1)
                     : changedElements(mLuminance, now, mOptions.threshold);
    try {
        const Invalidation result = mServer->invalidate(mShared.read().tracer(), changed);
        mServer->flush();
        if (result.samples > 0) mIndex.reset();
        mStatus.invalidated += result.samples;
        mStatus.samples = mFile->info().samples;
        spdlog::debug("holodeck: edits took {} samples from {} beams ({} kept) in {:.1f} ms",
                      result.samples, result.beams, result.kept, msSince(t0));
    } catch (const std::exception& e) {
        report(e.what());
    }
    mLuminance = std::move(now);
    // Matching the solution now, it matches the scene file when nothing was edited since the
    // save (or it holds nothing any scene could contradict).
    std::lock_guard<std::mutex> lock(mMutex);
    if (!mUnsaved || everyElement) mBehindFile = false;
}

void HolodeckService::storePoints(std::vector<Store>& stores, std::uint64_t lightSerial) {
    const auto t0 = Clock::now();
    std::int64_t added = 0;
    try {
        const RayTracer& tracer = mShared.read().tracer();
        for (const Store& store : stores)
            if (store.lightSerial == lightSerial)  // nothing changed since they were shaded
                added += storeViewPoints(*mServer, store.points, tracer, store.eye);
        mServer->flush();
        mStatus.samples = mFile->info().samples;
    } catch (const std::exception& e) {
        report(e.what());
    }
    mStatus.stored += added;
    stores.clear();
    spdlog::debug("holodeck: stored {} samples in {:.1f} ms", added, msSince(t0));
}

}  // namespace penumbra
