#include "render/holodeck/holo_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <type_traits>

#include "core/durable_file.h"
#include "core/input_error.h"

namespace penumbra {

// Samples are copied to and from the file as they lie in memory: their one multi-byte field,
// the distance, is little-endian on disk.
static_assert(std::is_trivially_copyable_v<HoloSample>);
static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__,
              "the holodeck file assumes a little-endian host");

namespace {

// The layout (docs/holodeck.md). Integers are little-endian; doubles are their IEEE-754 bits.
constexpr char kMagic[8] = {'P', 'N', 'B', 'R', 'H', 'O', 'L', 'O'};
constexpr std::uint32_t kVersion = 1;
constexpr std::uint32_t kMaxSections = 64;
constexpr std::size_t kSectionBytes = 64;
constexpr std::size_t kSlotBytes = 40;
constexpr std::uint32_t kBeamMagic = 0x4D414542;  // "BEAM"
constexpr std::uint32_t kDirMagic = 0x53524944;   // "DIRS"
constexpr std::size_t kRecordHeader = 24;
constexpr std::size_t kDirEntryBytes = 24;

void put32(std::uint8_t* p, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
void put64(std::uint8_t* p, std::uint64_t v) {
    for (int i = 0; i < 8; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
std::uint32_t get32(const std::uint8_t* p) {
    std::uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= std::uint32_t(p[i]) << (8 * i);
    return v;
}
std::uint64_t get64(const std::uint8_t* p) {
    std::uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= std::uint64_t(p[i]) << (8 * i);
    return v;
}
void putDouble(std::uint8_t* p, double d) {
    std::uint64_t bits;
    std::memcpy(&bits, &d, 8);
    put64(p, bits);
}
double getDouble(const std::uint8_t* p) {
    const std::uint64_t bits = get64(p);
    double d;
    std::memcpy(&d, &bits, 8);
    return d;
}

std::uint32_t crc(const std::uint8_t* data, std::size_t bytes) {
    return static_cast<std::uint32_t>(::crc32(0L, data, static_cast<uInt>(bytes)));
}

std::size_t headerBytes(std::size_t sections) { return 16 + kSectionBytes * sections + 8; }
std::uint64_t beamRecordBytes(std::uint32_t count) {
    return kRecordHeader + std::uint64_t(sizeof(HoloSample)) * count;
}

/// The header: magic, version, the sections, and a CRC-32 of all of it.
std::vector<std::uint8_t> encodeHeader(const std::vector<HoloSection>& sections) {
    std::vector<std::uint8_t> h(headerBytes(sections.size()), 0);
    std::memcpy(h.data(), kMagic, 8);
    put32(&h[8], kVersion);
    put32(&h[12], static_cast<std::uint32_t>(sections.size()));
    for (std::size_t s = 0; s < sections.size(); ++s) {
        std::uint8_t* p = &h[16 + kSectionBytes * s];
        for (int a = 0; a < 3; ++a) {
            putDouble(p + 8 * a, sections[s].origin()[a]);
            putDouble(p + 24 + 8 * a, sections[s].size()[a]);
            put32(p + 48 + 4 * a, static_cast<std::uint32_t>(sections[s].grid()[a]));
        }
        p[60] = static_cast<std::uint8_t>(sections[s].kind());
    }
    const std::size_t body = 16 + kSectionBytes * sections.size();
    put32(&h[body], crc(h.data(), body));
    return h;
}

/// A new, empty file: the header and two empty superblock slots.
std::vector<std::uint8_t> encodeNewFile(const std::vector<HoloSection>& sections) {
    std::vector<std::uint8_t> bytes = encodeHeader(sections);
    bytes.resize(bytes.size() + 2 * kSlotBytes, 0);
    return bytes;
}

/// A superblock slot: the commit's sequence number, its directory record, the file's end.
struct Slot {
    std::uint64_t sequence = 0, dirOffset = 0, dirBytes = 0, end = 0;
};

std::array<std::uint8_t, kSlotBytes> encodeSlot(const Slot& s) {
    std::array<std::uint8_t, kSlotBytes> b{};
    put64(&b[0], s.sequence);
    put64(&b[8], s.dirOffset);
    put64(&b[16], s.dirBytes);
    put64(&b[24], s.end);
    put32(&b[32], crc(b.data(), 32));
    return b;
}

std::optional<Slot> decodeSlot(const std::uint8_t* b) {
    if (get32(b + 32) != crc(b, 32)) return std::nullopt;
    Slot s{get64(b), get64(b + 8), get64(b + 16), get64(b + 24)};
    if (s.sequence == 0) return std::nullopt;
    return s;
}

std::string errnoText() { return std::strerror(errno); }

}  // namespace

HoloFile::HoloFile(const std::string& path, bool writable, Unopened)
    : mPath(path), mWritable(writable) {}

HoloFile::HoloFile(const std::string& path, const std::vector<HoloSection>& sections)
    : HoloFile(path, true, Unopened{}) {
    if (!std::filesystem::exists(path)) create(sections);
    mFd = ::open(path.c_str(), O_RDWR | O_CLOEXEC);
    if (mFd < 0) fail("", "cannot open: " + errnoText());
    load();
    // Adopted records become part of a durable directory at once.
    if (mRecovered > 0) commit();
}

HoloFile HoloFile::openReadOnly(const std::string& path) {
    HoloFile file(path, false, Unopened{});
    file.mFd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (file.mFd < 0) file.fail("", "cannot open: " + errnoText());
    file.load();
    return file;
}

void HoloFile::load() {
    readHeader();
    readDirectory();
    recoverTail();
    rebuildFreeList();
}

HoloFile::HoloFile(HoloFile&& o) noexcept
    : mPath(std::move(o.mPath)),
      mFd(o.mFd),
      mWritable(o.mWritable),
      mSections(std::move(o.mSections)),
      mDirectory(std::move(o.mDirectory)),
      mDataStart(o.mDataStart),
      mEnd(o.mEnd),
      mSequence(o.mSequence),
      mDirOffset(o.mDirOffset),
      mDirBytes(o.mDirBytes),
      mFree(std::move(o.mFree)),
      mPendingFree(std::move(o.mPendingFree)),
      mRecovered(o.mRecovered),
      mTruncated(o.mTruncated) {
    o.mFd = -1;
}

HoloFile::~HoloFile() {
    if (mFd >= 0) ::close(mFd);
}

void HoloFile::fail(const std::string& where, const std::string& problem) const {
    throw InputError(mPath, where, problem);
}

void HoloFile::create(const std::vector<HoloSection>& sections) {
    if (sections.empty() || sections.size() > kMaxSections)
        fail("", "a new holodeck needs 1 to " + std::to_string(kMaxSections) + " sections");
    // Written whole (writeFileAtomically): a new file is complete or absent.
    const std::vector<std::uint8_t> bytes = encodeNewFile(sections);
    writeFileAtomically(mPath, std::string_view(reinterpret_cast<const char*>(bytes.data()),
                                                 bytes.size()));
}

void HoloFile::readHeader() {
    std::uint8_t fixed[16];
    if (!readAt(0, fixed, 16) || std::memcmp(fixed, kMagic, 8) != 0)
        fail("header", "not a holodeck file");
    if (get32(fixed + 8) != kVersion)
        fail("header", "unsupported version " + std::to_string(get32(fixed + 8)));
    const std::uint32_t n = get32(fixed + 12);
    if (n == 0 || n > kMaxSections) fail("header", "bad section count " + std::to_string(n));
    std::vector<std::uint8_t> h(headerBytes(n));
    const std::size_t body = 16 + kSectionBytes * n;
    if (!readAt(0, h.data(), h.size()) || get32(&h[body]) != crc(h.data(), body))
        fail("header", "damaged (checksum)");
    for (std::uint32_t s = 0; s < n; ++s) {
        const std::uint8_t* p = &h[16 + kSectionBytes * s];
        Vec3 origin, size;
        std::array<int, 3> grid;
        for (int a = 0; a < 3; ++a) {
            origin[a] = getDouble(p + 8 * a);
            size[a] = getDouble(p + 24 + 8 * a);
            grid[a] = static_cast<int>(std::min<std::uint32_t>(get32(p + 48 + 4 * a), 1u << 20));
        }
        if (p[60] > 1) fail("sections[" + std::to_string(s) + "]", "unknown kind");
        try {
            mSections.emplace_back(origin, size, grid, static_cast<SectionKind>(p[60]));
        } catch (const std::invalid_argument& e) {
            fail("sections[" + std::to_string(s) + "]", e.what());
        }
    }
    mDirectory.assign(n, {});
    mDataStart = h.size() + 2 * kSlotBytes;
}

void HoloFile::readDirectory() {
    struct stat st {};
    if (::fstat(mFd, &st) != 0) fail("", "cannot stat: " + errnoText());
    const std::uint64_t size = static_cast<std::uint64_t>(st.st_size);
    mEnd = mDataStart;
    if (size < mDataStart) {
        // A header without slots: only a file cut short by something other than Penumbra.
        if (!mWritable) fail("header", "truncated");
        return;
    }
    std::uint8_t slots[2 * kSlotBytes];
    if (!readAt(mDataStart - 2 * kSlotBytes, slots, sizeof slots)) fail("", "cannot read");
    std::vector<Slot> candidates;
    for (int i = 0; i < 2; ++i)
        if (auto s = decodeSlot(slots + i * kSlotBytes)) candidates.push_back(*s);
    std::sort(candidates.begin(), candidates.end(),
              [](const Slot& a, const Slot& b) { return a.sequence > b.sequence; });
    // The newest commit whose directory record is whole.
    for (const Slot& slot : candidates) {
        if (slot.dirOffset < mDataStart || slot.dirBytes < kRecordHeader ||
            slot.dirOffset + slot.dirBytes > size || slot.end > size ||
            (slot.dirBytes - kRecordHeader) % kDirEntryBytes != 0)
            continue;
        std::vector<std::uint8_t> d(slot.dirBytes);
        if (!readAt(slot.dirOffset, d.data(), d.size())) continue;
        if (get32(&d[0]) != kDirMagic || get32(&d[4]) != crc(&d[8], d.size() - 8)) continue;
        const std::uint64_t n = get64(&d[16]);
        if (n != (slot.dirBytes - kRecordHeader) / kDirEntryBytes) continue;
        for (std::uint64_t i = 0; i < n; ++i) {
            const std::uint8_t* e = &d[kRecordHeader + kDirEntryBytes * i];
            const std::uint32_t section = get32(e), count = get32(e + 4);
            const std::int64_t beam = static_cast<std::int64_t>(get64(e + 8));
            const std::uint64_t offset = get64(e + 16);
            if (section >= mSections.size() || beam < 0 || beam >= mSections[section].beamCount() ||
                count == 0 || offset < mDataStart || offset + beamRecordBytes(count) > size)
                continue;  // a damaged entry: its beam is dropped
            mDirectory[section][beam] = {offset, count};
        }
        mSequence = slot.sequence;
        mDirOffset = slot.dirOffset;
        mDirBytes = slot.dirBytes;
        mEnd = std::max<std::uint64_t>(slot.end, mDataStart);
        return;
    }
}

void HoloFile::recoverTail() {
    struct stat st {};
    if (::fstat(mFd, &st) != 0) fail("", "cannot stat: " + errnoText());
    const std::uint64_t size = static_cast<std::uint64_t>(st.st_size);
    // Whole records appended after the last commit, in order: later ones supersede.
    std::uint64_t pos = mEnd;
    std::vector<std::uint8_t> record;
    while (pos + kRecordHeader <= size) {
        std::uint8_t head[kRecordHeader];
        if (!readAt(pos, head, kRecordHeader)) break;
        const std::uint32_t magic = get32(head);
        std::uint64_t bytes = 0;
        if (magic == kBeamMagic)
            bytes = beamRecordBytes(get32(head + 12));
        else if (magic == kDirMagic && get64(head + 16) < (size - pos) / kDirEntryBytes)
            bytes = kRecordHeader + kDirEntryBytes * get64(head + 16);
        else
            break;
        if (pos + bytes > size) break;
        record.resize(bytes);
        if (!readAt(pos, record.data(), bytes) || get32(&record[4]) != crc(&record[8], bytes - 8))
            break;
        if (magic == kBeamMagic) {
            const std::uint32_t section = get32(&record[8]), count = get32(&record[12]);
            const std::int64_t beam = static_cast<std::int64_t>(get64(&record[16]));
            if (section >= mSections.size() || beam < 0 || beam >= mSections[section].beamCount() ||
                count == 0)
                break;
            auto& entry = mDirectory[section][beam];
            if (entry.count > 0)
                mPendingFree.emplace_back(entry.offset, beamRecordBytes(entry.count));
            entry = {pos, count};
            ++mRecovered;
        }
        pos += bytes;
    }
    mTruncated = static_cast<std::int64_t>(size - std::min(size, pos));
    mEnd = std::max(mEnd, pos);
    if (mWritable && size > mEnd && ::ftruncate(mFd, static_cast<off_t>(mEnd)) != 0)
        fail("", "cannot truncate a torn record: " + errnoText());
}

void HoloFile::rebuildFreeList() {
    // Every extent in use (beams, the durable directory, extents it may still use); the gaps
    // between them are the free fragments.
    std::vector<std::pair<std::uint64_t, std::uint64_t>> used = mPendingFree;
    for (const auto& section : mDirectory)
        for (const auto& [beam, e] : section) used.emplace_back(e.offset, beamRecordBytes(e.count));
    if (mDirBytes > 0) used.emplace_back(mDirOffset, mDirBytes);
    std::sort(used.begin(), used.end());
    mFree.clear();
    std::uint64_t at = mDataStart;
    for (const auto& [offset, bytes] : used) {
        if (offset > at) mFree[at] = offset - at;
        at = std::max(at, offset + bytes);
    }
    if (mEnd > at) mFree[at] = mEnd - at;
}

std::uint64_t HoloFile::allocate(std::uint64_t bytes) {
    for (auto it = mFree.begin(); it != mFree.end(); ++it) {
        if (it->second < bytes) continue;
        const std::uint64_t offset = it->first, left = it->second - bytes;
        mFree.erase(it);
        if (left > 0) mFree[offset + bytes] = left;
        return offset;
    }
    const std::uint64_t offset = mEnd;
    mEnd += bytes;
    return offset;
}

void HoloFile::release(std::uint64_t offset, std::uint64_t bytes) {
    auto [it, inserted] = mFree.emplace(offset, bytes);
    if (!inserted) return;
    // Coalesce with the fragments on either side.
    if (it != mFree.begin()) {
        auto before = std::prev(it);
        if (before->first + before->second == offset) {
            before->second += it->second;
            mFree.erase(it);
            it = before;
        }
    }
    auto after = std::next(it);
    if (after != mFree.end() && it->first + it->second == after->first) {
        it->second += after->second;
        mFree.erase(after);
    }
}

void HoloFile::writeAt(std::uint64_t offset, const void* data, std::size_t bytes) {
    const auto* p = static_cast<const std::uint8_t*>(data);
    while (bytes > 0) {
        const ssize_t n = ::pwrite(mFd, p, bytes, static_cast<off_t>(offset));
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) fail("", "cannot write: " + errnoText());
        p += n;
        offset += static_cast<std::uint64_t>(n);
        bytes -= static_cast<std::size_t>(n);
    }
}

bool HoloFile::readAt(std::uint64_t offset, void* data, std::size_t bytes) const {
    auto* p = static_cast<std::uint8_t*>(data);
    while (bytes > 0) {
        const ssize_t n = ::pread(mFd, p, bytes, static_cast<off_t>(offset));
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) return false;
        p += n;
        offset += static_cast<std::uint64_t>(n);
        bytes -= static_cast<std::size_t>(n);
    }
    return true;
}

void HoloFile::sync() {
    if (::fdatasync(mFd) != 0) fail("", "cannot sync: " + errnoText());
}

std::uint32_t HoloFile::sampleCount(int section, std::int64_t beam) const {
    if (section < 0 || section >= int(mDirectory.size())) return 0;
    const auto it = mDirectory[section].find(beam);
    return it == mDirectory[section].end() ? 0 : it->second.count;
}

std::vector<HoloSample> HoloFile::readBeam(int section, std::int64_t beam) {
    if (section < 0 || section >= int(mDirectory.size())) return {};
    const auto it = mDirectory[section].find(beam);
    if (it == mDirectory[section].end()) return {};
    const Entry e = it->second;
    std::vector<std::uint8_t> record(beamRecordBytes(e.count));
    const bool whole =
        readAt(e.offset, record.data(), record.size()) && get32(&record[0]) == kBeamMagic &&
        get32(&record[4]) == crc(&record[8], record.size() - 8) &&
        get32(&record[8]) == std::uint32_t(section) && get32(&record[12]) == e.count &&
        static_cast<std::int64_t>(get64(&record[16])) == beam;
    if (!whole) {
        // Damaged on disk: the beam is dropped (its extent stays unused until optimize).
        mDirectory[section].erase(it);
        return {};
    }
    std::vector<HoloSample> samples(e.count);
    std::memcpy(static_cast<void*>(samples.data()), &record[kRecordHeader],
                sizeof(HoloSample) * e.count);
    return samples;
}

void HoloFile::checkWritable(int section, std::int64_t beam, std::size_t samples) const {
    if (!mWritable) throw std::logic_error("holodeck: writeBeam on a file opened read-only");
    if (section < 0 || section >= int(mSections.size()) || beam < 0 ||
        beam >= mSections[section].beamCount())
        throw std::invalid_argument("holodeck: beam " + std::to_string(beam) + " of section " +
                                    std::to_string(section) + " is out of range");
    if (samples > 0xffffffffu) throw std::invalid_argument("holodeck: beam too large");
}

void HoloFile::forget(int section, std::int64_t beam) {
    auto& dir = mDirectory[section];
    const auto old = dir.find(beam);
    if (old == dir.end()) return;
    mPendingFree.emplace_back(old->second.offset, beamRecordBytes(old->second.count));
    dir.erase(old);
}

void HoloFile::encodeRecord(int section, std::int64_t beam, const std::vector<HoloSample>& samples,
                            std::uint8_t* record) {
    const auto count = static_cast<std::uint32_t>(samples.size());
    put32(&record[0], kBeamMagic);
    put32(&record[8], static_cast<std::uint32_t>(section));
    put32(&record[12], count);
    put64(&record[16], static_cast<std::uint64_t>(beam));
    std::memcpy(&record[kRecordHeader], samples.data(), sizeof(HoloSample) * count);
    put32(&record[4], crc(&record[8], beamRecordBytes(count) - 8));
}

void HoloFile::writeBeam(int section, std::int64_t beam, const std::vector<HoloSample>& samples) {
    checkWritable(section, beam, samples.size());
    forget(section, beam);
    if (samples.empty()) return;
    const auto count = static_cast<std::uint32_t>(samples.size());
    std::vector<std::uint8_t> record(beamRecordBytes(count));
    encodeRecord(section, beam, samples, record.data());
    const std::uint64_t offset = allocate(record.size());
    writeAt(offset, record.data(), record.size());
    mDirectory[section][beam] = {offset, count};
}

void HoloFile::writeBeams(const std::vector<BeamSamples>& beams) {
    std::uint64_t bytes = 0;
    for (const BeamSamples& b : beams) {
        checkWritable(b.section, b.beam, b.samples.size());
        if (!b.samples.empty()) bytes += beamRecordBytes(std::uint32_t(b.samples.size()));
    }
    // Every record into one buffer, written to one extent; then the directory points at them.
    std::vector<std::uint8_t> records(bytes);
    std::uint64_t at = 0;
    for (const BeamSamples& b : beams) {
        if (b.samples.empty()) continue;
        encodeRecord(b.section, b.beam, b.samples, &records[at]);
        at += beamRecordBytes(std::uint32_t(b.samples.size()));
    }
    const std::uint64_t offset = bytes > 0 ? allocate(bytes) : 0;
    if (bytes > 0) writeAt(offset, records.data(), records.size());
    at = 0;
    for (const BeamSamples& b : beams) {
        forget(b.section, b.beam);
        if (b.samples.empty()) continue;
        const auto count = static_cast<std::uint32_t>(b.samples.size());
        mDirectory[b.section][b.beam] = {offset + at, count};
        at += beamRecordBytes(count);
    }
}

void HoloFile::commit() {
    if (!mWritable) throw std::logic_error("holodeck: commit on a file opened read-only");
    // The directory, in section and beam order.
    const auto beams = storedBeams();
    std::vector<std::uint8_t> d(kRecordHeader + kDirEntryBytes * beams.size());
    put32(&d[0], kDirMagic);
    put64(&d[8], mSequence + 1);
    put64(&d[16], beams.size());
    for (std::size_t i = 0; i < beams.size(); ++i) {
        const auto [section, beam] = beams[i];
        const Entry& e = mDirectory[section].at(beam);
        std::uint8_t* p = &d[kRecordHeader + kDirEntryBytes * i];
        put32(p, static_cast<std::uint32_t>(section));
        put32(p + 4, e.count);
        put64(p + 8, static_cast<std::uint64_t>(beam));
        put64(p + 16, e.offset);
    }
    put32(&d[4], crc(&d[8], d.size() - 8));
    const std::uint64_t dirOffset = allocate(d.size());
    writeAt(dirOffset, d.data(), d.size());
    // Records and directory durable before the slot that points at them.
    sync();
    const Slot slot{mSequence + 1, dirOffset, d.size(), mEnd};
    const auto bytes = encodeSlot(slot);
    writeAt(mDataStart - 2 * kSlotBytes + kSlotBytes * (slot.sequence % 2), bytes.data(),
            bytes.size());
    sync();
    // What the previous commit used is free now.
    if (mDirBytes > 0) release(mDirOffset, mDirBytes);
    for (const auto& [offset, size] : mPendingFree) release(offset, size);
    mPendingFree.clear();
    mSequence = slot.sequence;
    mDirOffset = dirOffset;
    mDirBytes = d.size();
}

std::vector<std::pair<int, std::int64_t>> HoloFile::storedBeams() const {
    std::vector<std::pair<int, std::int64_t>> beams;
    for (int s = 0; s < int(mDirectory.size()); ++s) {
        const std::size_t first = beams.size();
        for (const auto& [beam, e] : mDirectory[s]) beams.emplace_back(s, beam);
        std::sort(beams.begin() + std::ptrdiff_t(first), beams.end());
    }
    return beams;
}

HoloFileInfo HoloFile::info() const {
    HoloFileInfo info;
    info.sections = int(mSections.size());
    for (const auto& section : mDirectory) {
        info.beams += std::int64_t(section.size());
        for (const auto& [beam, e] : section) info.samples += e.count;
    }
    info.bytes = std::int64_t(mEnd);
    for (const auto& [offset, bytes] : mFree) {
        info.freeBytes += std::int64_t(bytes);
        ++info.fragments;
    }
    info.recovered = mRecovered;
    info.truncated = mTruncated;
    return info;
}

void HoloFile::optimize(const std::string& path) {
    HoloFile source = openReadOnly(path);
    // The collated copy is built in an AtomicFile (a unique temporary beside `path`), through a
    // HoloFile on a duplicate of its descriptor, and replaces `path` durably once committed.
    AtomicFile replacement(path);
    {
        HoloFile target(path, true, Unopened{});
        target.mFd = ::fcntl(replacement.fd(), F_DUPFD_CLOEXEC, 0);
        if (target.mFd < 0) target.fail("", "cannot write the optimized file: " + errnoText());
        const std::vector<std::uint8_t> bytes = encodeNewFile(source.sections());
        target.writeAt(0, bytes.data(), bytes.size());
        target.load();
        for (const auto& [section, beam] : source.storedBeams())
            target.writeBeam(section, beam, source.readBeam(section, beam));
        target.commit();
    }
    replacement.commit();
}

}  // namespace penumbra
