// core/durable_file.h: the bytes arrive whole, an existing file keeps its permission bits, a
// new one gets 0666 less the umask, and every failure (missing or read-only directory, a write
// refused by the file-size limit, a rename over a directory, a writer that throws) throws
// naming the file and the system's reason, leaves the target as it was and no temporary file.

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/durable_file.h"
#include "core/input_error.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

std::string readAll(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream out;
    out << in.rdbuf();
    return out.str();
}

mode_t modeOf(const fs::path& path) {
    struct stat info {};
    EXPECT_EQ(::stat(path.c_str(), &info), 0) << path;
    return info.st_mode & 07777;
}

/// The names in `dir`, sorted.
std::vector<std::string> namesIn(const fs::path& dir) {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir))
        names.push_back(entry.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
}

/// `what` run, the InputError it throws (fails the test when it throws none).
template <typename F>
std::string inputErrorOf(F&& what) {
    try {
        what();
    } catch (const InputError& e) {
        return e.what();
    }
    ADD_FAILURE() << "no InputError";
    return "";
}

class DurableFile : public ::testing::Test {
protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        mDir = fs::temp_directory_path() / (std::string("penumbra_durable_") + info->name() +
                                            "_" + std::to_string(::getpid()));
        fs::remove_all(mDir);
        fs::create_directories(mDir);
    }
    void TearDown() override {
        fs::permissions(mDir, fs::perms::owner_all, fs::perm_options::add);
        fs::remove_all(mDir);
    }
    fs::path mDir;
};

TEST_F(DurableFile, WritesTheBytesAndReplacesALongerFile) {
    const fs::path target = mDir / "out.bin";
    std::string bytes(200000, '\0');
    for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<char>(i * 7 + i / 251);
    writeFileAtomically(target.string(), bytes);
    EXPECT_EQ(readAll(target), bytes);

    writeFileAtomically(target.string(), std::string_view("short"));
    EXPECT_EQ(readAll(target), "short");
    writeFileAtomically(target.string(), std::string_view());
    EXPECT_EQ(readAll(target), "");
    EXPECT_EQ(namesIn(mDir), std::vector<std::string>{"out.bin"}) << "a temporary file is left";
}

TEST_F(DurableFile, StreamsSmallAndLargePiecesInOrder) {
    const fs::path target = mDir / "stream.txt";
    std::string expected;
    writeFileAtomically(target.string(), [&](std::ostream& out) {
        // Pieces smaller and larger than the stream's buffer, and formatted numbers.
        for (int i = 0; i < 20000; ++i) out << i << ' ';
        const std::string big(300000, 'x');
        out << big;
        out.put('\n');
        out.write("tail", 4);
    });
    {
        std::ostringstream reference;
        for (int i = 0; i < 20000; ++i) reference << i << ' ';
        reference << std::string(300000, 'x') << '\n' << "tail";
        expected = reference.str();
    }
    EXPECT_EQ(readAll(target), expected);
    EXPECT_EQ(namesIn(mDir), std::vector<std::string>{"stream.txt"});
}

TEST_F(DurableFile, KeepsAnExistingFilesPermissionsAndGivesANewOneTheUmasks) {
    const fs::path kept = mDir / "kept.json";
    writeFileAtomically(kept.string(), std::string_view("old"));
    for (mode_t mode : {0640u, 0600u, 0755u, 0444u}) {
        ASSERT_EQ(::chmod(kept.c_str(), mode), 0);
        writeFileAtomically(kept.string(), std::string_view("new"));
        EXPECT_EQ(modeOf(kept), mode) << std::oct << "mode 0" << mode << " not kept";
        EXPECT_EQ(readAll(kept), "new");
    }

    // A new file: 0666 less the umask, for two umasks.
    for (mode_t mask : {022u, 077u}) {
        const mode_t previous = ::umask(mask);
        const fs::path fresh = mDir / ("fresh-" + std::to_string(mask));
        writeFileAtomically(fresh.string(), std::string_view("x"));
        ::umask(previous);
        EXPECT_EQ(modeOf(fresh), 0666u & ~mask) << std::oct << "umask 0" << mask;
    }
}

TEST_F(DurableFile, AMissingDirectoryThrowsNamingThePathAndTheReason) {
    const std::string path = (mDir / "no" / "such" / "out.ply").string();
    const std::string message = inputErrorOf([&] { writeFileAtomically(path, "bytes"); });
    EXPECT_EQ(message.rfind(path + ": cannot write", 0), 0u) << message;
    EXPECT_NE(message.find(std::strerror(ENOENT)), std::string::npos) << message;
    EXPECT_TRUE(namesIn(mDir).empty());
}

TEST_F(DurableFile, AReadOnlyDirectoryThrowsAndLeavesTheTargetUntouched) {
    const fs::path dir = mDir / "read-only", target = dir / "scene.json";
    fs::create_directories(dir);
    writeFileAtomically(target.string(), std::string_view("old"));
    fs::permissions(dir, fs::perms::owner_read | fs::perms::owner_exec | fs::perms::group_read |
                             fs::perms::group_exec | fs::perms::others_read |
                             fs::perms::others_exec);
    // Root writes into read-only directories: it tries as nobody, in a child process.
    const auto attempt = [&] {
        return inputErrorOf([&] { writeFileAtomically(target.string(), std::string_view("new")); });
    };
    if (::geteuid() == 0) {
        const pid_t child = ::fork();
        ASSERT_GE(child, 0);
        if (child == 0) {
            if (::setgid(65534) != 0 || ::setuid(65534) != 0) ::_exit(3);
            try {
                writeFileAtomically(target.string(), std::string_view("new"));
            } catch (const InputError& e) {
                ::_exit(std::string(e.what()).find(std::strerror(EACCES)) != std::string::npos
                            ? 0
                            : 2);
            }
            ::_exit(1);
        }
        int status = 0;
        ASSERT_EQ(::waitpid(child, &status, 0), child);
        ASSERT_TRUE(WIFEXITED(status));
        if (WEXITSTATUS(status) == 3) GTEST_SKIP() << "cannot become nobody to test as root";
        EXPECT_EQ(WEXITSTATUS(status), 0)
            << "as nobody: 1 no exception, 2 an exception without the reason";
    } else {
        const std::string message = attempt();
        EXPECT_NE(message.find(std::strerror(EACCES)), std::string::npos) << message;
    }
    fs::permissions(dir, fs::perms::owner_all);
    EXPECT_EQ(readAll(target), "old");
    EXPECT_EQ(namesIn(dir), std::vector<std::string>{"scene.json"});
}

TEST_F(DurableFile, AFailedWriteRemovesTheTemporaryAndLeavesTheTarget) {
    const fs::path target = mDir / "export.glb";
    writeFileAtomically(target.string(), std::string_view("old contents"));

    // The file-size limit makes write() fail with EFBIG part-way (SIGXFSZ ignored), as a full
    // disk would with ENOSPC; root is bound by it too.
    struct rlimit previous {};
    ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &previous), 0);
    const auto oldHandler = ::signal(SIGXFSZ, SIG_IGN);
    struct rlimit small = previous;
    small.rlim_cur = 4096;
    ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &small), 0);
    const std::string big(100000, 'b');
    const std::string bytesError =
        inputErrorOf([&] { writeFileAtomically(target.string(), big); });
    const std::string streamError = inputErrorOf([&] {
        writeFileAtomically(target.string(), [&](std::ostream& out) {
            for (int i = 0; i < 1000; ++i) out << big.substr(0, 100);
        });
    });
    ::setrlimit(RLIMIT_FSIZE, &previous);
    ::signal(SIGXFSZ, oldHandler);

    for (const std::string& message : {bytesError, streamError}) {
        EXPECT_EQ(message.rfind(target.string() + ": cannot write", 0), 0u) << message;
        EXPECT_NE(message.find(std::strerror(EFBIG)), std::string::npos) << message;
    }
    EXPECT_EQ(readAll(target), "old contents");
    EXPECT_EQ(namesIn(mDir), std::vector<std::string>{"export.glb"});
}

TEST_F(DurableFile, AFailedRenameRemovesTheTemporary) {
    // The target is a directory that is not empty: rename() refuses.
    const fs::path target = mDir / "taken";
    fs::create_directories(target / "inside");
    const std::string message =
        inputErrorOf([&] { writeFileAtomically(target.string(), std::string_view("x")); });
    EXPECT_NE(message.find("renaming"), std::string::npos) << message;
    EXPECT_TRUE(fs::is_directory(target / "inside"));
    EXPECT_EQ(namesIn(mDir), std::vector<std::string>{"taken"});
}

TEST_F(DurableFile, AThrowingWriterOrAnAbandonedFileLeavesTheTarget) {
    const fs::path target = mDir / "report.json";
    writeFileAtomically(target.string(), std::string_view("{}\n"));
    EXPECT_THROW(writeFileAtomically(target.string(),
                                     [](std::ostream& out) {
                                         out << "half a report";
                                         throw std::logic_error("encoder failed");
                                     }),
                 std::logic_error);
    {
        AtomicFile file(target.string());
        file.write("never committed");
        EXPECT_TRUE(fs::exists(file.temporaryPath()));
        EXPECT_EQ(fs::path(file.temporaryPath()).parent_path(), mDir);
    }
    EXPECT_EQ(readAll(target), "{}\n");
    EXPECT_EQ(namesIn(mDir), std::vector<std::string>{"report.json"});
}

TEST_F(DurableFile, ABareFileNameWritesInTheWorkingDirectory) {
    const fs::path previous = fs::current_path();
    fs::current_path(mDir);
    writeFileAtomically("bare.txt", std::string_view("here"));
    fs::current_path(previous);
    EXPECT_EQ(readAll(mDir / "bare.txt"), "here");
}

}  // namespace
}  // namespace penumbra
