#pragma once
// The editor's holodeck (Ward & Simmons 1999; docs/holodeck.md): a service with its own thread
// and state (HoloFile and HoloServer are not thread-safe; nothing else touches them). It opens
// the file, answers a new display's request for its view's samples, stores the points a display
// shaded from the converged solution once its view rested, and, once the solution converges
// after edits, forgets what they changed (HoloServer::invalidate). While edits wait for that
// invalidation the holodeck is neither read nor written; new points are stored only while the
// document is the one in the scene file the holodeck belongs to (no edits since it was opened
// or saved there). It hears of edits and saves as an EditListener and reads the lighting from
// the board; it reads the structure holding it shared.

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "render/display/render_cache.h"
#include "render/holodeck/holo_file.h"
#include "render/holodeck/holo_server.h"
#include "render/holodeck/holo_view.h"
#include "ui/runner_board.h"
#include "ui/service_thread.h"
#include "ui/shared_session.h"

namespace penumbra {

struct HolodeckServiceOptions {
    /// The holodeck file, "" for none; created with the scene's sections when missing. One
    /// that cannot be opened is one warning line and the service goes on without it.
    std::string path;
    /// After edits, the relative change of an element's light that makes the holodeck forget
    /// the samples on it (changedElements).
    double threshold = 0.01;
    int backgroundNice = 0;  ///< Linux nice increment of the thread
};

class HolodeckService : public EditListener {
public:
    HolodeckService(SharedSession& shared, RunnerBoard& board, HolodeckServiceOptions options);
    /// Stops the thread, stores what was handed over, makes the file match the scene file and
    /// flushes it.
    ~HolodeckService() override;
    HolodeckService(const HolodeckService&) = delete;
    HolodeckService& operator=(const HolodeckService&) = delete;

    bool enabled() const { return !mOptions.path.empty(); }
    /// Starts the thread (threaded runners); without it, iterate() runs on the caller's.
    void start();
    void stop();
    /// Opens the file, invalidates after edits once the solution converged, answers the read
    /// and stores the points waiting. Returns whether it did work.
    bool iterate();

    // -- Requests (the display producer's thread) ------------------------------------------------

    /// Asks for the stored samples of `camera`'s view at w × h; returns the request's id (0
    /// when disabled). A newer request replaces an unanswered one.
    std::uint64_t requestView(const Camera& camera, int width, int height);
    /// The answer to request `id` once it came: points stamped with frame and shading 0 (the
    /// display stamps its own); empty when the holodeck could not serve the view.
    std::optional<std::vector<ShadedPoint>> takeView(std::uint64_t id);
    /// How many hit indexes were built: a view read before the last one took only its own
    /// beams' samples, and may ask again.
    std::uint64_t indexBuilds() const { return mIndexBuilds.load(std::memory_order_acquire); }
    /// Points a display shaded from the converged light `lightSerial`, seen from `eye`: stored
    /// when that is still the latest light and the document is the scene file's.
    void store(std::vector<CachePoint> points, const Vec3& eye, std::uint64_t lightSerial);

    // -- EditListener (the solver worker's thread) ---------------------------------------------------

    void edited(const EditEvent& event) override;
    void savedHolodeckScene() override;
    void published() override { mThread.wake(); }

private:
    struct Read {
        std::uint64_t id = 0;
        Camera camera;
        int width = 0, height = 0;
    };
    struct Answer {
        std::uint64_t id = 0;
        std::vector<ShadedPoint> points;
    };
    struct Store {
        std::vector<CachePoint> points;
        Vec3 eye{0.0};
        std::uint64_t lightSerial = 0;
    };
    void open();
    /// Forgets what the edits since the last invalidation changed: the elements whose light
    /// moved beyond the threshold against `now`, or every element's.
    void invalidate(bool everyElement, std::vector<double> now);
    void storePoints(std::vector<Store>& stores, std::uint64_t lightSerial);
    std::vector<ShadedPoint> viewPoints(const Read& read);
    void publishStatus();
    void report(const std::string& message);

    SharedSession& mShared;
    RunnerBoard& mBoard;
    HolodeckServiceOptions mOptions;

    mutable std::mutex mMutex;  ///< requests, answers, stores and the edit notes
    std::optional<Read> mRead;
    std::optional<Answer> mAnswer;
    std::vector<Store> mStores;
    std::uint64_t mReadIds = 0;
    /// Edits noted, and the light serial that first includes the last of them.
    std::uint64_t mEdits = 0, mEditLight = 0;
    /// Edits since the document was the holodeck's scene file (opened or saved there).
    bool mUnsaved = false;
    /// The scene file was saved with edits the holodeck had not yet forgotten: it matches the
    /// file again only when it forgets them with nothing edited since the save (otherwise it
    /// forgets every element's light).
    bool mBehindFile = false;
    ServiceThread mThread;

    // The service's own (its thread's, or the destructor's once it joined).
    std::optional<HoloFile> mFile;
    std::unique_ptr<HoloServer> mServer;
    /// Where its samples hit, so a view takes every stored sample it can see, not only its
    /// own beams'. Built after the first read, which takes its own beams at once (without
    /// holding the structure: it reads the file alone), and again after an invalidation;
    /// samples stored since join at the next build.
    std::optional<HoloHitIndex> mIndex;
    bool mIndexWanted = false;
    std::atomic<std::uint64_t> mIndexBuilds{0};
    HolodeckStatus mStatus;
    bool mTried = false;
    /// Edits the last invalidation covered (mEdits beyond it: the holodeck is behind).
    std::uint64_t mInvalidatedEdits = 0;
    /// Element luminance of the solution the holodeck matches (empty before it first
    /// converged).
    std::vector<double> mLuminance;
};

}  // namespace penumbra
