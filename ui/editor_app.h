#pragma once
// The editor window: GLFW + Dear ImGui 1.86 (OpenGL3 backend over the glad loader), a viewport
// showing the lit scene as a texture, the gizmo, panels (solver, object and material,
// cameras, scene), menus (open, save, export, undo/redo), a status bar; `--play` replays an
// edit log live, `--screenshot` saves the window after `--frames` frames, and a driver
// (ui/editor_driver.h: an input script, a benchmark) plays input from outside.
//
// The window reads the document and lighting only through SessionRunner's snapshots and
// changes them only by submitting edit commands (docs/style.md: the UI emits commands and keeps
// no copy of the model).

#include <algorithm>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "edit/edit_log.h"
#include "edit/io/scene_import.h"
#include "ui/drag_controller.h"
#include "ui/editor_driver.h"
#include "ui/file_dialog.h"
#include "ui/gizmo.h"
#include "ui/mesh_library.h"
#include "ui/recovery.h"
#include "ui/session_runner.h"
#include "ui/view_camera.h"

struct GLFWwindow;

namespace penumbra {

struct EditorOptions {
    std::string scene;       ///< scene file to open, "" for none
    ImportOptions import;    ///< how a glTF or OBJ scene is imported (File ▸ Open too)
    std::string log;         ///< edit log to append to
    std::string play;        ///< edit log to replay live
    std::string screenshot;  ///< PNG written after `frames` frames, then exit
    int frames = 0;
    int width = 1280, height = 720;
    int playEvery = 3;   ///< frames per replayed log line
    double maxFps = 60;  ///< frame loop cap (Xvfb has no vertical sync)
    /// The cap under a software GL (Mesa's llvmpipe, as under Xvfb): there the window's own
    /// drawing runs on the CPU cores the display and the solver need.
    double softwareGlMaxFps = 40;
    /// Plays input from outside the editor (ui/editor_driver.h): an input script (--script),
    /// a benchmark (--bench-drag, --bench-still). A driven editor keeps no recovery journal,
    /// never asks about one, and runs until its driver quits or the window closes.
    std::shared_ptr<EditorDriver> driver;
    bool quiet = false;
    /// The viewport's initial display mode (View ▸ Mode). Edge-and-point by default; the
    /// viewport shows Gouraud until the display has been built (seconds in large scenes).
    ViewMode mode = ViewMode::EdgeAndPoint;
    int displayDivisor = 1;  ///< display modes render viewport / d pixels (SessionRunnerOptions)
    /// View ▸ Overlay ▸ Settling on from the start (--overlay settling).
    bool settlingOverlay = false;
    /// The recovery journal (ui/recovery.h): kept unless `log` names a log of the user's own
    /// or a drag is benchmarked.
    bool journal = true;
    /// Unsaved edits an earlier editor run left: replayed at once (--recover) instead of asked
    /// about. Runs that do not wait for the user (--screenshot, --play, a driver) never ask.
    bool recover = false;
    /// The holodeck (docs/holodeck.md) the display modes start a view from and store their
    /// converged points in: `holodeck` for the scene named in `scene` (created when missing);
    /// otherwise, for every scene opened, the scene's path with the extension .hdk when that
    /// file exists. `noHolodeck`: none. One that cannot be opened is a warning line on stderr
    /// ("holodeck: not used" in the status line), and the scene opens without it.
    std::string holodeck;
    bool noHolodeck = false;
};

/// The holodeck the editor uses for `scene` (EditorOptions::holodeck): "" for none.
std::string editorHolodeckPath(const EditorOptions& options, const std::string& scene);

/// No window could be opened (no DISPLAY, no GL 3.3 core context).
struct DisplayError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

/// Pointer state in viewport pixels, for scripted input (tests, benchmarks): consumed one per
/// frame instead of the real mouse, through the same handling.
struct PointerInput {
    double x = 0, y = 0;
    bool left = false, right = false, middle = false;
    double wheel = 0;
    bool shift = false;
};

/// Frame-time figures.
struct FrameStats {
    int frames = 0;
    double lastMs = 0;             ///< work time of the last frame (without the cap's sleep)
    std::vector<double> workMs;    ///< per frame
    std::vector<double> periodMs;  ///< drawn frame start to the next, when both were drawn
    int imagesShown = 0;           ///< viewport images uploaded
    int ticks = 0;                 ///< frame-loop iterations, drawn or not
    double firstTick = -1, lastTick = 0;
    void tick(double now) {
        ++ticks;
        if (firstTick < 0) firstTick = now;
        lastTick = now;
    }
    double seconds() const { return firstTick < 0 ? 0.0 : lastTick - firstTick; }
    std::vector<double> imageMs;  ///< per uploaded image: its render time on the render thread
};

class EditorApp : public EditorControls {
public:
    /// Opens the window and the scene (InputError for a bad scene or log; DisplayError when no
    /// window can be opened).
    explicit EditorApp(EditorOptions options);
    ~EditorApp() override;
    EditorApp(const EditorApp&) = delete;
    EditorApp& operator=(const EditorApp&) = delete;

    /// Runs frames until the window closes, the screenshot is written or the driver quits.
    /// Returns the exit status (0; 1 when the screenshot could not be written; the driver's).
    int run();
    /// One frame. False when the editor should stop.
    bool frame();
    /// Whether run() draws a frame now, or only ticks (events, the drag benchmark): true for
    /// half a second after any input event and while a button or key is held, a drag or camera
    /// move is on, a log replays, the driver plays input, a screenshot is due, a new viewport
    /// image or message waits;
    /// otherwise only to refresh the status bar (every 0.25 s while the light changes, every
    /// second when idle). An unchanged window is not redrawn: under a software rasterizer the
    /// swap alone costs about a core at the frame cap, which the solver and display need.
    bool needsFrame();

    // EditorControls: what a driver (and a test) does as a user would.
    SessionRunner* runner() override { return mRunner.get(); }
    void select(const std::string& id) override { mSelection = id; }
    bool beginDrag() override;
    Transform dragStart() const override { return mDrag.start(); }
    void dragTo(const Transform& to) override;
    Transform endDrag() override;
    std::shared_ptr<const ViewportImage> shownImage() const override { return mShown; }
    const FrameStats& frameStats() const override { return mStats; }
    void resetFrameStats() override { mStats = FrameStats{}; }
    int viewportWidth() const override { return mViewportW; }
    int viewportHeight() const override { return mViewportH; }
    int displayDivisor() const override { return std::max(1, mOptions.displayDivisor); }
    ViewMode viewMode() const override { return mMode; }
    const std::string& scenePath() const override { return mScenePath; }
    void quit(int status) override {
        mQuit = true;
        mExitStatus = status;
    }

    // For tests.
    void queuePointer(const PointerInput& input) { mScripted.push_back(input); }
    std::size_t pendingPointer() const { return mScripted.size(); }
    const ViewCamera& viewCamera() const { return mView; }
    const std::string& selection() const { return mSelection; }
    /// The gizmo as drawn for the selection now (none without a selection).
    std::optional<Gizmo> gizmo() const;
    double gizmoSize(const Vec3& pivot) const;
    bool playing() const { return mPlayNext < mPlay.size(); }
    /// An earlier editor run's unsaved edits the editor offers to recover (the prompt is open
    /// while they are not empty).
    const UnsavedEdits& unsaved() const { return mUnsaved; }
    /// The prompt's Recover: replays unsaved() through the runner (each edit validated and
    /// journaled again as it applies), then discards what was set aside.
    void recoverUnsaved();
    /// File ▸ Save (Ctrl+S) when `path` is the scene's, Save as otherwise: written by the
    /// solver thread in order with the edits; the recovery journal then starts again.
    void saveScene(const std::string& path);

    /// Switches the viewport's display mode (View ▸ Mode); difference mode asks for a reference.
    void setViewMode(ViewMode mode);
    /// Writes the window's back buffer as PNG (call after the frame was drawn).
    void writeScreenshot(const std::string& path);

    /// The Add menu's meshes (ui/mesh_library.h): the scene's `meshes/` folder and the
    /// repository's `scenes/meshes/`, rescanned whenever the menu opens or on refreshMeshLibrary.
    const std::vector<LibraryEntry>& meshLibrary() const { return mMeshLibrary; }
    void refreshMeshLibrary();
    /// Where the Add menu puts a new object now: the surface under the viewport's centre
    /// (picked through Embree, normal from two neighbouring picks on the same object), else
    /// the view target's distance in front of the camera.
    PlacementTarget addTarget();
    /// Adds `entry` as the Add menu does and selects it: a primitive of kPrimitiveSize, or the
    /// mesh (loaded on the solver thread, its path relative to the scene file, DESIGN.md)
    /// scaled to fit kMeshSize, placed at addTarget(), with the scene's first non-emissive
    /// material unless the mesh file has its own. Returns the new object's id ("" without a
    /// scene or materials); a mesh that fails to load is reported in the status line.
    std::string addFromLibrary(const LibraryEntry& entry);
    /// The file dialogs (File and Add menus).
    enum class Dialog { None, OpenScene, SaveSceneAs, Export, PlayLog, AddMeshFile };
    /// Opens a file dialog as its menu item does (drawn from the next frame on).
    void openDialog(Dialog dialog) { mPopup = static_cast<int>(dialog); }
    /// The open dialog's browser, or nullptr (for tests).
    FileBrowser* fileBrowser() { return mBrowser.get(); }
    static constexpr double kPrimitiveSize = 0.4;  ///< metres across
    static constexpr double kMeshSize = 0.5;       ///< largest bounding-box side, metres

private:
    void openScene(const std::string& path);
    void drawMenu();
    void drawPanels();
    void drawSolverPanel(const SolverSnapshot& s);
    void drawObjectPanel(const DocumentSummary& doc);
    void drawScenePanel(const DocumentSummary& doc);
    void drawViewport();
    void drawStatusBar();
    void drawPopups();
    /// The modal that offers an earlier editor run's unsaved edits (recovery.h).
    void drawRecoveryPrompt();
    /// Removes the journal when it holds no edit (everything was saved).
    void removeEmptyJournal();
    void handleViewportInput(const PointerInput& in, bool hovered);
    void handleKeys();
    void uploadImage();
    void submit(const EditCommand& c);
    void frameSelection();

    EditorOptions mOptions;
    GLFWwindow* mWindow = nullptr;
    std::unique_ptr<SessionRunner> mRunner;
    std::string mScenePath;
    std::string mJournal;   ///< the recovery journal of mScenePath, "" when off
    UnsavedEdits mUnsaved;  ///< an earlier editor run's unsaved edits, while not yet answered

    // View and interaction.
    ViewCamera mView;
    int mViewportX = 0, mViewportY = 0, mViewportW = 0, mViewportH = 0;
    std::string mSelection;
    GizmoMode mGizmoMode = GizmoMode::Translate;
    GizmoSnap mSnap;
    std::optional<Gizmo> mDragGizmo;  ///< while dragging a handle
    DragController mDrag;
    PointerInput mLastPointer;
    bool mPointerDownOnViewport = false;
    double mPressX = 0, mPressY = 0;
    double mLastInteraction = -1e9;  ///< time of the last camera move or drag
    std::deque<PointerInput> mScripted;

    // Viewport texture.
    ViewMode mMode = ViewMode::EdgeAndPoint;
    std::uint64_t mReferenceRequest = 0;  ///< ViewRequest::referenceRequest
    bool mSettlingOverlay = false;        ///< View ▸ Overlay ▸ Settling
    unsigned int mTexture = 0;
    int mTextureW = 0, mTextureH = 0;
    std::shared_ptr<const ViewportImage> mShown;

    // Play.
    std::vector<LoggedEdit> mPlay;
    std::size_t mPlayNext = 0;
    bool mPlayPaused = false;

    // Panels.
    std::string mMaterialFor;
    std::uint64_t mMaterialSerial = 0;
    float mReflectance[3] = {0.5f, 0.5f, 0.5f};
    float mEmissionColour[3] = {1, 1, 1};
    float mEmissionStrength = 0;
    float mConvergeEps = 1e-3f;
    int mPopup = 0;                         ///< 0 none, 1 open, 2 save as, 3 export, 4 play log
    std::unique_ptr<FileBrowser> mBrowser;  ///< the open file dialog's state
    std::vector<LibraryEntry> mMeshLibrary;
    std::set<std::string> mIssuedIds;  ///< ids addFromLibrary gave out
    std::string mStatus;
    bool mQuit = false;
    int mExitStatus = 0;  ///< quit()'s

    // Frames: drawn on demand (needsFrame), the loop ticking at maxFps.
    static void wake(GLFWwindow* window);         ///< GLFW input callbacks: counts the event
    static constexpr double kEagerSeconds = 0.5;  ///< frames drawn after each input event
    /// The view request stays `interactive` this long after the last camera move or drag.
    static constexpr double kInteractiveSeconds = 0.3;
    static constexpr double kBusyRedrawSeconds = 0.25;  ///< status refresh while the light changes
    /// Under a software GL while dragging: frames without a new lit image at most this often.
    static constexpr double kDragRedrawSeconds = 0.05;
    bool mSoftwareGl = false;  ///< the window is drawn by Mesa's llvmpipe or softpipe
    static constexpr double kIdleRedrawSeconds = 1.0;
    std::uint64_t mInputEvents = 0, mInputEventsSeen = 0;
    double mEagerUntil = 0;
    double mLastDrawn = -1e9;
    bool mDrawnLast = false;  ///< the previous tick drew a frame
    FrameStats mStats;
    double mFrameStart = 0;
    int mFrame = 0;
    bool mCaptureNow = false;
    double mCaptureWaitStart = -1;
};

}  // namespace penumbra
