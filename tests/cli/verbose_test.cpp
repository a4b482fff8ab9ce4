// `--verbose` turns on the debug lines (spdlog, on stderr); without it a run prints none, and
// stdout stays the command's own output either way.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "cli/cli_support.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

struct CliRun {
    int status = -1;
    std::string out, err;
};

CliRun exportHifi(const fs::path& dir, bool verbose) {
    const fs::path out = dir / "out.txt", err = dir / "err.txt";
    const std::string command = std::string("timeout 120 '") + PENUMBRA_EXE + "'" +
                                (verbose ? " --verbose" : "") + " export '" + PENUMBRA_SOURCE_DIR +
                                "/scenes/cube-room.json' '" + (dir / "lit.glb").string() +
                                "' --hifi --converge 0.01 > '" + out.string() + "' 2> '" +
                                err.string() + "'";
    CliRun run;
    run.status = test::runShell(command);
    run.out = test::readFile(out);
    run.err = test::readFile(err);
    return run;
}

TEST(VerboseCli, DebugLinesOnlyWithTheFlag) {
    const fs::path dir =
        fs::temp_directory_path() / ("penumbra_cli_verbose_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const CliRun quiet = exportHifi(dir, false);
    const CliRun verbose = exportHifi(dir, true);
    EXPECT_EQ(quiet.status, 0) << quiet.err;
    EXPECT_EQ(verbose.status, 0) << verbose.err;
    EXPECT_EQ(quiet.err.find("penumbra debug:"), std::string::npos) << quiet.err;
    EXPECT_NE(verbose.err.find("penumbra debug: "), std::string::npos) << verbose.err;
    EXPECT_NE(verbose.err.find("interpolants: 1688 elements"), std::string::npos) << verbose.err;
    EXPECT_TRUE(quiet.out.empty());
    EXPECT_TRUE(verbose.out.empty());
    fs::remove_all(dir);
}

}  // namespace
}  // namespace penumbra
