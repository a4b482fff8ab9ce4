// The real `penumbra bench solver` on a small scene: every figure of the table is written,
// and each scene's measurement runs in a child that uses all the cores. A child forked after
// oneTBB had started its workers got none of them, and every figure came from one thread.

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "cli/cli_support.h"

namespace {

namespace fs = std::filesystem;

TEST(BenchSolverCli, EachSceneIsMeasuredOnEveryCoreInAFreshChild) {
    const fs::path dir =
        fs::temp_directory_path() / ("penumbra_bench_solver_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const fs::path json = dir / "bench.json";
    const std::string command = "cd '" + std::string(PENUMBRA_SOURCE_DIR) + "' && '" +
                                PENUMBRA_EXE +
                                "' bench solver --scenes scenes/cornell-box.json --max-seconds 2 "
                                "--json '" +
                                json.string() + "' > '" + (dir / "out.txt").string() + "' 2>&1";
    ASSERT_EQ(penumbra::test::runShell(command), 0) << penumbra::test::readFile(dir / "out.txt");
    const auto rows = nlohmann::json::parse(penumbra::test::readFile(json));
    ASSERT_EQ(rows.size(), 1u);
    const auto& r = rows[0];
    ASSERT_FALSE(r.contains("error")) << r.dump();
    for (const char* key :
         {"raw_occlusion_rays_per_s", "solver_rays_per_s", "ratio_solver_to_raw", "peak_rss_mib"})
        EXPECT_GT(r[key].get<double>(), 0) << key;
    EXPECT_GT(r["shots"].get<long>(), 0);
    // The raw-ray loop (1,024 tasks of 1,024 rays) ran on every core oneTBB offers.
    const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    EXPECT_EQ(r["threads"].get<int>(), cores);
    EXPECT_EQ(r["threads_seen"].get<int>(), cores) << "the measuring child ran on fewer threads";
    fs::remove_all(dir);
}

}  // namespace
