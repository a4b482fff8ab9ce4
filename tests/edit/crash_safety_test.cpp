// kill -9 at random moments loses nothing acknowledged (DESIGN.md "Edit log"; issue 26):
// - an editing session (crash_child: EditSession with an edit log, as the editor's runner
//   drives it) is killed 100 times, each at a random moment: every line of its log is whole
//   and parses, every edit it acknowledged is there (at most the one in flight more), each
//   line is the edit the session applied, the saved scene is the last acknowledged save or
//   the one in flight, never a torn file; and replaying the recovered log converges to the
//   lighting of the same edits applied directly;
// - `penumbra replay --save-scene` is killed 20 times over a scene file that already exists:
//   the file is afterwards either the old scene or the finished one;
// - `penumbra export` is killed 100 times over an export that already exists (issue 43), half
//   at a random moment of its run and half just after its temporary file appears (inside the
//   write): the export is afterwards either the old file or the reference export, byte for
//   byte, and a temporary file is left only by kills inside the write.

#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "cli/cli_support.h"
#include "core/random.h"
#include "crash_edits.h"
#include "edit/edit_log.h"
#include "edit/edit_session.h"
#include "edit/io/scene_io.h"

extern char** environ;

namespace penumbra {
namespace {

namespace fs = std::filesystem;

/// A child process whose stdout is a pipe.
struct Child {
    pid_t pid = -1;
    int out = -1;
};

/// Starts `args` with its stdout a pipe (and its stderr /dev/null when `quiet`).
Child spawn(const std::vector<std::string>& args, bool quiet = false) {
    int fds[2];
    if (::pipe(fds) != 0) throw std::runtime_error("pipe failed");
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);
    if (quiet)
        posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addclose(&actions, fds[0]);
    posix_spawn_file_actions_addclose(&actions, fds[1]);
    std::vector<char*> argv;
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    Child c;
    const int rc = posix_spawn(&c.pid, argv[0], &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    ::close(fds[1]);
    if (rc != 0) {
        ::close(fds[0]);
        throw std::runtime_error("cannot start " + args[0]);
    }
    c.out = fds[0];
    return c;
}

/// Waits until `c` has written the line `line` (none: at once), then `delay`; kills it with
/// SIGKILL, reaps it and returns everything it wrote; `killed` says whether the signal ended it
/// (false: it finished first). Waiting for a line puts the kill at a point of the session
/// whatever the machine's speed (a sanitizer build runs several times slower); the delay then
/// puts it at a random moment of the edits that follow.
std::string killAfter(Child& c, const std::string& line, std::chrono::microseconds delay,
                      bool& killed) {
    std::string text;
    char buffer[4096];
    if (!line.empty()) {
        const std::string wanted = line + "\n";
        ssize_t n;
        while (text.find(wanted) == std::string::npos &&
               (n = ::read(c.out, buffer, sizeof buffer)) > 0)
            text.append(buffer, static_cast<std::size_t>(n));
    }
    std::this_thread::sleep_for(delay);
    ::kill(c.pid, SIGKILL);
    int status = 0;
    ::waitpid(c.pid, &status, 0);
    killed = WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
    for (ssize_t n; (n = ::read(c.out, buffer, sizeof buffer)) > 0;)
        text.append(buffer, static_cast<std::size_t>(n));
    ::close(c.out);
    return text;
}

/// The last "WORD N" line's N in `text`, 0 when none.
int lastAcknowledged(const std::string& text, const std::string& word) {
    int last = 0;
    std::istringstream in(text);
    for (std::string w; in >> w;) {
        int n = 0;
        in >> n;
        if (w == word) last = n;
    }
    return last;
}

/// The highest K of the "box-K" objects in `scene`.
int lastRound(const Scene& scene) {
    int last = 0;
    for (int k = 1; k < 1000; ++k)
        if (scene.findObject(test::crashBoxId(k)) >= 0) last = k;
    return last;
}

/// The session of edits 1 … n, converged.
std::vector<Rgb> convergedAfter(const std::vector<EditCommand>& edits) {
    EditSession session(test::makeLitRoom("red"), SolverOptions{});
    session.converge(1e-2);
    for (const EditCommand& c : edits) session.apply(c);
    session.converge(1e-3);
    return session.displayRadiosity();
}

class CrashSafety : public ::testing::Test {
protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        mDir = fs::temp_directory_path() /
               (std::string("penumbra_crash_") + info->name() + "_" + std::to_string(::getpid()));
        fs::remove_all(mDir);
        fs::create_directories(mDir);
    }
    void TearDown() override { fs::remove_all(mDir); }
    fs::path mDir;
};

TEST_F(CrashSafety, AKilledEditingSessionKeepsEveryAcknowledgedEditAndAWholeScene) {
    constexpr int kTrials = 100;
    SplitMix random(26);
    int killedTrials = 0, recoveredEdits = 0, replays = 0, mostEdits = 0;
    for (int trial = 0; trial < kTrials; ++trial) {
        const fs::path dir = mDir / std::to_string(trial);
        fs::create_directories(dir);
        Child child = spawn({PENUMBRA_CRASH_CHILD, dir.string()});
        bool killed = false;
        // One trial in ten during start-up (loading, a first solve); the others after a random
        // edit of the first 150 and up to 3 ms more (longer than an edit takes, so kills land
        // inside edits as well as between them).
        const bool early = random.next() < 0.1;
        const int after = early ? 0 : 1 + static_cast<int>(random.next() * 150);
        const auto delay =
            std::chrono::microseconds(static_cast<long>(random.next() * (early ? 50000 : 3000)));
        const std::string acks =
            killAfter(child, after ? "edit " + std::to_string(after) : "", delay, killed);
        ASSERT_TRUE(killed) << "trial " << trial << ": the child ended by itself";
        ++killedTrials;
        const int acknowledged = lastAcknowledged(acks, "edit");
        const int saved = lastAcknowledged(acks, "save");

        // The log: whole lines that parse, the acknowledged edits and at most one more, each
        // the edit applied.
        const fs::path log = dir / "edits.jsonl";
        std::vector<EditCommand> recovered;
        if (fs::exists(log)) {
            const std::string text = test::readFile(log);
            EXPECT_TRUE(text.empty() || text.back() == '\n')
                << "trial " << trial << ": a torn last line";
            std::vector<LoggedEdit> edits;
            ASSERT_NO_THROW(edits = readEditLog(log.string())) << "trial " << trial;
            for (LoggedEdit& e : edits) {
                e.command.tMs.reset();
                ASSERT_EQ(e.command.toString(), test::crashEdit(e.line).toString())
                    << "trial " << trial << ", line " << e.line;
                recovered.push_back(e.command);
            }
        }
        const int lines = static_cast<int>(recovered.size());
        EXPECT_GE(lines, acknowledged) << "trial " << trial << ": an acknowledged edit is lost";
        EXPECT_LE(lines, acknowledged + 1) << "trial " << trial;
        recoveredEdits += lines;
        mostEdits = std::max(mostEdits, lines);

        // The scene: the last acknowledged save or the one in flight, whole.
        const fs::path scene = dir / "scene.json";
        if (saved > 0) {
            ASSERT_TRUE(fs::exists(scene)) << "trial " << trial;
        }
        if (fs::exists(scene)) {
            Scene s;
            ASSERT_NO_THROW(s = loadScene(scene.string())) << "trial " << trial;
            const int rounds = lastRound(s);
            EXPECT_TRUE(rounds == saved || rounds == saved + 1)
                << "trial " << trial << ": the scene holds " << rounds << " rounds, " << saved
                << " acknowledged";
        }

        // About every twentieth trial (the first with edits after each twenty): the recovered
        // log replays to the lighting of the same edits applied directly (both deterministic:
        // the same bits).
        if (replays * 20 <= trial && lines > 0) {
            std::vector<EditCommand> direct;
            for (int i = 1; i <= lines; ++i) direct.push_back(test::crashEdit(i));
            const std::vector<Rgb> a = convergedAfter(recovered), b = convergedAfter(direct);
            ASSERT_EQ(a.size(), b.size());
            double worst = 0;
            for (std::size_t e = 0; e < a.size(); ++e)
                worst = std::max(worst, std::abs(luminance(a[e]) - luminance(b[e])));
            EXPECT_EQ(worst, 0.0) << "trial " << trial << " (" << lines << " edits)";
            ++replays;
        }
        fs::remove_all(dir);
    }
    std::printf("%d kills; %d edits recovered (at most %d in one log); %d replays compared\n",
                killedTrials, recoveredEdits, mostEdits, replays);
    EXPECT_GT(mostEdits, 2 * test::kCrashRound) << "the kills should reach far into the edits";
}

TEST_F(CrashSafety, AKilledReplayLeavesTheOldSceneOrTheNewOne) {
    // The old file: the room as it starts. The new one: what a finished replay of 24 edits of
    // the crash session writes.
    const fs::path start = mDir / "start.json", log = mDir / "edits.jsonl";
    saveScene(test::makeLitRoom("red"), start.string());
    {
        EditLogWriter writer(log.string());
        for (int i = 1; i <= 3 * test::kCrashRound; ++i) writer.append(test::crashEdit(i));
    }
    const auto replay = [&](const fs::path& out) {
        return std::vector<std::string>{PENUMBRA_EXE,   "replay",     start.string(), log.string(),
                                        "--save-scene", out.string(), "--converge",   "0.01"};
    };
    const fs::path finished = mDir / "finished.json";
    {
        Child c = spawn(replay(finished));
        int status = 0;
        ::waitpid(c.pid, &status, 0);
        ::close(c.out);
        ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    }
    const std::string oldText = test::readFile(start), newText = test::readFile(finished);
    ASSERT_NE(oldText, newText);

    SplitMix random(25);
    int sawOld = 0, sawNew = 0;
    for (int trial = 0; trial < 20; ++trial) {
        const fs::path out = mDir / "out.json";
        fs::copy_file(start, out, fs::copy_options::overwrite_existing);
        Child c = spawn(replay(out));
        bool killed = false;
        killAfter(c, "", std::chrono::microseconds(static_cast<long>(random.next() * 400000)),
                  killed);
        const std::string text = test::readFile(out);
        EXPECT_TRUE(text == oldText || text == newText)
            << "trial " << trial << ": " << text.size() << " bytes, neither scene";
        sawOld += text == oldText;
        sawNew += text == newText;
    }
    std::printf("killed replays: %d left the old scene, %d the new one\n", sawOld, sawNew);
}

/// The names in `dir` that start with `prefix`.
std::vector<std::string> namesStartingWith(const fs::path& dir, const std::string& prefix) {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir)) {
        const std::string name = entry.path().filename().string();
        if (name.rfind(prefix, 0) == 0) names.push_back(name);
    }
    return names;
}

/// Waits until a name starting with `prefix` appears in `dir` or `c` ends (then false).
bool waitForName(const Child& c, const fs::path& dir, const std::string& prefix) {
    for (;;) {
        if (!namesStartingWith(dir, prefix).empty()) return true;
        siginfo_t info{};
        if (::waitid(P_PID, static_cast<id_t>(c.pid), &info, WEXITED | WNOHANG | WNOWAIT) == 0 &&
            info.si_pid == c.pid)
            return false;
        std::this_thread::sleep_for(std::chrono::microseconds(50));
    }
}

TEST_F(CrashSafety, AKilledExportLeavesTheOldFileOrTheNewOne) {
    // The old file: the cube room's export. The new one: the cubicles' (6,898 elements, about
    // 0.8 MB of glTF), unsolved so that the run is mostly loading, meshing and writing.
    const fs::path out = mDir / "lit.gltf", old = mDir / "old.gltf";
    const auto exportOf = [&](const std::string& scene, const fs::path& to) {
        return std::vector<std::string>{PENUMBRA_EXE,
                                        "export",
                                        std::string(PENUMBRA_SOURCE_DIR) + "/scenes/" + scene,
                                        to.string(),
                                        "--max-shots",
                                        "0",
                                        "--threads",
                                        "1"};
    };
    const auto runToEnd = [&](const std::vector<std::string>& args) {
        Child c = spawn(args, true);
        int status = 0;
        ::waitpid(c.pid, &status, 0);
        ::close(c.out);
        return WIFEXITED(status) && WEXITSTATUS(status) == 0;
    };
    ASSERT_TRUE(runToEnd(exportOf("cube-room.json", old)));
    // The reference export, timed: the kills' random moments span its run.
    const auto start = std::chrono::steady_clock::now();
    const fs::path reference = mDir / "reference.gltf";
    ASSERT_TRUE(runToEnd(exportOf("cubicles.json", reference)));
    const double runSeconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const std::string oldBytes = test::readFile(old), newBytes = test::readFile(reference);
    ASSERT_NE(oldBytes, newBytes);

    // The temporary file's prefix (core/durable_file.h: `.NAME.tmp-`).
    const std::string temporary = "." + out.filename().string() + ".tmp-";
    SplitMix random(43);
    int sawOld = 0, sawNew = 0, insideWrite = 0, finished = 0;
    for (int trial = 0; trial < 100; ++trial) {
        fs::copy_file(old, out, fs::copy_options::overwrite_existing);
        Child c = spawn(exportOf("cubicles.json", out), true);
        // Even trials: a random moment of the run. Odd ones: up to 2 ms after the temporary
        // file appears, inside the write, fsync and rename.
        bool killed = false;
        if (trial % 2 == 0) {
            killAfter(c, "", std::chrono::microseconds(static_cast<long>(
                                 random.next() * runSeconds * 1e6)),
                      killed);
        } else {
            waitForName(c, mDir, temporary);
            killAfter(c, "", std::chrono::microseconds(static_cast<long>(random.next() * 2000)),
                      killed);
        }
        finished += !killed;

        const std::string bytes = test::readFile(out);
        const bool isOld = bytes == oldBytes, isNew = bytes == newBytes;
        EXPECT_TRUE(isOld || isNew) << "trial " << trial << ": " << bytes.size()
                                    << " bytes, neither the old export nor the new one";
        sawOld += isOld;
        sawNew += isNew;
        // A temporary file left behind: killed between its creation and the rename, so the
        // target is still the old file. Removed before the next trial.
        const std::vector<std::string> left = namesStartingWith(mDir, temporary);
        EXPECT_LE(left.size(), 1u) << "trial " << trial;
        if (!left.empty()) {
            ++insideWrite;
            EXPECT_TRUE(isOld) << "trial " << trial << ": the rename happened, yet "
                               << left.front() << " is left";
            for (const std::string& name : left) fs::remove(mDir / name);
        }
    }
    std::printf(
        "killed exports (run %.3f s): %d left the old file, %d the new one; %d killed inside "
        "the write, %d finished first\n",
        runSeconds, sawOld, sawNew, insideWrite, finished);
    EXPECT_GT(sawOld, 0);
    EXPECT_GT(insideWrite, 0) << "no kill landed inside the write: the test does not reach it";
}

}  // namespace
}  // namespace penumbra
