#pragma once
// `penumbra holodeck fill | info | merge` (Ward & Simmons 1999; docs/holodeck.md): the
// subcommands, their options and what they run.

#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>
#include <vector>

#include "app/cli_common.h"

namespace penumbra::cli {

struct HolodeckArgs {
    std::string file;  ///< fill: --holodeck (default SCENE.hdk); info: FILE; merge: OUT
    std::vector<std::string> parts;  ///< merge: PART...
    std::string camera;
    double seconds = 0;
    std::int64_t samples = 0;
    int width = 512, height = 512;  ///< --camera: the view whose beams are filled
};

/// The holodeck subcommands' options, and which of them ran.
struct HolodeckCommands {
    HolodeckArgs args;
    CLI::App *fill = nullptr, *info = nullptr, *merge = nullptr;
};

/// `holodeck` and its subcommands on `app`; fill takes the scene and solver options `solve`.
void addHolodeckCommands(CLI::App& app, SolveArgs& solve, HolodeckCommands& c);
/// Runs the holodeck subcommand that was given: its exit status, or −1 when none was.
int runHolodeckCommand(const SolveArgs& solve, const HolodeckCommands& c);

}  // namespace penumbra::cli
