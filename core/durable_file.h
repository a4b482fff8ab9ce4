#pragma once
// Durable whole-file writes: a file is replaced by a complete new version or left as it was,
// whatever stops the writer (an error, a kill, a power cut once the call has returned). Every
// writer of a whole user-visible file goes through here: scenes and meshes, exports, images,
// reports, the lit-scene solution, the holodeck's creation and compaction. The append-only edit
// log and the holodeck's in-place records keep their own durability rules.
//
// The steps: a temporary file beside the target (unique name, created exclusively, so the
// rename never crosses file systems and two writers never share one), all bytes written and
// fsync'd, the old file's permission bits copied onto it (a new file has 0666 less the umask),
// rename over the target, fsync of the directory. Any failure removes the temporary file and
// throws InputError naming the target and the system's reason; the target is then untouched.
//
// Index: AtomicFile · writeFileAtomically

#include <functional>
#include <ostream>
#include <string>
#include <string_view>

namespace penumbra {

/// A replacement of one file in progress. Creating it makes the temporary file; commit() puts
/// it in place of the target; destroying it without a commit removes the temporary file. Use
/// it directly only to write through the descriptor (positioned writes); otherwise call
/// writeFileAtomically.
class AtomicFile {
public:
    /// Creates the temporary file `.NAME.tmp-XXXXXXXX` in `path`'s directory, open for
    /// reading and writing. Throws InputError naming `path` when it cannot.
    explicit AtomicFile(std::string path);
    /// Removes the temporary file unless commit() has run.
    ~AtomicFile();
    AtomicFile(const AtomicFile&) = delete;
    AtomicFile& operator=(const AtomicFile&) = delete;

    /// The file being replaced, as the caller named it.
    const std::string& path() const { return mPath; }
    /// The temporary file's path.
    const std::string& temporaryPath() const { return mTemporary; }
    /// The temporary file's descriptor (read-write; pwrite and pread allowed); -1 after
    /// commit(). Owned here: do not close it.
    int fd() const { return mFd; }

    /// Appends all of `bytes` at the descriptor's position. Throws InputError naming path()
    /// and the system's reason (the temporary file is removed when this object goes).
    void write(std::string_view bytes);
    /// Makes the written bytes the file at path(): fsync, the old file's permission bits (or
    /// 0666 less the umask for a new file), rename over path(), fsync of the directory.
    /// Throws InputError naming path() and the system's reason, with the temporary file
    /// removed and path() untouched (unless only the final directory fsync failed).
    void commit();

private:
    [[noreturn]] void fail(const std::string& step, int error);

    std::string mPath;
    std::string mTemporary;
    int mFd = -1;
    bool mCommitted = false;
};

/// Replaces `path` with exactly `bytes`, durably and atomically (see the file comment).
/// Throws InputError `PATH: cannot write: REASON` on failure, `path` untouched.
void writeFileAtomically(const std::string& path, std::string_view bytes);

/// Replaces `path` with what `write` streams into the std::ostream it is given (binary, a
/// fresh stream: default precision and flags), durably and atomically. An exception thrown by
/// `write` passes through, with `path` untouched; a failed write throws InputError as above.
void writeFileAtomically(const std::string& path,
                         const std::function<void(std::ostream&)>& write);

}  // namespace penumbra
