// Index: window and GL setup · scene · frame loop · input (viewport pointer, keys) · panels
//        (menu, solver, object and material, scene, popups, status bar) · viewport texture ·
//        driven input (EditorControls) · screenshot. The Add menu's placement: editor_add.cpp.

#include "ui/editor_app.h"

#include <glad/gl.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <imgui_impl_glfw.h>
#include <imgui_impl_opengl3.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <thread>

#include "core/input_error.h"
#include "edit/io/mesh_io.h"
#include "edit/io/scene_import.h"
#include "render/image.h"
#include "solver/progressive_solver.h"

namespace penumbra {

namespace {

constexpr float kPanelWidth = 360.0f;
constexpr float kStatusHeight = 24.0f;

std::string glfwErrorText() {
    const char* description = nullptr;
    glfwGetError(&description);
    return description ? description : "unknown GLFW error";
}

std::string format(const char* fmt, double a, double b = 0, double c = 0) {
    char buffer[256];
    std::snprintf(buffer, sizeof buffer, fmt, a, b, c);
    return buffer;
}

const char* shapeLabel(ShapeType t) { return shapeTypeName(t); }

}  // namespace

// ---------------------------------------------------------------------------------------------
// Window and GL setup.

EditorApp::EditorApp(EditorOptions options) : mOptions(std::move(options)) {
    // The display first (cheap), then the inputs, so bad input is reported without a window.
    const char* display = std::getenv("DISPLAY");
    if (!display || !*display)
        throw DisplayError("no display: DISPLAY is not set (run under X11, or `xvfb-run -a`)");
    if (!mOptions.play.empty()) {
        const std::string base = mOptions.scene.empty()
                                     ? std::string()
                                     : std::filesystem::path(mOptions.scene).parent_path().string();
        mPlay = readEditLog(mOptions.play, base);
    }
    if (!mOptions.scene.empty()) openScene(mOptions.scene);

    if (!glfwInit()) throw DisplayError("cannot initialise GLFW: " + glfwErrorText());
    const int versions[][2] = {{4, 5}, {3, 3}};
    for (const auto& v : versions) {
        glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, v[0]);
        glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, v[1]);
        glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
        glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
        mWindow = glfwCreateWindow(mOptions.width, mOptions.height, "Penumbra", nullptr, nullptr);
        if (mWindow) break;
    }
    if (!mWindow) {
        const std::string error = glfwErrorText();
        glfwTerminate();
        throw DisplayError("cannot open a GL 3.3+ core window: " + error);
    }
    glfwMakeContextCurrent(mWindow);
    glfwSwapInterval(0);
    if (!gladLoadGL(reinterpret_cast<GLADloadfunc>(glfwGetProcAddress))) {
        glfwDestroyWindow(mWindow);
        glfwTerminate();
        throw DisplayError("cannot load GL functions through glfwGetProcAddress");
    }

    // A software rasterizer draws the window on the cores the display and solver use: a
    // lower frame cap there (still above 30 fps).
    if (const auto* renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER))) {
        const std::string name = renderer;
        mSoftwareGl = name.find("llvmpipe") != std::string::npos ||
                      name.find("softpipe") != std::string::npos;
        if (mSoftwareGl) mOptions.maxFps = std::min(mOptions.maxFps, mOptions.softwareGlMaxFps);
    }

    // Input wakes the frame loop: these count every event (ImGui's backend, installed next,
    // chains the button, scroll, key, char, focus and enter callbacks to these).
    glfwSetWindowUserPointer(mWindow, this);
    glfwSetMouseButtonCallback(mWindow, [](GLFWwindow* w, int, int, int) { wake(w); });
    glfwSetScrollCallback(mWindow, [](GLFWwindow* w, double, double) { wake(w); });
    glfwSetKeyCallback(mWindow, [](GLFWwindow* w, int, int, int, int) { wake(w); });
    glfwSetCharCallback(mWindow, [](GLFWwindow* w, unsigned int) { wake(w); });
    glfwSetWindowFocusCallback(mWindow, [](GLFWwindow* w, int) { wake(w); });
    glfwSetCursorEnterCallback(mWindow, [](GLFWwindow* w, int) { wake(w); });
    glfwSetCursorPosCallback(mWindow, [](GLFWwindow* w, double, double) { wake(w); });
    glfwSetWindowRefreshCallback(mWindow, [](GLFWwindow* w) { wake(w); });
    glfwSetFramebufferSizeCallback(mWindow, [](GLFWwindow* w, int, int) { wake(w); });

    IMGUI_CHECKVERSION();
    ImGui::CreateContext();
    ImGui::GetIO().IniFilename = nullptr;  // fixed layout, no imgui.ini next to the user's files
    ImGui::StyleColorsDark();
    ImGui_ImplGlfw_InitForOpenGL(mWindow, true);
    ImGui_ImplOpenGL3_Init("#version 330 core");

    glGenTextures(1, &mTexture);
    glBindTexture(GL_TEXTURE_2D, mTexture);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);

    if (!mPlay.empty() && mRunner) mRunner->setAutoSolve(false);
    setViewMode(mOptions.mode);
    mSettlingOverlay = mOptions.settlingOverlay;
}

void EditorApp::setViewMode(ViewMode mode) {
    mMode = mode;
    if (mode == ViewMode::Difference && mReferenceRequest == 0) ++mReferenceRequest;
}

EditorApp::~EditorApp() {
    mRunner.reset();  // stop the worker before the window goes
    removeEmptyJournal();
    if (mWindow) {
        if (mTexture) glDeleteTextures(1, &mTexture);
        ImGui_ImplOpenGL3_Shutdown();
        ImGui_ImplGlfw_Shutdown();
        ImGui::DestroyContext();
        glfwDestroyWindow(mWindow);
        glfwTerminate();
    }
}

// ---------------------------------------------------------------------------------------------
// Scene.

std::string editorHolodeckPath(const EditorOptions& options, const std::string& scene) {
    if (options.noHolodeck || scene.empty()) return "";
    if (!options.holodeck.empty() && scene == options.scene) return options.holodeck;
    std::string beside = std::filesystem::path(scene).replace_extension(".hdk").string();
    std::error_code ignored;
    return std::filesystem::is_regular_file(beside, ignored) ? beside : "";
}

void EditorApp::openScene(const std::string& path) {
    auto session = EditSession::open(path, interactiveSolverOptions(), mOptions.import);
    // An imported scene (glTF, OBJ) is saved as a Penumbra scene beside it, never over it.
    const std::string scenePath =
        isImportableScene(path) ? std::filesystem::path(path).replace_extension(".json").string()
                                : path;
    if (!mOptions.log.empty()) session->openLog(mOptions.log);
    // The previous scene's journal ends with its edit session (below); this one's starts now,
    // after what an earlier run of the editor left unsaved was set aside.
    mRunner.reset();
    removeEmptyJournal();
    mUnsaved = {};  // an unanswered offer stays set aside for the next session on its scene
    mJournal.clear();
    // Runs that do not wait for the user (a screenshot, a played log, a benchmark) keep no
    // journal and leave an earlier one as it is, unless told to recover it.
    const bool waitsForUser =
        mOptions.screenshot.empty() && mOptions.play.empty() && !mOptions.driver;
    if (mOptions.journal && mOptions.log.empty() && (waitsForUser || mOptions.recover)) {
        try {
            const std::string journal = recoveryJournalPath(scenePath);
            mUnsaved =
                takeUnsavedEdits(journal, std::filesystem::path(path).parent_path().string());
            session->openLog(journal, true);
            mJournal = journal;
        } catch (const std::exception& e) {
            // No journal is no reason not to open the scene.
            mUnsaved.error = std::string("no recovery journal: ") + e.what();
        }
    }
    SessionRunnerOptions runnerOptions;
    runnerOptions.displayDivisor = std::max(1, mOptions.displayDivisor);
    // The holodeck belongs to the scene file (saved beside it), not to an imported one.
    runnerOptions.holodeck = editorHolodeckPath(mOptions, path);
    mRunner = std::make_unique<SessionRunner>(std::move(session), runnerOptions);
    mRunner->setConvergeEps(mConvergeEps);
    mScenePath = scenePath;
    if (!mUnsaved.edits.empty() && mOptions.recover) recoverUnsaved();
    mSelection.clear();
    const auto doc = mRunner->document();
    if (doc && !doc->cameras.empty()) {
        mView = ViewCamera::fromCamera(doc->cameras.front());
    } else if (doc && !doc->objects.empty()) {
        Vec3 lo = doc->objects[0].boundsMin, hi = doc->objects[0].boundsMax;
        for (const ObjectSummary& o : doc->objects)
            lo = glm::min(lo, o.boundsMin), hi = glm::max(hi, o.boundsMax);
        mView.frame(0.5 * (lo + hi), 0.5 * glm::length(hi - lo));
    }
    refreshMeshLibrary();
    mStatus = mScenePath == path ? "opened " + path
                                 : "imported " + path + " (Save writes " + mScenePath + ")";
    if (!mUnsaved.error.empty()) mStatus += "; recovery: " + mUnsaved.error;
}

void EditorApp::saveScene(const std::string& path) {
    if (!mRunner) return;
    // Written atomically by the solver thread (edit/io/scene_io.h), in order with the edits; once
    // it is written, the journal starts again (for `path`: Save as moves it).
    std::string journal;
    if (!mJournal.empty()) journal = recoveryJournalPath(path);
    // Saved over the scene file, the holodeck beside it takes new points again.
    mRunner->postSave(
        [path, old = mJournal, journal](EditSession& s) {
            s.saveScene(path);
            if (journal.empty()) return;
            // What the journals held is in the file now, and so is whatever an earlier run of the
            // editor left unsaved for `path` (the file replaces it).
            s.closeLog();
            std::error_code ignored;
            for (const std::string& stale : {old, journal, journal + ".unsaved"})
                std::filesystem::remove(stale, ignored);
            s.openLog(journal, true);
        },
        path == mScenePath);
    if (!journal.empty()) mJournal = journal;
    mStatus = "saving " + path;
}

void EditorApp::recoverUnsaved() {
    if (!mRunner) return;
    for (const EditCommand& c : mUnsaved.edits) mRunner->submit(c, EditSource{mUnsaved.file, 0});
    // Dropped once they are applied, and so journaled again.
    mRunner->post([unsaved = mUnsaved](EditSession&) { discardUnsaved(unsaved); });
    mStatus = "recovered " + std::to_string(mUnsaved.edits.size()) + " unsaved edits";
    mUnsaved = {};
}

void EditorApp::removeEmptyJournal() {
    // A session that saved everything leaves nothing to recover.
    std::error_code ignored;
    if (!mJournal.empty() && std::filesystem::exists(mJournal) &&
        std::filesystem::file_size(mJournal, ignored) == 0)
        std::filesystem::remove(mJournal, ignored);
}

void EditorApp::drawRecoveryPrompt() {
    if (mUnsaved.edits.empty() || mPopup != 0) return;
    const char* title = "Recover unsaved edits";
    if (!ImGui::IsPopupOpen(title)) ImGui::OpenPopup(title);
    const ImGuiIO& io = ImGui::GetIO();
    ImGui::SetNextWindowPos(ImVec2(io.DisplaySize.x * 0.5f, io.DisplaySize.y * 0.4f),
                            ImGuiCond_Appearing, ImVec2(0.5f, 0.5f));
    ImGui::SetNextWindowSize(ImVec2(std::min(io.DisplaySize.x - 40.0f, 520.0f), 0.0f));
    if (!ImGui::BeginPopupModal(title, nullptr, ImGuiWindowFlags_NoResize)) return;
    const std::string name = std::filesystem::path(mScenePath).filename().string();
    ImGui::TextWrapped(
        "%zu edits made to %s were not saved when its last session ended. "
        "Recover replays them (the scene file is not changed until you save); "
        "Discard drops them.",
        mUnsaved.edits.size(), name.c_str());
    ImGui::PushTextWrapPos(0.0f);
    ImGui::TextDisabled("%s", mUnsaved.file.c_str());
    ImGui::PopTextWrapPos();
    if (ImGui::Button("Recover")) {
        recoverUnsaved();
        ImGui::CloseCurrentPopup();
    }
    ImGui::SameLine();
    if (ImGui::Button("Discard")) {
        discardUnsaved(mUnsaved);
        mUnsaved = {};
        mStatus = "discarded the unsaved edits";
        ImGui::CloseCurrentPopup();
    }
    ImGui::EndPopup();
}

void EditorApp::submit(const EditCommand& c) {
    if (mRunner) mRunner->submit(c);
}

// ---------------------------------------------------------------------------------------------
// Frame loop.

void EditorApp::wake(GLFWwindow* window) {
    if (auto* app = static_cast<EditorApp*>(glfwGetWindowUserPointer(window))) ++app->mInputEvents;
}

bool EditorApp::needsFrame() {
    const double now = glfwGetTime();
    if (mInputEvents != mInputEventsSeen) {
        mInputEventsSeen = mInputEvents;
        mEagerUntil = now + kEagerSeconds;
    }
    // A drag under a software GL: the window is drawn when a lit image of the viewport comes
    // (the object, its light and its outline move in those), and the gizmo at least every
    // kDragRedrawSeconds. Each drawn frame costs llvmpipe most of a core, which the render
    // thread making those images needs.
    if ((mDragGizmo || mDrag.active()) && mSoftwareGl && mRunner)
        return mRunner->image() != mShown || now - mLastDrawn >= kDragRedrawSeconds;
    if (now < mEagerUntil || !mScripted.empty() || mDragGizmo || mDrag.active()) return true;
    // Until a frame has told the runner the view is no longer interactive.
    if (now - mLastInteraction < kInteractiveSeconds + 0.2) return true;
    if (ImGui::IsAnyMouseDown()) return true;
    for (bool down : ImGui::GetIO().KeysDown)
        if (down) return true;
    if (playing() || (mOptions.driver && mOptions.driver->wantsFrames()) ||
        !mOptions.screenshot.empty() || mCaptureNow)
        return true;
    if (!mRunner) return now - mLastDrawn > kIdleRedrawSeconds;
    if (mRunner->image() != mShown || mRunner->hasMessages()) return true;
    // The status bar's solver figures while the light changes.
    return now - mLastDrawn > (mRunner->quiescent() ? kIdleRedrawSeconds : kBusyRedrawSeconds);
}

int EditorApp::run() {
    int status = 0;
    while (!mQuit && !glfwWindowShouldClose(mWindow)) {
        // A frame only when something on screen can change: input, a new viewport image, a
        // message or the solver's progress. Redrawing an unchanged window costs a software
        // rasterizer a core (the swap copies the whole window), which the solver and the
        // display need after a drop.
        glfwPollEvents();
        if (!needsFrame()) {
            ++mFrame;
            mDrawnLast = false;
            mStats.tick(glfwGetTime());
            if (mOptions.driver) mOptions.driver->tick(*this, glfwGetTime());
            if (mQuit) break;
            if (mOptions.screenshot.empty() && !mOptions.driver && mOptions.frames > 0 &&
                mFrame >= mOptions.frames)
                break;
            glfwWaitEventsTimeout(1.0 / std::max(mOptions.maxFps, 1.0));
            continue;
        }
        const bool capture = mCaptureNow;
        if (!frame()) break;
        if (capture) {
            try {
                writeScreenshot(mOptions.screenshot);
                if (!mOptions.quiet)
                    std::cerr << "penumbra-editor: wrote " << mOptions.screenshot << "\n";
            } catch (const std::exception& e) {
                std::cerr << "penumbra-editor: " << e.what() << "\n";
                status = 1;
            }
            glfwSwapBuffers(mWindow);
            break;
        }
        glfwSwapBuffers(mWindow);

        // Cap the frame rate (Xvfb has no vertical sync) so the worker keeps its core.
        const double period = 1.0 / std::max(mOptions.maxFps, 1.0);
        const double left = mFrameStart + period - glfwGetTime();
        if (left > 0) std::this_thread::sleep_for(std::chrono::duration<double>(left));

        // Screenshot: after `frames` frames, once the replay is done and the lighting and
        // image are settled (at most 120 s more), capture the next frame.
        if (!mOptions.screenshot.empty() && mFrame >= mOptions.frames) {
            const bool settled =
                !playing() && (!mRunner || (mRunner->quiescent() && mShown == mRunner->image()));
            if (mCaptureWaitStart < 0) mCaptureWaitStart = glfwGetTime();
            if (settled || glfwGetTime() - mCaptureWaitStart > 120) {
                if (!settled)
                    std::cerr << "penumbra-editor: warning: screenshot before the "
                                 "lighting settled (120 s)\n";
                mCaptureNow = true;
            }
        }
        if (mOptions.screenshot.empty() && !mOptions.driver && mOptions.frames > 0 &&
            mFrame >= mOptions.frames)
            break;
    }
    if (mOptions.driver) mOptions.driver->finished(*this);
    return status != 0 ? status : mExitStatus;
}

bool EditorApp::frame() {
    const double start = glfwGetTime();
    // Frame periods between consecutive drawn frames: the rate while something changes.
    if (mStats.frames > 0 && mDrawnLast) mStats.periodMs.push_back((start - mFrameStart) * 1e3);
    mDrawnLast = true;
    mLastDrawn = start;
    mStats.tick(start);
    mFrameStart = start;
    ++mFrame;

    glfwPollEvents();
    ImGui_ImplOpenGL3_NewFrame();
    ImGui_ImplGlfw_NewFrame();
    ImGui::NewFrame();

    // Replay: one log line every few frames.
    if (mRunner && playing() && !mPlayPaused && mFrame % std::max(mOptions.playEvery, 1) == 0) {
        const LoggedEdit& e = mPlay[mPlayNext++];
        mRunner->submit(e.command, EditSource{mOptions.play, e.line});
        if (!playing()) {
            mRunner->setAutoSolve(true);
            mStatus = "replayed " + mOptions.play;
        }
    }
    if (mRunner)
        for (const std::string& m : mRunner->takeMessages()) {
            mStatus = m;
            if (!mOptions.quiet) std::cerr << "penumbra-editor: " << m << "\n";
        }
    if (mOptions.driver) mOptions.driver->tick(*this, glfwGetTime());

    uploadImage();
    drawMenu();
    drawViewport();
    drawPanels();
    drawStatusBar();
    drawPopups();
    drawRecoveryPrompt();
    handleKeys();

    // Tell the worker what to render.
    if (mRunner && mViewportW > 0 && mViewportH > 0) {
        ViewRequest request;
        request.camera = mView.toCamera();
        request.width = mViewportW;
        request.height = mViewportH;
        request.highlight = mSelection;
        request.interactive =
            mDrag.active() || glfwGetTime() - mLastInteraction < kInteractiveSeconds;
        request.mode = mMode;
        request.referenceRequest = mReferenceRequest;
        request.settlingOverlay = mSettlingOverlay;
        mRunner->setView(request);
    }

    ImGui::Render();
    int fbw = 0, fbh = 0;
    glfwGetFramebufferSize(mWindow, &fbw, &fbh);
    glViewport(0, 0, fbw, fbh);
    glClearColor(0.1f, 0.1f, 0.11f, 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());

    mStats.lastMs = (glfwGetTime() - start) * 1e3;
    mStats.workMs.push_back(mStats.lastMs);
    ++mStats.frames;
    return !mQuit;
}

// ---------------------------------------------------------------------------------------------
// Input.

std::optional<Gizmo> EditorApp::gizmo() const {
    if (mDragGizmo) return mDragGizmo;
    if (mSelection.empty() || !mRunner) return std::nullopt;
    const auto doc = mRunner->document();
    const ObjectSummary* o = doc ? doc->find(mSelection) : nullptr;
    if (!o) return std::nullopt;
    return Gizmo(mGizmoMode, o->transform, gizmoSize(o->transform.translate));
}

double EditorApp::gizmoSize(const Vec3& pivot) const {
    // About a sixth of the view's height at the pivot's distance.
    const double d = std::max(glm::length(pivot - mView.position()), 1e-3);
    return 0.3 * d * std::tan(glm::radians(mView.fovDeg) * 0.5);
}

void EditorApp::handleViewportInput(const PointerInput& in, bool hovered) {
    const PointerInput last = mLastPointer;
    mLastPointer = in;
    if (!mRunner || mViewportW <= 0 || mViewportH <= 0) return;
    const Camera camera = mView.toCamera();
    const double dx = in.x - last.x, dy = in.y - last.y;
    const bool pressedLeft = in.left && !last.left, releasedLeft = !in.left && last.left;

    // A handle drag in progress: new positions, then unselect on release.
    if (mDragGizmo) {
        const Ray ray = pixelRay(camera, mViewportW, mViewportH, in.x, in.y);
        if (auto c = mDrag.update(mDragGizmo->drag(ray, mSnap))) mRunner->submitCoalescing(*c);
        mLastInteraction = glfwGetTime();
        if (releasedLeft) {
            for (const EditCommand& c : mDrag.end()) submit(c);
            mDragGizmo.reset();
        }
        return;
    }

    if (hovered && pressedLeft) {
        mPointerDownOnViewport = true;
        mPressX = in.x, mPressY = in.y;
        // A gizmo handle under the cursor starts a drag (select → positions → unselect).
        if (auto g = gizmo()) {
            const GizmoHandle h = g->hitTest(camera, mViewportW, mViewportH, {in.x, in.y});
            if (h != GizmoHandle::None &&
                g->begin(h, pixelRay(camera, mViewportW, mViewportH, in.x, in.y))) {
                mDragGizmo = *g;
                for (const EditCommand& c : mDrag.begin(mSelection, g->transform())) submit(c);
                mPointerDownOnViewport = false;
                return;
            }
        }
    }
    if (releasedLeft && mPointerDownOnViewport) {
        mPointerDownOnViewport = false;
        // A click (not a drag) picks through Embree.
        if (std::abs(in.x - mPressX) + std::abs(in.y - mPressY) < 4) {
            const Pick pick = mRunner->pick(camera, mViewportW, mViewportH, in.x, in.y);
            mSelection = pick.id;
            mStatus = pick.hit() ? "selected " + pick.id : "nothing selected";
        }
    }
    if (!hovered && !(in.right || in.middle)) return;

    // Camera: right drag orbits (with Shift: pans), middle drag pans, wheel zooms.
    bool moved = false;
    if ((in.right && last.right) && (dx != 0 || dy != 0)) {
        if (in.shift)
            mView.pan(dx, dy, mViewportH);
        else
            mView.orbit(dx * 0.005, -dy * 0.005);
        moved = true;
    }
    if (in.middle && last.middle && (dx != 0 || dy != 0)) {
        mView.pan(dx, dy, mViewportH);
        moved = true;
    }
    if (hovered && in.wheel != 0) {
        mView.zoom(std::pow(0.88, in.wheel));
        moved = true;
    }
    if (moved) mLastInteraction = glfwGetTime();
}

void EditorApp::handleKeys() {
    ImGuiIO& io = ImGui::GetIO();
    if (io.WantTextInput || !mRunner) return;
    const bool ctrl = io.KeyCtrl, shift = io.KeyShift;
    if (ctrl && ImGui::IsKeyPressed(GLFW_KEY_Z, false)) {
        if (mDrag.active())
            mStatus = "finish the drag before undo";
        else
            submit(shift ? EditCommand(RedoCommand{}) : EditCommand(UndoCommand{}));
    }
    if (ctrl && ImGui::IsKeyPressed(GLFW_KEY_Y, false) && !mDrag.active()) submit(RedoCommand{});
    if (ctrl && ImGui::IsKeyPressed(GLFW_KEY_S, false)) saveScene(mScenePath);
    if (ctrl) return;
    // Fly with WASD (and Q/E down/up) while the right button is held.
    if (ImGui::IsMouseDown(ImGuiMouseButton_Right)) {
        const double speed = std::max(mView.distance, 0.5) * io.DeltaTime * (shift ? 3.0 : 1.0);
        Vec3 d(0.0);
        if (ImGui::IsKeyDown(GLFW_KEY_W)) d.z += speed;
        if (ImGui::IsKeyDown(GLFW_KEY_S)) d.z -= speed;
        if (ImGui::IsKeyDown(GLFW_KEY_D)) d.x += speed;
        if (ImGui::IsKeyDown(GLFW_KEY_A)) d.x -= speed;
        if (ImGui::IsKeyDown(GLFW_KEY_E)) d.y += speed;
        if (ImGui::IsKeyDown(GLFW_KEY_Q)) d.y -= speed;
        if (d != Vec3(0.0)) {
            mView.fly(d);
            mLastInteraction = glfwGetTime();
        }
        return;
    }
    if (ImGui::IsKeyPressed(GLFW_KEY_F, false)) frameSelection();
    if (ImGui::IsKeyPressed(GLFW_KEY_W, false)) mGizmoMode = GizmoMode::Translate;
    if (ImGui::IsKeyPressed(GLFW_KEY_E, false)) mGizmoMode = GizmoMode::Rotate;
    if (ImGui::IsKeyPressed(GLFW_KEY_R, false)) mGizmoMode = GizmoMode::Scale;
    if (ImGui::IsKeyPressed(GLFW_KEY_ESCAPE, false) && mDrag.active()) {
        for (const EditCommand& c : mDrag.cancel()) submit(c);
        mDragGizmo.reset();
    }
    if (ImGui::IsKeyPressed(GLFW_KEY_DELETE, false) && !mSelection.empty() && !mDrag.active()) {
        submit(RemoveCommand{mSelection});
        mSelection.clear();
    }
}

void EditorApp::frameSelection() {
    if (!mRunner) return;
    const auto doc = mRunner->document();
    if (!doc || doc->objects.empty()) return;
    Vec3 lo(1e30), hi(-1e30);
    for (const ObjectSummary& o : doc->objects)
        if (mSelection.empty() || o.id == mSelection)
            lo = glm::min(lo, o.boundsMin), hi = glm::max(hi, o.boundsMax);
    if (lo.x > hi.x) return;
    const double aspect = mViewportH > 0 ? double(mViewportW) / mViewportH : 1.0;
    mView.frame(0.5 * (lo + hi), std::max(0.5 * glm::length(hi - lo), 0.05), aspect);
    mLastInteraction = glfwGetTime();
}

// ---------------------------------------------------------------------------------------------
// Panels.

void EditorApp::drawMenu() {
    if (!ImGui::BeginMainMenuBar()) return;
    if (ImGui::BeginMenu("File")) {
        if (ImGui::MenuItem("Open scene...")) mPopup = 1;
        if (ImGui::MenuItem("Save", "Ctrl+S", false, mRunner != nullptr)) saveScene(mScenePath);
        if (ImGui::MenuItem("Save as...", nullptr, false, mRunner != nullptr)) mPopup = 2;
        if (ImGui::MenuItem("Export...", nullptr, false, mRunner != nullptr)) mPopup = 3;
        if (ImGui::MenuItem("Play edit log...", nullptr, false, mRunner != nullptr)) mPopup = 4;
        ImGui::Separator();
        if (ImGui::MenuItem("Quit")) mQuit = true;
        ImGui::EndMenu();
    }
    if (ImGui::BeginMenu("Edit")) {
        const SolverSnapshot s = mRunner ? mRunner->solver() : SolverSnapshot{};
        if (ImGui::MenuItem("Undo", "Ctrl+Z", false, s.undoDepth > 0 && !mDrag.active()))
            submit(UndoCommand{});
        if (ImGui::MenuItem("Redo", "Ctrl+Shift+Z", false, s.redoDepth > 0 && !mDrag.active()))
            submit(RedoCommand{});
        ImGui::Separator();
        if (ImGui::MenuItem("Translate", "W", mGizmoMode == GizmoMode::Translate))
            mGizmoMode = GizmoMode::Translate;
        if (ImGui::MenuItem("Rotate", "E", mGizmoMode == GizmoMode::Rotate))
            mGizmoMode = GizmoMode::Rotate;
        if (ImGui::MenuItem("Scale", "R", mGizmoMode == GizmoMode::Scale))
            mGizmoMode = GizmoMode::Scale;
        ImGui::MenuItem("Snap", nullptr, &mSnap.enabled);
        ImGui::Separator();
        if (ImGui::MenuItem("Delete", "Del", false, !mSelection.empty() && !mDrag.active())) {
            submit(RemoveCommand{mSelection});
            mSelection.clear();
        }
        ImGui::EndMenu();
    }
    if (ImGui::BeginMenu("Add")) {
        // The library (ui/mesh_library.h): primitives, the meshes found next to the scene and
        // in the repository's scenes/meshes/, or any mesh file.
        if (ImGui::IsWindowAppearing()) refreshMeshLibrary();
        const auto doc = mRunner ? mRunner->document() : nullptr;
        const bool canAdd = doc && !doc->materials.empty() && !mDrag.active();
        for (const LibraryEntry& e : listPrimitives())
            if (ImGui::MenuItem(e.label.c_str(), nullptr, false, canAdd)) addFromLibrary(e);
        ImGui::Separator();
        if (ImGui::BeginMenu("Mesh", canAdd)) {
            if (mMeshLibrary.empty())
                ImGui::TextDisabled("no mesh files in meshes/ or scenes/meshes/");
            for (const LibraryEntry& e : mMeshLibrary)
                if (ImGui::MenuItem(e.label.c_str())) addFromLibrary(e);
            ImGui::EndMenu();
        }
        if (ImGui::MenuItem("Mesh file...", nullptr, false, canAdd)) mPopup = 5;
        ImGui::EndMenu();
    }
    if (ImGui::BeginMenu("View")) {
        if (ImGui::MenuItem("Frame selection", "F")) frameSelection();
        if (ImGui::BeginMenu("Mode")) {
            for (int m = 0; m < kViewModeCount; ++m) {
                const ViewMode mode = static_cast<ViewMode>(m);
                if (ImGui::MenuItem(viewModeLabel(mode), nullptr, mMode == mode)) setViewMode(mode);
            }
            ImGui::EndMenu();
        }
        if (ImGui::MenuItem("Compute reference", nullptr, false, mMode == ViewMode::Difference))
            ++mReferenceRequest;
        if (ImGui::BeginMenu("Overlay")) {
            ImGui::MenuItem("Settling", nullptr, &mSettlingOverlay);
            ImGui::EndMenu();
        }
        ImGui::EndMenu();
    }
    ImGui::EndMainMenuBar();
}

void EditorApp::drawPanels() {
    const ImGuiIO& io = ImGui::GetIO();
    const float top = ImGui::GetFrameHeight();
    ImGui::SetNextWindowPos(ImVec2(io.DisplaySize.x - kPanelWidth, top));
    ImGui::SetNextWindowSize(ImVec2(kPanelWidth, io.DisplaySize.y - top - kStatusHeight));
    ImGui::Begin("Panels", nullptr,
                 ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoCollapse |
                     ImGuiWindowFlags_NoTitleBar);
    if (!mRunner) {
        ImGui::TextWrapped("No scene. File > Open scene...");
        ImGui::End();
        return;
    }
    const SolverSnapshot s = mRunner->solver();
    const auto doc = mRunner->document();
    if (ImGui::CollapsingHeader("Solver", ImGuiTreeNodeFlags_DefaultOpen)) drawSolverPanel(s);
    if (doc && ImGui::CollapsingHeader("Object", ImGuiTreeNodeFlags_DefaultOpen))
        drawObjectPanel(*doc);
    if (doc && ImGui::CollapsingHeader("Scene", ImGuiTreeNodeFlags_DefaultOpen))
        drawScenePanel(*doc);
    ImGui::End();
}

void EditorApp::drawSolverPanel(const SolverSnapshot& s) {
    bool paused = mRunner->paused();
    if (ImGui::Checkbox("Pause", &paused)) mRunner->setPaused(paused);
    ImGui::SameLine();
    ImGui::TextUnformatted(s.idle ? (s.converged ? "converged" : "idle") : "solving");
    ImGui::Text("shots %llu (%llu redistribution)", static_cast<unsigned long long>(s.shots),
                static_cast<unsigned long long>(s.redistributionShots));
    ImGui::Text("shots/s %.0f   rays %.2fM", s.shotsPerSecond, s.rays * 1e-6);
    ImGui::Text("unshot %.2e of emitted", s.unshotFraction);
    ImGui::Text("pending redistribution %.3g W (%zu edits)", s.pendingRedistribution,
                s.pendingChanges);
    ImGui::Text("elements %zu   patches %zu", s.elements, s.patches);
    if (!s.history.empty())
        ImGui::PlotLines("##conv", s.history.data(), static_cast<int>(s.history.size()), 0,
                         "log10 unshot", -5.0f, 0.0f, ImVec2(kPanelWidth - 20, 60));
    if (ImGui::SliderFloat("converge at", &mConvergeEps, 1e-5f, 1e-1f, "%.0e",
                           ImGuiSliderFlags_Logarithmic))
        mRunner->setConvergeEps(mConvergeEps);
    // George et al.'s interleaving of redistribution and shooting: strategy one redistributes
    // first while the strongest pending redistribution carries more than the threshold ×
    // emitted power; strategy two always shoots whichever carries more energy.
    int strategy = mRunner->strategy() == RedistributionStrategy::RedistributeFirst ? 0 : 1;
    float threshold = static_cast<float>(mRunner->redistributionThreshold());
    ImGui::TextUnformatted("strategy");
    ImGui::SameLine();
    bool strategyChanged = ImGui::RadioButton("one", &strategy, 0);
    if (ImGui::IsItemHovered())
        ImGui::SetTooltip(
            "redistribute first while an edit's pending redistribution carries\n"
            "more than the threshold x emitted power, then interleave");
    ImGui::SameLine();
    strategyChanged |= ImGui::RadioButton("two", &strategy, 1);
    if (ImGui::IsItemHovered())
        ImGui::SetTooltip("interleave: always shoot whichever carries more energy");
    ImGui::SameLine();
    ImGui::TextDisabled(strategy == 0 ? "(redistribute first)" : "(interleave)");
    if (strategy == 0)
        strategyChanged |= ImGui::SliderFloat("redistribute >", &threshold, 1e-6f, 1e-1f, "%.0e",
                                              ImGuiSliderFlags_Logarithmic);
    if (strategyChanged)
        mRunner->setStrategy(strategy == 0 ? RedistributionStrategy::RedistributeFirst
                                           : RedistributionStrategy::Interleave,
                             std::clamp(static_cast<double>(threshold), 0.0, 1.0));
    if (s.strategy != mRunner->strategy() ||
        s.redistributionThreshold != mRunner->redistributionThreshold())
        ImGui::TextDisabled("(switching strategy)");
    if (playing()) {
        ImGui::Text("playing %zu / %zu", mPlayNext, mPlay.size());
        ImGui::SameLine();
        ImGui::Checkbox("hold", &mPlayPaused);
        ImGui::SameLine();
        if (ImGui::Button("step") && mPlayNext < mPlay.size()) {
            const LoggedEdit& e = mPlay[mPlayNext++];
            mRunner->submit(e.command, EditSource{mOptions.play, e.line});
        }
    }
}

void EditorApp::drawObjectPanel(const DocumentSummary& doc) {
    const ObjectSummary* o = doc.find(mSelection);
    if (!o) {
        ImGui::TextDisabled("click an object to select it");
        return;
    }
    ImGui::Text("%s  (%s)", o->id.c_str(), shapeLabel(o->shape));
    const Transform& t = o->transform;
    ImGui::Text("at %.3f %.3f %.3f", t.translate.x, t.translate.y, t.translate.z);
    ImGui::Text("rotate %.1f %.1f %.1f", t.rotateDeg.x, t.rotateDeg.y, t.rotateDeg.z);
    ImGui::Text("scale %.3f %.3f %.3f", t.scale.x, t.scale.y, t.scale.z);
    int mode = static_cast<int>(mGizmoMode);
    ImGui::RadioButton("move", &mode, 0);
    ImGui::SameLine();
    ImGui::RadioButton("rotate", &mode, 1);
    ImGui::SameLine();
    ImGui::RadioButton("scale", &mode, 2);
    ImGui::SameLine();
    ImGui::Checkbox("snap", &mSnap.enabled);
    mGizmoMode = static_cast<GizmoMode>(mode);
    if (ImGui::Button("Duplicate") && !mDrag.active()) {
        // The same object beside it (the document object is not at hand here: only meshes'
        // summaries are, so duplicate through the scene).
        // The copy is made from the document on the solver thread; its id is chosen here.
        std::string id;
        for (int k = 2;; ++k) {
            id = o->id + "-" + std::to_string(k);
            if (!doc.find(id)) break;
        }
        const std::string from = o->id;
        const double dx = 0.6 * (o->boundsMax.x - o->boundsMin.x) + 0.1;
        mRunner->submitMade([from, id, dx](EditSession& s) -> EditCommand {
            const int i = s.scene().findObject(from);
            if (i < 0) throw std::runtime_error("duplicate: object '" + from + "' is gone");
            SceneObject copy = s.scene().objects[i];
            copy.id = id;
            copy.transform.translate.x += dx;
            return AddCommand{copy};
        });
        mSelection = id;
        return;
    }
    ImGui::SameLine();
    if (ImGui::Button("Delete") && !mDrag.active()) {
        submit(RemoveCommand{o->id});
        mSelection.clear();
        return;
    }

    // Material: reflectance, emission colour and strength; lights are emissive objects.
    if (o->material.empty()) {
        ImGui::TextDisabled("materials from the mesh file");
        return;
    }
    if (mMaterialFor != o->id || (mMaterialSerial != doc.serial && !ImGui::IsAnyItemActive())) {
        mMaterialFor = o->id;
        mMaterialSerial = doc.serial;
        const Material& m = o->materialValue;
        for (int k = 0; k < 3; ++k) mReflectance[k] = static_cast<float>(m.reflectance[k]);
        const double peak = std::max({m.emission.x, m.emission.y, m.emission.z});
        mEmissionStrength = static_cast<float>(peak);
        for (int k = 0; k < 3; ++k)
            mEmissionColour[k] = peak > 0 ? static_cast<float>(m.emission[k] / peak) : 1.0f;
    }
    ImGui::Text("material '%s'", o->material.c_str());
    ImGui::ColorEdit3("reflectance", mReflectance);
    if (ImGui::IsItemDeactivatedAfterEdit()) {
        MaterialCommand c;
        c.id = o->id;
        c.reflectance = Rgb(std::min(mReflectance[0], 0.99f), std::min(mReflectance[1], 0.99f),
                            std::min(mReflectance[2], 0.99f));
        submit(c);
    }
    ImGui::ColorEdit3("emission", mEmissionColour);
    const bool colourDone = ImGui::IsItemDeactivatedAfterEdit();
    ImGui::SliderFloat("strength W/m2", &mEmissionStrength, 0.0f, 100.0f);
    if (colourDone || ImGui::IsItemDeactivatedAfterEdit()) {
        MaterialCommand c;
        c.id = o->id;
        c.emission = Rgb(mEmissionColour[0], mEmissionColour[1], mEmissionColour[2]) *
                     static_cast<double>(std::max(mEmissionStrength, 0.0f));
        submit(c);
    }
}

void EditorApp::drawScenePanel(const DocumentSummary& doc) {
    if (!doc.cameras.empty()) {
        ImGui::TextUnformatted("cameras:");
        for (const Camera& c : doc.cameras) {
            ImGui::SameLine();
            if (ImGui::SmallButton(c.name.c_str())) {
                mView = ViewCamera::fromCamera(c);
                mLastInteraction = glfwGetTime();
            }
        }
    }
    ImGui::BeginChild("objects", ImVec2(0, 0), true);
    for (const ObjectSummary& o : doc.objects)
        if (ImGui::Selectable(o.id.c_str(), o.id == mSelection)) mSelection = o.id;
    ImGui::EndChild();
}

void EditorApp::drawPopups() {
    static const char* titles[] = {"",       "Open scene",    "Save scene as",
                                   "Export", "Play edit log", "Add mesh file"};
    if (mPopup > 0 && !mBrowser) {
        // A file browser for the dialog, starting next to the scene.
        namespace fs = std::filesystem;
        const fs::path sceneDir =
            mScenePath.empty() ? fs::current_path() : fs::path(mScenePath).parent_path();
        switch (mPopup) {
            case 1:
                mBrowser = std::make_unique<FileBrowser>(
                    FileDialogKind::Open, mScenePath.empty() ? sceneDir.string() : mScenePath,
                    std::vector<std::string>{".json", ".gltf", ".glb", ".obj"});
                break;
            case 2:
                mBrowser = std::make_unique<FileBrowser>(
                    FileDialogKind::Save, mScenePath, std::vector<std::string>{".json"}, ".json");
                break;
            case 3:
                mBrowser = std::make_unique<FileBrowser>(
                    FileDialogKind::Save, (sceneDir / "export.gltf").string(),
                    std::vector<std::string>{".gltf", ".glb", ".ply", ".obj", ".png"}, ".gltf");
                break;
            case 4: {
                const fs::path logs = sceneDir / "logs";
                mBrowser =
                    std::make_unique<FileBrowser>(FileDialogKind::Open,
                                                  !mOptions.play.empty()   ? mOptions.play
                                                  : fs::is_directory(logs) ? logs.string()
                                                                           : sceneDir.string(),
                                                  std::vector<std::string>{".jsonl"});
                break;
            }
            default: {
                const auto roots = meshLibraryRoots(mScenePath, findSourceDir(sceneDir.string()));
                mBrowser = std::make_unique<FileBrowser>(
                    FileDialogKind::Open, roots.empty() ? sceneDir.string() : roots.front(),
                    std::vector<std::string>{".obj", ".off", ".ply", ".stl", ".gltf", ".glb"});
                break;
            }
        }
        ImGui::OpenPopup(titles[mPopup]);
    }
    if (!mBrowser) return;
    std::string path;
    const FileDialogResult result = drawFileDialog(titles[mPopup], *mBrowser, &path);
    if (result == FileDialogResult::Open) return;
    const int popup = mPopup;
    mPopup = 0;
    mBrowser.reset();
    if (result == FileDialogResult::Cancelled) return;
    try {
        if (popup == 1) {
            openScene(path);
        } else if (popup == 2) {
            saveScene(path);
            mScenePath = path;
        } else if (popup == 3) {
            const std::string ext = std::filesystem::path(path).extension().string();
            if (ext == ".png" || ext == ".PNG") {
                if (!mShown) throw std::runtime_error("no image yet");
                writePng(mShown->render.radiance, path);
            } else {
                mRunner->post([path](EditSession& s) { s.exportLitScene(path); });
            }
            mStatus = "exporting " + path;
        } else if (popup == 4) {
            const std::string base = std::filesystem::path(mScenePath).parent_path().string();
            mPlay = readEditLog(path, base);
            mPlayNext = 0;
            mOptions.play = path;
            mRunner->setAutoSolve(mPlay.empty());
        } else if (popup == 5) {
            addFromLibrary(LibraryEntry{std::filesystem::path(path).filename().string(),
                                        ShapeType::Mesh, path});
        }
    } catch (const std::exception& e) {
        mStatus = e.what();
    }
}

namespace {

/// The status line's word on the settling estimate: how much is still to change, or that the
/// lighting settled and how long after the last edit.
std::string settlingStatus(const SolverSnapshot& s) {
    if (s.settlingRms < 0) return "";
    if (!s.settled) return format("lighting settling: %.1f%% still to change", 100 * s.settlingRms);
    if (s.settleSeconds < 0) return "lighting settled";
    return format("lighting settled %.1f s after the last edit", s.settleSeconds);
}

}  // namespace

void EditorApp::drawStatusBar() {
    const ImGuiIO& io = ImGui::GetIO();
    ImGui::SetNextWindowPos(ImVec2(0, io.DisplaySize.y - kStatusHeight));
    ImGui::SetNextWindowSize(ImVec2(io.DisplaySize.x, kStatusHeight));
    ImGui::Begin(
        "Status", nullptr,
        ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoSavedSettings);
    // Mean work time over the last 30 frames.
    double ms = 0;
    const std::size_t n = std::min<std::size_t>(30, mStats.workMs.size());
    for (std::size_t i = mStats.workMs.size() - n; i < mStats.workMs.size(); ++i)
        ms += mStats.workMs[i];
    ms = n ? ms / n : 0;
    // What a lighting designer waits for first: whether the light has settled.
    std::string text;
    if (mRunner)
        if (const std::string settling = settlingStatus(mRunner->solver()); !settling.empty())
            text = settling + "   ";
    text += format("frame %.1f ms (%.0f fps)", ms, io.Framerate);
    if (mShown) {
        text += format("   view %.0fx%.0f in %.0f ms", mShown->render.radiance.width,
                       mShown->render.radiance.height, mShown->renderMs);
        text += std::string("   ") + viewModeLabel(mShown->mode);
        if (usesInteractiveDisplay(mShown->mode))
            text += format(" (%.0f new samples, %.0f edges)",
                           static_cast<double>(mShown->display.newSamples),
                           static_cast<double>(mShown->display.screenEdges));
        if (mShown->meanDifference >= 0)
            text += format(" mean |diff| %.4f", mShown->meanDifference);
        if (!mShown->note.empty()) text += ": " + mShown->note;
    }
    if (mRunner) {
        const SolverSnapshot s = mRunner->solver();
        text += format("   %.0f shots/s   undo %.0f redo %.0f", s.shotsPerSecond,
                       static_cast<double>(s.undoDepth), static_cast<double>(s.redoDepth));
        if (!s.holodeck.path.empty()) text += "   " + s.holodeck.toString();
    }
    text += "   " + mStatus;
    ImGui::TextUnformatted(text.c_str());
    ImGui::End();
}

// ---------------------------------------------------------------------------------------------
// Viewport.

void EditorApp::drawViewport() {
    const ImGuiIO& io = ImGui::GetIO();
    const float top = ImGui::GetFrameHeight();
    ImGui::SetNextWindowPos(ImVec2(0, top));
    ImGui::SetNextWindowSize(
        ImVec2(io.DisplaySize.x - kPanelWidth, io.DisplaySize.y - top - kStatusHeight));
    ImGui::PushStyleVar(ImGuiStyleVar_WindowPadding, ImVec2(0, 0));
    ImGui::Begin("Viewport", nullptr,
                 ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_NoMove |
                     ImGuiWindowFlags_NoBringToFrontOnFocus | ImGuiWindowFlags_NoSavedSettings |
                     ImGuiWindowFlags_NoBackground);
    const ImVec2 origin = ImGui::GetCursorScreenPos();
    const ImVec2 size = ImGui::GetContentRegionAvail();
    mViewportX = static_cast<int>(origin.x), mViewportY = static_cast<int>(origin.y);
    mViewportW = std::max(0, static_cast<int>(size.x));
    mViewportH = std::max(0, static_cast<int>(size.y));
    if (mShown && mTextureW > 0) {
        // The image is opaque and covers the window (drawn without a background): without
        // blending. Under a software rasterizer the viewport's pixels are most of the UI's cost.
        ImDrawList* draw = ImGui::GetWindowDrawList();
        draw->AddCallback([](const ImDrawList*, const ImDrawCmd*) { glDisable(GL_BLEND); },
                          nullptr);
        ImGui::Image(reinterpret_cast<ImTextureID>(static_cast<intptr_t>(mTexture)), size);
        draw->AddCallback(ImDrawCallback_ResetRenderState, nullptr);
    } else
        ImGui::InvisibleButton("##viewport",
                               ImVec2(std::max(size.x, 1.0f), std::max(size.y, 1.0f)));
    const bool hovered = ImGui::IsWindowHovered();

    // Pointer: scripted input when queued, else the mouse.
    PointerInput in;
    bool scripted = false;
    if (!mScripted.empty()) {
        in = mScripted.front();
        mScripted.pop_front();
        scripted = true;
    } else {
        in.x = io.MousePos.x - origin.x;
        in.y = io.MousePos.y - origin.y;
        in.left = io.MouseDown[0];
        in.right = io.MouseDown[1];
        in.middle = io.MouseDown[2];
        in.wheel = hovered ? io.MouseWheel : 0;
        in.shift = io.KeyShift;
    }
    const bool inside = in.x >= 0 && in.y >= 0 && in.x < mViewportW && in.y < mViewportH;
    handleViewportInput(in, scripted ? inside : hovered);

    // The gizmo, drawn over the image.
    if (mViewportW > 0 && mViewportH > 0)
        if (auto g = gizmo()) {
            Gizmo shown = *g;
            if (mDragGizmo) shown = Gizmo(g->mode(), mDrag.current(), g->size());
            const ImU32 colours[] = {IM_COL32(230, 60, 60, 255), IM_COL32(80, 210, 80, 255),
                                     IM_COL32(70, 120, 240, 255), IM_COL32(230, 230, 230, 255)};
            ImDrawList* draw = ImGui::GetWindowDrawList();
            for (const GizmoShape& s : shown.shapes(mView.toCamera(), mViewportW, mViewportH)) {
                int axis = 3;
                switch (s.handle) {
                    case GizmoHandle::X:
                    case GizmoHandle::PlaneYZ:
                        axis = 0;
                        break;
                    case GizmoHandle::Y:
                    case GizmoHandle::PlaneZX:
                        axis = 1;
                        break;
                    case GizmoHandle::Z:
                    case GizmoHandle::PlaneXY:
                        axis = 2;
                        break;
                    default:
                        break;
                }
                std::vector<ImVec2> pts;
                for (const glm::dvec2& p : s.points)
                    pts.emplace_back(origin.x + static_cast<float>(p.x),
                                     origin.y + static_cast<float>(p.y));
                const bool active = mDragGizmo && mDragGizmo->active() == s.handle;
                ImU32 c = active ? IM_COL32(255, 220, 40, 255) : colours[axis];
                if (s.filled)
                    draw->AddConvexPolyFilled(pts.data(), static_cast<int>(pts.size()),
                                              (c & 0x00ffffff) | 0x90000000);
                else
                    draw->AddPolyline(pts.data(), static_cast<int>(pts.size()), c,
                                      s.closed ? ImDrawFlags_Closed : 0, 2.5f);
            }
        }
    ImGui::End();
    ImGui::PopStyleVar();
}

void EditorApp::uploadImage() {
    if (!mRunner) return;
    auto img = mRunner->image();
    if (!img || img == mShown || img->render.rgba.empty()) return;
    const int w = img->render.radiance.width, h = img->render.radiance.height;
    glBindTexture(GL_TEXTURE_2D, mTexture);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    if (w != mTextureW || h != mTextureH) {
        glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, w, h, 0, GL_RGBA, GL_UNSIGNED_BYTE,
                     img->render.rgba.data());
        mTextureW = w, mTextureH = h;
    } else {
        glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE,
                        img->render.rgba.data());
    }
    mShown = img;
    ++mStats.imagesShown;
    mStats.imageMs.push_back(img->renderMs);
    if (mOptions.driver) mOptions.driver->shown(*this, img, glfwGetTime());
}

// ---------------------------------------------------------------------------------------------
// Driven input (EditorControls): the gizmo's press, positions and release without a pointer.

bool EditorApp::beginDrag() {
    if (!mRunner || mDrag.active() || mSelection.empty()) return false;
    const auto doc = mRunner->document();
    const ObjectSummary* o = doc ? doc->find(mSelection) : nullptr;
    if (!o) return false;
    for (const EditCommand& c : mDrag.begin(o->id, o->transform)) submit(c);
    mLastInteraction = glfwGetTime();
    return true;
}

void EditorApp::dragTo(const Transform& to) {
    if (!mRunner || !mDrag.active()) return;
    if (auto c = mDrag.update(to)) mRunner->submitCoalescing(*c);
    mLastInteraction = glfwGetTime();
}

Transform EditorApp::endDrag() {
    const Transform final = mDrag.current();
    if (mDrag.active())
        for (const EditCommand& c : mDrag.end()) submit(c);
    return final;
}

// ---------------------------------------------------------------------------------------------
// Screenshot.

void EditorApp::writeScreenshot(const std::string& path) {
    int w = 0, h = 0;
    glfwGetFramebufferSize(mWindow, &w, &h);
    std::vector<unsigned char> pixels(static_cast<std::size_t>(w) * h * 3);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadBuffer(GL_BACK);
    glReadPixels(0, 0, w, h, GL_RGB, GL_UNSIGNED_BYTE, pixels.data());
    // GL rows run bottom-up; PNG values are sRGB already: decode so writePng re-encodes them.
    Image image(w, h);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const unsigned char* p = &pixels[(static_cast<std::size_t>(h - 1 - y) * w + x) * 3];
            image.at(x, y) =
                Rgb(srgbDecode(p[0] / 255.0), srgbDecode(p[1] / 255.0), srgbDecode(p[2] / 255.0));
        }
    writePng(image, path);
}

}  // namespace penumbra
