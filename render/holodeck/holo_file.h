#pragma once
// The holodeck file (Ward & Simmons 1999, §2.1 and Fig. 5; format in docs/holodeck.md): a
// header with the sections, two superblock slots, and records anywhere after them: beam
// records (a beam's samples, contiguous) and directory records (where every beam's record
// is). The file is crash-safe by construction:
// - every record carries a CRC-32 of its contents;
// - a beam is never rewritten in place: a new record goes to a free fragment or the end of
//   the file, and the old one is freed only once a directory that does not use it is durable;
// - commit() makes the records durable, then the directory, then a superblock slot pointing at
//   it (the slots alternate, so a torn superblock leaves the previous commit);
// - open() takes the newest valid superblock, then adopts the whole beam records appended after
//   that commit and truncates the file at the first torn one.
// So a kill at any moment loses at most the beams written since the last commit into reused
// fragments, and never leaves a file that does not open. Not thread-safe: the server owns it.
//
// Index: HoloFile · HoloFileInfo

#include <cstdint>
#include <map>
#include <string>
#include <unordered_map>
#include <vector>

#include "render/holodeck/holo_sample.h"
#include "render/holodeck/holo_section.h"

namespace penumbra {

/// What `penumbra holodeck info` reports.
struct HoloFileInfo {
    int sections = 0;
    std::int64_t beams = 0;      ///< beams holding samples
    std::int64_t samples = 0;    ///< samples over all beams
    std::int64_t bytes = 0;      ///< the file's size
    std::int64_t freeBytes = 0;  ///< in free fragments
    int fragments = 0;           ///< free fragments
    std::int64_t recovered = 0;  ///< beam records adopted from after the last commit on open
    std::int64_t truncated = 0;  ///< bytes of torn records dropped on open
};

class HoloFile {
public:
    /// Opens `path`, creating it with `sections` when it does not exist (an existing file
    /// keeps its own sections; `sections` is then ignored). Repairs the tail of a file whose
    /// writer was killed. Throws InputError naming the file when it is not a holodeck file, its
    /// header or sections are damaged, or it cannot be read or written.
    HoloFile(const std::string& path, const std::vector<HoloSection>& sections);
    /// Opens an existing file for reading only (no repair: a torn tail is ignored).
    static HoloFile openReadOnly(const std::string& path);
    HoloFile(HoloFile&& other) noexcept;
    HoloFile& operator=(HoloFile&&) = delete;
    HoloFile(const HoloFile&) = delete;
    ~HoloFile();

    const std::string& path() const { return mPath; }
    const std::vector<HoloSection>& sections() const { return mSections; }
    /// The samples stored for a beam (0 when none).
    std::uint32_t sampleCount(int section, std::int64_t beam) const;
    /// A beam's samples; empty when none, or when its record fails its checksum (dropped).
    std::vector<HoloSample> readBeam(int section, std::int64_t beam);
    /// Replaces a beam's samples (durable at the next commit). Throws std::invalid_argument for
    /// a section or beam out of range, InputError when the write fails.
    void writeBeam(int section, std::int64_t beam, const std::vector<HoloSample>& samples);
    /// A beam's samples, for writeBeams.
    struct BeamSamples {
        int section = 0;
        std::int64_t beam = 0;
        std::vector<HoloSample> samples;
    };
    /// Replaces many beams' samples at once, as writeBeam each (a later entry for a beam wins),
    /// with their records side by side in one extent written at once (merging many beams).
    /// Checks every beam before writing any; throws as writeBeam.
    void writeBeams(const std::vector<BeamSamples>& beams);
    /// Makes every write so far durable (records, directory, superblock; fsync between).
    void commit();
    /// The beams holding samples, by section, in beam order.
    std::vector<std::pair<int, std::int64_t>> storedBeams() const;
    HoloFileInfo info() const;

    /// Rewrites the file with its beams collated in section and beam order and no free
    /// fragments (§2.2's optimizer): built in an AtomicFile beside `path`, which replaces `path`
    /// durably once complete (core/durable_file.h). Throws InputError naming `path`.
    static void optimize(const std::string& path);

private:
    struct Entry {
        std::uint64_t offset = 0;
        std::uint32_t count = 0;
    };
    struct Unopened {};
    HoloFile(const std::string& path, bool writable, Unopened);
    /// Writes a new, empty file at mPath with writeFileAtomically.
    void create(const std::vector<HoloSection>& sections);
    /// Reads the header and directory of the open mFd, adopts records after the last commit
    /// and builds the free list.
    void load();
    void readHeader();
    void readDirectory();
    void recoverTail();
    void rebuildFreeList();
    std::uint64_t allocate(std::uint64_t bytes);
    void release(std::uint64_t offset, std::uint64_t bytes);
    void checkWritable(int section, std::int64_t beam, std::size_t samples) const;
    /// Drops a beam from the directory; its record is freed at the next commit.
    void forget(int section, std::int64_t beam);
    /// A beam record (beamRecordBytes of the samples) at `record`.
    static void encodeRecord(int section, std::int64_t beam, const std::vector<HoloSample>& samples,
                             std::uint8_t* record);
    void writeAt(std::uint64_t offset, const void* data, std::size_t bytes);
    bool readAt(std::uint64_t offset, void* data, std::size_t bytes) const;
    void sync();
    [[noreturn]] void fail(const std::string& where, const std::string& problem) const;

    std::string mPath;
    int mFd = -1;
    bool mWritable = false;
    std::vector<HoloSection> mSections;
    std::vector<std::unordered_map<std::int64_t, Entry>> mDirectory;  ///< per section
    std::uint64_t mDataStart = 0;                  ///< the first byte after the superblock slots
    std::uint64_t mEnd = 0;                        ///< the file's logical end
    std::uint64_t mSequence = 0;                   ///< of the last durable commit
    std::uint64_t mDirOffset = 0, mDirBytes = 0;   ///< the durable directory record
    std::map<std::uint64_t, std::uint64_t> mFree;  ///< offset → bytes, coalesced
    /// Extents freed since the last commit: the durable directory may still use them.
    std::vector<std::pair<std::uint64_t, std::uint64_t>> mPendingFree;
    std::int64_t mRecovered = 0, mTruncated = 0;
};

}  // namespace penumbra
