#include "core/durable_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <cerrno>
#include <cstring>
#include <exception>
#include <filesystem>
#include <random>
#include <streambuf>
#include <vector>

#include "core/input_error.h"

namespace penumbra {

namespace {

/// The directory holding `path` ("." for a bare file name).
std::string directoryOf(const std::string& path) {
    const std::filesystem::path parent = std::filesystem::path(path).parent_path();
    return parent.empty() ? std::string(".") : parent.string();
}

/// Eight random hexadecimal digits: random_device for separate processes, a counter for
/// threads of one process.
std::string uniqueSuffix() {
    static std::atomic<unsigned> counter{0};
    thread_local std::mt19937 random{std::random_device{}() ^
                                     (counter.fetch_add(1) * 0x9E3779B9u)};
    static constexpr char kHex[] = "0123456789abcdef";
    std::uint32_t bits = static_cast<std::uint32_t>(random()) ^ counter.fetch_add(1);
    std::string s(8, '0');
    for (char& c : s) {
        c = kHex[bits & 15];
        bits >>= 4;
    }
    return s;
}

/// A std::streambuf that appends to an AtomicFile through a buffer of its own. A failed
/// write makes the stream bad and is kept for rethrow().
class AtomicFileBuffer : public std::streambuf {
public:
    explicit AtomicFileBuffer(AtomicFile& file) : mFile(file), mBuffer(1 << 16) {
        setp(mBuffer.data(), mBuffer.data() + mBuffer.size());
    }

    /// Writes what is still buffered; rethrows the first failed write.
    void finish() {
        flush();
        if (mError) std::rethrow_exception(mError);
    }

protected:
    int_type overflow(int_type c) override {
        if (!flush()) return traits_type::eof();
        if (!traits_type::eq_int_type(c, traits_type::eof())) {
            *pptr() = traits_type::to_char_type(c);
            pbump(1);
        }
        return traits_type::not_eof(c);
    }

    std::streamsize xsputn(const char* s, std::streamsize n) override {
        // Large pieces go straight to the file rather than through the buffer.
        if (n < static_cast<std::streamsize>(mBuffer.size()))
            return std::streambuf::xsputn(s, n);
        if (!flush() || !append(std::string_view(s, static_cast<std::size_t>(n)))) return 0;
        return n;
    }

    int sync() override { return flush() ? 0 : -1; }

private:
    bool flush() {
        const std::string_view pending(pbase(), static_cast<std::size_t>(pptr() - pbase()));
        setp(mBuffer.data(), mBuffer.data() + mBuffer.size());
        return append(pending);
    }

    bool append(std::string_view bytes) {
        if (mError) return false;
        try {
            mFile.write(bytes);
            return true;
        } catch (...) {
            mError = std::current_exception();
            return false;
        }
    }

    AtomicFile& mFile;
    std::vector<char> mBuffer;
    std::exception_ptr mError;
};

}  // namespace

AtomicFile::AtomicFile(std::string path) : mPath(std::move(path)) {
    const std::string directory = directoryOf(mPath);
    const std::string name = std::filesystem::path(mPath).filename().string();
    // Mode 0666: the kernel takes the umask (or the directory's default ACL) off, as for any
    // new file; commit() copies an existing target's bits instead.
    for (int attempt = 0; mFd < 0; ++attempt) {
        mTemporary = (std::filesystem::path(directory) / ("." + name + ".tmp-" + uniqueSuffix()))
                         .string();
        mFd = ::open(mTemporary.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (mFd < 0 && (errno != EEXIST || attempt == 100)) {
            const int error = errno;
            mTemporary.clear();
            fail("creating a temporary file in " + directory, error);
        }
    }
}

AtomicFile::~AtomicFile() {
    if (mFd >= 0) ::close(mFd);
    if (!mCommitted && !mTemporary.empty()) ::unlink(mTemporary.c_str());
}

void AtomicFile::fail(const std::string& step, int error) {
    if (mFd >= 0) ::close(mFd);
    mFd = -1;
    if (!mCommitted && !mTemporary.empty()) ::unlink(mTemporary.c_str());
    mTemporary.clear();
    throw InputError(mPath, "", "cannot write (" + step + "): " + std::strerror(error));
}

void AtomicFile::write(std::string_view bytes) {
    if (mFd < 0) throw InputError(mPath, "", "cannot write: the file is already committed");
    while (!bytes.empty()) {
        const ssize_t n = ::write(mFd, bytes.data(), bytes.size());
        if (n < 0) {
            if (errno == EINTR) continue;
            fail("writing", errno);
        }
        bytes.remove_prefix(static_cast<std::size_t>(n));
    }
}

void AtomicFile::commit() {
    if (mFd < 0) throw InputError(mPath, "", "cannot write: the file is already committed");
    // The old file's permission bits, set before the fsync so they are durable with the bytes.
    struct stat existing {};
    if (::stat(mPath.c_str(), &existing) == 0 && ::fchmod(mFd, existing.st_mode & 07777) != 0)
        fail("setting permissions", errno);
    if (::fsync(mFd) != 0) fail("syncing", errno);
    const int fd = mFd;
    mFd = -1;
    if (::close(fd) != 0) fail("closing", errno);
    if (::rename(mTemporary.c_str(), mPath.c_str()) != 0) fail("renaming over it", errno);
    mCommitted = true;

    // The rename is durable once the directory is: sync it. EINVAL: the file system cannot
    // sync a directory (its renames are as durable as it makes them).
    const std::string directory = directoryOf(mPath);
    const int dirFd = ::open(directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dirFd < 0) fail("opening its directory to sync it", errno);
    if (::fsync(dirFd) != 0 && errno != EINVAL) {
        const int error = errno;
        ::close(dirFd);
        fail("syncing its directory", error);
    }
    ::close(dirFd);
}

void writeFileAtomically(const std::string& path, std::string_view bytes) {
    AtomicFile file(path);
    file.write(bytes);
    file.commit();
}

void writeFileAtomically(const std::string& path,
                         const std::function<void(std::ostream&)>& write) {
    AtomicFile file(path);
    AtomicFileBuffer buffer(file);
    std::ostream out(&buffer);
    write(out);
    buffer.finish();
    if (!out) throw InputError(path, "", "cannot write: the output stream failed");
    file.commit();
}

}  // namespace penumbra
