// penumbra-editor [SCENE] [--emission-scale S] [--light-size R] [--units mm|cm|m] [--log LOG]
// [--play LOG] [--screenshot PNG --frames N] [--mode NAME] [--recover] [--no-journal]
//                 [--display-divisor N]
//                 [--holodeck FILE | --no-holodeck] [--script FILE]
//                 [--bench-drag ID [--frames N] [--record DIR] [--no-references]]
//                 [--bench-still S [--record DIR]]
// The GUI (ui/editor_app.h). --script plays an input script (ui/input_script.h); the benchmarks
// drive the editor through scripts of their own (ui/editor_benches.h). Exit status: 0 success;
// 1 the screenshot could not be written; 2 bad input (a malformed script, an object it names
// that the scene lacks) or no display, with one line on stderr.

#include <CLI/CLI.hpp>
#include <OpenMesh/Core/System/omstream.hh>
#include <exception>
#include <filesystem>
#include <iostream>

#include "app/import_flags.h"
#include "core/input_error.h"
#include "core/log.h"
#include "render/holodeck/holo_file.h"
#include "ui/editor_app.h"
#include "ui/editor_benches.h"
#include "ui/input_script.h"

int main(int argc, char** argv) {
    // OpenMesh reports non-manifold faces it cannot link (which the edge finder handles by
    // giving them their own vertices) on its own error stream; the editor reports its errors
    // in the status bar and on stderr (as `penumbra` does).
    omerr().disable();
    penumbra::EditorOptions options;
    std::string script, benchDrag, record;
    bool benchReferences = true;
    double benchStill = 0;
    CLI::App app{"Penumbra editor: interactive radiosity lighting"};
    app.add_option("scene", options.scene, "scene file (*.json, or *.gltf *.glb *.obj to import)");
    addImportFlags(&app, options.import);
    app.add_option("--log", options.log, "append every edit to this edit log (JSONL)");
    app.add_option("--play", options.play, "replay this edit log live");
    app.add_option("--screenshot", options.screenshot,
                   "after --frames frames and once the lighting settles, save the window as "
                   "PNG and exit");
    app.add_option("--frames", options.frames, "frames before the screenshot (or before exit)")
        ->check(CLI::NonNegativeNumber);
    app.add_option("--width", options.width, "window width")->check(CLI::PositiveNumber);
    app.add_option("--height", options.height, "window height")->check(CLI::PositiveNumber);
    app.add_option("--play-every", options.playEvery, "frames per replayed log line")
        ->check(CLI::PositiveNumber);
    auto* scripted = app.add_option(
        "--script", script,
        "play this input script (select, drag, move, drop, waits: docs/architecture.md)");
    app.add_option("--bench-drag", benchDrag,
                   "drag this object in a circle for --frames frames and print frame times")
        ->excludes(scripted);
    app.add_option("--record", record,
                   "with --bench-drag: write every image shown, its edit line and the "
                   "references into this folder (--bench-still: the images, the reference and "
                   "Gouraud)");
    app.add_option("--bench-still", benchStill,
                   "keep the view still for S seconds, then print how far the viewport was from "
                   "a reference render at 1, 2, 5, 10 ... s, and Gouraud's error (JSON)")
        ->check(CLI::PositiveNumber)
        ->excludes(scripted);
    app.add_flag("!--no-references", benchReferences,
                 "with --bench-drag: skip the reference renders (errors against references)");
    app.add_flag("--recover", options.recover,
                 "replay the edits an earlier session on SCENE left unsaved without asking");
    app.add_flag("!--no-journal", options.journal,
                 "keep no recovery journal of this session's edits");
    app.add_flag("--quiet", options.quiet, "no status lines on stderr");
    bool verbose = false;
    app.add_flag("--verbose", verbose,
                 "debug lines on stderr (the solver, render and display threads' work and times)");
    app.add_option("--display-divisor", options.displayDivisor,
                   "edge-and-point modes render the viewport at 1/N resolution (upscaled)")
        ->check(CLI::PositiveNumber);
    // Accepted so that existing command lines keep working: the one display keeps the
    // viewport's resolution while the view moves or an object is dragged.
    int interactiveDivisor = 1;
    auto* interactive = app.add_option("--interactive-divisor", interactiveDivisor,
                                       "no longer used: the display keeps its resolution while "
                                       "the view moves or an object is dragged")
                            ->check(CLI::NonNegativeNumber);
    auto* holodeck = app.add_option("--holodeck", options.holodeck,
                                    "the holodeck (ray cache) views start from and store their "
                                    "points in (created if missing; default: SCENE.hdk when it "
                                    "exists)");
    app.add_flag("--no-holodeck", options.noHolodeck, "use no holodeck")->excludes(holodeck);
    std::string mode = "epi";
    app.add_option("--mode", mode,
                   "viewport mode: epi (default), gouraud, cache, edges, samples, difference, "
                   "outofdate, interpolant")
        ->check([](const std::string& name) {
            return penumbra::parseViewMode(name) ? std::string() : "unknown mode '" + name + "'";
        });
    std::string overlay;
    app.add_option("--overlay", overlay,
                   "viewport overlay from the start: settling (View > Overlay > Settling)")
        ->check([](const std::string& name) {
            return name == "settling" ? std::string()
                                      : "unknown overlay '" + name + "' (available: settling)";
        });
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e) == 0 ? 0 : 2;
    }
    penumbra::initLogging(verbose);
    if (*interactive && interactiveDivisor != 1)
        spdlog::warn("--interactive-divisor is no longer used: the display keeps its resolution");
    options.mode = *penumbra::parseViewMode(mode);
    options.settlingOverlay = overlay == "settling";
    try {
        // What drives the editor from outside: an input script, or a benchmark playing its own.
        if (!script.empty()) {
            options.driver =
                std::make_shared<penumbra::InputScript>(penumbra::InputScript::load(script));
        } else if (!benchDrag.empty()) {
            penumbra::DragBenchDriverOptions drag;
            drag.object = benchDrag;
            drag.frames = options.frames > 0 ? options.frames : 300;
            drag.recordDir = record;
            drag.references = benchReferences;
            options.driver = std::make_shared<penumbra::DragBenchDriver>(drag);
        } else if (benchStill > 0) {
            options.driver = std::make_shared<penumbra::StillBenchDriver>(
                options.scene, options.import, benchStill, record, options.quiet);
        }
        if (options.driver) options.journal = false;
        // A holodeck named on the command line is checked like the other inputs (bad: one line,
        // exit 2); the one found beside a scene only warns when it cannot be used.
        if (!options.holodeck.empty() && std::filesystem::exists(options.holodeck))
            (void)penumbra::HoloFile::openReadOnly(options.holodeck);
        penumbra::EditorApp editor(options);
        return editor.run();
    } catch (const penumbra::DisplayError& e) {
        std::cerr << "penumbra-editor: " << e.what() << "\n";
        return 2;
    } catch (const penumbra::InputError& e) {
        std::cerr << "penumbra-editor: " << e.what() << "\n";
        return 2;
    } catch (const std::exception& e) {
        std::cerr << "penumbra-editor: " << e.what() << "\n";
        return 2;
    }
}
