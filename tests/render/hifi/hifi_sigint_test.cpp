// `penumbra render --mode interpolant` on a terminal (issue 46, point 3): the build's progress
// line counts the elements meshed of all and the time left, and SIGINT during the build stops
// the command within a second with exit status 130 and no output file.

#include <gtest/gtest.h>
#include <poll.h>
#include <pty.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <string>

namespace penumbra {
namespace {

/// Reads what the terminal shows into `out` until `until` returns true, the child closes it,
/// or `seconds` pass. Returns whether `until` held.
template <class Until>
bool readTerminal(int fd, std::string& out, double seconds, Until until) {
    const auto start = std::chrono::steady_clock::now();
    char buffer[4096];
    while (!until(out)) {
        const double left =
            seconds -
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        if (left <= 0) return false;
        pollfd p{fd, POLLIN, 0};
        if (poll(&p, 1, static_cast<int>(left * 1000) + 1) <= 0) continue;
        const ssize_t n = read(fd, buffer, sizeof buffer);
        if (n <= 0) return until(out);  // closed: the child ended
        out.append(buffer, std::size_t(n));
    }
    return true;
}

TEST(HifiSigint, ABuildStopsWithinASecondWithStatus130AndWritesNothing) {
    const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cornell-box.json";
    const std::string image = (std::filesystem::temp_directory_path() /
                               ("hifi_sigint_" + std::to_string(getpid()) + ".png"))
                                  .string();
    std::filesystem::remove(image);
    int fd = -1;
    const pid_t pid = forkpty(&fd, nullptr, nullptr, nullptr);
    ASSERT_GE(pid, 0) << "forkpty failed";
    if (pid == 0) {
        // Many far-field rays: a build long enough to be interrupted in the middle.
        execl(PENUMBRA_EXE, PENUMBRA_EXE, "render", scene.c_str(), "--mode", "interpolant",
              "--gather-rays", "4096", "--width", "32", "--height", "32", "--out", image.c_str(),
              static_cast<char*>(nullptr));
        _exit(127);
    }
    std::string shown;
    const bool building = readTerminal(
        fd, shown, 240, [](const std::string& s) { return s.find("s left") != std::string::npos; });
    if (!building) kill(pid, SIGKILL);
    ASSERT_TRUE(building) << "no progress with the time left on the terminal:\n" << shown;
    EXPECT_NE(shown.find(" of 3952 elements"), std::string::npos) << shown;

    kill(pid, SIGINT);
    const auto sent = std::chrono::steady_clock::now();
    int status = 0;
    while (waitpid(pid, &status, WNOHANG) == 0) {
        readTerminal(fd, shown, 0.01, [](const std::string&) { return false; });
        if (std::chrono::steady_clock::now() - sent > std::chrono::seconds(60)) {
            kill(pid, SIGKILL);
            waitpid(pid, &status, 0);
            break;
        }
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - sent).count();
    close(fd);
    EXPECT_LT(seconds, 1.0) << shown;
    ASSERT_TRUE(WIFEXITED(status)) << "ended by a signal: " << shown;
    EXPECT_EQ(WEXITSTATUS(status), 130) << shown;
    EXPECT_FALSE(std::filesystem::exists(image)) << image;
}

}  // namespace
}  // namespace penumbra
