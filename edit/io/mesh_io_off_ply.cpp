// OFF and PLY: strict readers of our own. OpenMesh 9's readers for these two formats hang
// (negative or absurd counts, malformed PLY headers), crash (SEGV in _PLYReader_::can_u_read)
// or print to std::cerr on malformed files; these readers fail with one InputError instead,
// and every loop is bounded by the bytes left in the file.
// See mesh_io_internal.h.

#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <string_view>

#include "core/colour.h"
#include "core/input_error.h"
#include "edit/io/mesh_io_internal.h"

namespace penumbra::mesh_io_detail {

std::string formatNumber(double value) {
    std::ostringstream out;
    out << value;
    return out.str();
}

std::string readFileBytes(const std::string& path) {
    std::ifstream file(path, std::ios::binary);
    std::ostringstream bytes;
    bytes << file.rdbuf();
    if (!file && !file.eof()) throw InputError(path, "", "read error");
    return bytes.str();
}

/// Whitespace-separated tokens of one line.
void splitTokens(std::string_view line, std::vector<std::string_view>& tokens) {
    tokens.clear();
    size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
        const size_t start = i;
        while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
        if (i > start) tokens.push_back(line.substr(start, i - start));
    }
}

/// A finite or non-finite decimal number ("nan" and "inf" included); false on garbage.
bool parseDouble(std::string_view token, double& value) {
    const char* end = token.data() + token.size();
    const auto [ptr, ec] = std::from_chars(token.data(), end, value);
    return ec == std::errc() && ptr == end;
}

/// A non-negative integer up to `limit`; false on garbage, sign or overflow.
bool parseCount(std::string_view token, uint64_t limit, uint64_t& value) {
    const char* end = token.data() + token.size();
    const auto [ptr, ec] = std::from_chars(token.data(), end, value);
    return ec == std::errc() && ptr == end && value <= limit;
}

/// Lines of an OFF file without '#' comments, blank lines skipped, with line numbers.
class OffLines {
public:
    explicit OffLines(std::string_view text) : mText(text) {}

    /// Tokens of the next non-blank line; false at the end of the file.
    bool next(std::vector<std::string_view>& tokens) {
        while (mPos < mText.size()) {
            size_t end = mText.find('\n', mPos);
            if (end == std::string_view::npos) end = mText.size();
            std::string_view line = mText.substr(mPos, end - mPos);
            mPos = end + 1;
            ++mLine;
            line = line.substr(0, line.find('#'));
            splitTokens(line, tokens);
            if (!tokens.empty()) return true;
        }
        return false;
    }
    std::string where() const { return "line " + std::to_string(mLine); }

private:
    std::string_view mText;
    size_t mPos = 0;
    size_t mLine = 0;
};

PolygonSoup readOff(const std::string& path) {
    const std::string text = readFileBytes(path);
    OffLines lines(text);
    std::vector<std::string_view> tokens;
    auto fail = [&](const std::string& problem) { throw InputError(path, lines.where(), problem); };

    // Header keyword: [ST][C][N]OFF; 4OFF, nOFF and binary OFF are not supported.
    if (!lines.next(tokens)) throw InputError(path, "", "empty file, expected an OFF header");
    const std::string_view keyword = tokens[0];
    static const std::array<std::string_view, 8> kKeywords = {
        "OFF", "COFF", "NOFF", "CNOFF", "STOFF", "STCOFF", "STNOFF", "STCNOFF"};
    if (std::find(kKeywords.begin(), kKeywords.end(), keyword) == kKeywords.end()) {
        fail("expected an OFF header (OFF, COFF, NOFF, STOFF...), got '" + std::string(keyword) +
             "'");
    }
    if (tokens.size() > 1 && tokens[1] == "BINARY") fail("binary OFF is not supported");

    // Counts, on the header line or the next one: vertices faces [edges].
    std::vector<std::string_view> counts(tokens.begin() + 1, tokens.end());
    if (counts.empty()) {
        if (!lines.next(tokens)) fail("file ends before the vertex and face counts");
        counts = tokens;
    }
    uint64_t vertexCount = 0, faceCount = 0;
    const uint64_t limit = text.size();  // every vertex and face takes at least one byte
    if (counts.size() < 2 || !parseCount(counts[0], limit, vertexCount) ||
        !parseCount(counts[1], limit, faceCount)) {
        fail("expected vertex and face counts (non-negative, at most one per byte of the file)");
    }

    PolygonSoup soup;
    for (uint64_t v = 0; v < vertexCount; ++v) {
        if (!lines.next(tokens)) {
            fail("file ends after " + std::to_string(v) + " of " + std::to_string(vertexCount) +
                 " vertices");
        }
        double xyz[3];
        if (tokens.size() < 3 || !parseDouble(tokens[0], xyz[0]) ||
            !parseDouble(tokens[1], xyz[1]) || !parseDouble(tokens[2], xyz[2])) {
            fail("expected vertex coordinates x y z");
        }
        soup.positions.emplace_back(xyz[0], xyz[1], xyz[2]);
    }
    std::vector<int> face;
    for (uint64_t f = 0; f < faceCount; ++f) {
        if (!lines.next(tokens)) {
            fail("file ends after " + std::to_string(f) + " of " + std::to_string(faceCount) +
                 " faces");
        }
        uint64_t n = 0;
        if (!parseCount(tokens[0], tokens.size() - 1, n)) {
            fail("expected a vertex count followed by that many vertex indices");
        }
        face.clear();
        for (uint64_t k = 1; k <= n; ++k) {
            uint64_t index = 0;
            if (!parseCount(tokens[k], std::numeric_limits<int>::max(), index)) {
                fail("invalid vertex index '" + std::string(tokens[k]) + "'");
            }
            face.push_back(static_cast<int>(index));
        }
        soup.addFace(face.data(), face.size(), -1);
    }
    return soup;
}

enum class PlyType { Int8, Uint8, Int16, Uint16, Int32, Uint32, Float32, Float64 };

struct PlyProperty {
    std::string name;
    bool isList = false;
    PlyType countType = PlyType::Uint8;  ///< lists only
    PlyType valueType = PlyType::Float32;
};

struct PlyElement {
    std::string name;
    uint64_t count = 0;
    std::vector<PlyProperty> properties;
};

bool parsePlyType(std::string_view name, PlyType& type) {
    static const std::pair<std::string_view, PlyType> kNames[] = {
        {"char", PlyType::Int8},      {"int8", PlyType::Int8},       {"uchar", PlyType::Uint8},
        {"uint8", PlyType::Uint8},    {"short", PlyType::Int16},     {"int16", PlyType::Int16},
        {"ushort", PlyType::Uint16},  {"uint16", PlyType::Uint16},   {"int", PlyType::Int32},
        {"int32", PlyType::Int32},    {"uint", PlyType::Uint32},     {"uint32", PlyType::Uint32},
        {"float", PlyType::Float32},  {"float32", PlyType::Float32}, {"double", PlyType::Float64},
        {"float64", PlyType::Float64}};
    for (const auto& [text, value] : kNames) {
        if (text == name) {
            type = value;
            return true;
        }
    }
    return false;
}

size_t plyTypeSize(PlyType type) {
    switch (type) {
        case PlyType::Int8:
        case PlyType::Uint8:
            return 1;
        case PlyType::Int16:
        case PlyType::Uint16:
            return 2;
        case PlyType::Int32:
        case PlyType::Uint32:
        case PlyType::Float32:
            return 4;
        case PlyType::Float64:
            return 8;
    }
    return 1;
}

/// Values of a PLY body: whitespace-separated text, or packed binary of either byte order.
class PlyBody {
public:
    enum class Encoding { Ascii, LittleEndian, BigEndian };

    PlyBody(const std::string& path, std::string_view bytes, Encoding encoding)
        : mPath(path), mBytes(bytes), mEncoding(encoding) {}

    size_t remaining() const { return mBytes.size() - mPos; }

    double read(PlyType type, const std::string& what) {
        return mEncoding == Encoding::Ascii ? readText(what) : readBinary(type, what);
    }

private:
    double readText(const std::string& what) {
        while (mPos < mBytes.size() && std::isspace(static_cast<unsigned char>(mBytes[mPos]))) {
            ++mPos;
        }
        const size_t start = mPos;
        while (mPos < mBytes.size() && !std::isspace(static_cast<unsigned char>(mBytes[mPos]))) {
            ++mPos;
        }
        if (mPos == start) throw InputError(mPath, what, "file ends early");
        double value = 0.0;
        const std::string_view token = mBytes.substr(start, mPos - start);
        if (!parseDouble(token, value)) {
            throw InputError(mPath, what, "invalid number '" + std::string(token) + "'");
        }
        return value;
    }

    double readBinary(PlyType type, const std::string& what) {
        const size_t size = plyTypeSize(type);
        if (remaining() < size) throw InputError(mPath, what, "file ends early");
        unsigned char raw[8];
        std::memcpy(raw, mBytes.data() + mPos, size);
        mPos += size;
        if ((mEncoding == Encoding::BigEndian) != (std::endian::native == std::endian::big)) {
            std::reverse(raw, raw + size);
        }
        switch (type) {
            case PlyType::Int8:
                return static_cast<double>(static_cast<int8_t>(raw[0]));
            case PlyType::Uint8:
                return raw[0];
            case PlyType::Int16:
                return decode<int16_t>(raw);
            case PlyType::Uint16:
                return decode<uint16_t>(raw);
            case PlyType::Int32:
                return decode<int32_t>(raw);
            case PlyType::Uint32:
                return decode<uint32_t>(raw);
            case PlyType::Float32:
                return decode<float>(raw);
            case PlyType::Float64:
                return decode<double>(raw);
        }
        return 0.0;
    }

    template <typename T>
    static double decode(const unsigned char* raw) {
        T value;
        std::memcpy(&value, raw, sizeof value);
        return static_cast<double>(value);
    }

    std::string mPath;
    std::string_view mBytes;
    Encoding mEncoding;
    size_t mPos = 0;
};

/// A PLY header: its elements in file order, the body's encoding, and where the body starts.
struct PlyHeader {
    std::vector<PlyElement> elements;
    PlyBody::Encoding encoding = PlyBody::Encoding::Ascii;
    size_t bodyStart = 0;  ///< byte after the end_header line (may be past the file's end)
};

/// The encoding named on a PLY format line ("format ENCODING 1.0"), the header's line 2.
PlyBody::Encoding parsePlyFormat(const std::vector<std::string_view>& tokens,
                                 const std::string& path, const std::string& where) {
    auto fail = [&](const std::string& problem) { throw InputError(path, where, problem); };
    PlyBody::Encoding encoding = PlyBody::Encoding::Ascii;
    if (tokens.size() != 3 || tokens[0] != "format" || tokens[2] != "1.0") {
        fail("expected 'format ascii|binary_little_endian|binary_big_endian 1.0'");
    }
    if (tokens[1] == "ascii")
        encoding = PlyBody::Encoding::Ascii;
    else if (tokens[1] == "binary_little_endian")
        encoding = PlyBody::Encoding::LittleEndian;
    else if (tokens[1] == "binary_big_endian")
        encoding = PlyBody::Encoding::BigEndian;
    else
        fail("unknown PLY format '" + std::string(tokens[1]) + "'");
    return encoding;
}

/// A property line: "property TYPE NAME" or "property list TYPE TYPE NAME".
PlyProperty parsePlyProperty(const std::vector<std::string_view>& tokens, const std::string& path,
                             const std::string& where) {
    PlyProperty property;
    bool ok = false;
    if (tokens.size() == 5 && tokens[1] == "list") {
        property.isList = true;
        ok = parsePlyType(tokens[2], property.countType) &&
             parsePlyType(tokens[3], property.valueType);
        property.name = std::string(tokens[4]);
    } else if (tokens.size() == 3) {
        ok = parsePlyType(tokens[1], property.valueType);
        property.name = std::string(tokens[2]);
    }
    if (!ok) {
        throw InputError(path, where,
                         "expected 'property TYPE NAME' or 'property list TYPE TYPE NAME'");
    }
    return property;
}

/// Reads the header's lines up to end_header: "ply", the format line, then elements with
/// their properties (comments and obj_info skipped); any other line is an error.
PlyHeader readPlyHeader(const std::string& path, const std::string& bytes) {
    PlyHeader header;
    std::vector<PlyElement>& elements = header.elements;
    size_t pos = 0;
    size_t lineNumber = 0;
    bool ended = false;
    std::vector<std::string_view> tokens;
    while (!ended) {
        if (pos >= bytes.size()) throw InputError(path, "", "header has no end_header line");
        size_t end = bytes.find('\n', pos);
        if (end == std::string::npos) end = bytes.size();
        const std::string_view line(bytes.data() + pos, end - pos);
        pos = end + 1;
        ++lineNumber;
        const std::string where = "line " + std::to_string(lineNumber);
        splitTokens(line, tokens);
        auto fail = [&](const std::string& problem) { throw InputError(path, where, problem); };
        if (lineNumber == 1) {
            if (tokens.size() != 1 || tokens[0] != "ply") fail("expected 'ply'");
            continue;
        }
        if (lineNumber == 2) {
            header.encoding = parsePlyFormat(tokens, path, where);
            continue;
        }
        if (tokens.empty() || tokens[0] == "comment" || tokens[0] == "obj_info") continue;
        if (tokens[0] == "end_header" && tokens.size() == 1) {
            ended = true;
        } else if (tokens[0] == "element") {
            PlyElement element;
            if (tokens.size() != 3 || !parseCount(tokens[2], bytes.size(), element.count)) {
                fail("expected 'element NAME COUNT' with a count of at most the file size");
            }
            element.name = std::string(tokens[1]);
            elements.push_back(std::move(element));
        } else if (tokens[0] == "property") {
            if (elements.empty()) fail("property before any element");
            elements.back().properties.push_back(parsePlyProperty(tokens, path, where));
        } else {
            fail("unknown header line '" + std::string(tokens[0]) + "'");
        }
    }
    header.bodyStart = pos;
    return header;
}

/// Reads every instance of `element` from `body`: a vertex element's x, y, z become positions,
/// a face element's vertex_indices list becomes a face; other properties are read and dropped.
/// `face` is scratch space.
void readPlyElement(const std::string& path, const PlyElement& element, PlyBody& body,
                    PolygonSoup& soup, std::vector<int>& face) {
    const bool isVertex = element.name == "vertex";
    const bool isFace = element.name == "face";
    int axisOf[3] = {-1, -1, -1};
    int indicesProperty = -1;
    for (size_t p = 0; p < element.properties.size(); ++p) {
        const PlyProperty& property = element.properties[p];
        for (int axis = 0; axis < 3; ++axis) {
            if (isVertex && !property.isList && property.name == std::string(1, 'x' + axis)) {
                axisOf[axis] = static_cast<int>(p);
            }
        }
        if (isFace && property.isList &&
            (property.name == "vertex_indices" || property.name == "vertex_index")) {
            indicesProperty = static_cast<int>(p);
        }
    }
    if (isVertex && (axisOf[0] < 0 || axisOf[1] < 0 || axisOf[2] < 0)) {
        throw InputError(path, "", "vertex element lacks an x, y or z property");
    }
    if (isFace && indicesProperty < 0) {
        throw InputError(path, "", "face element lacks a vertex_indices list");
    }
    for (uint64_t i = 0; i < element.count; ++i) {
        const std::string what = element.name + " " + std::to_string(i);
        Vec3 position(0.0);
        face.clear();
        for (size_t p = 0; p < element.properties.size(); ++p) {
            const PlyProperty& property = element.properties[p];
            if (!property.isList) {
                const double value = body.read(property.valueType, what);
                for (int axis = 0; axis < 3; ++axis) {
                    if (axisOf[axis] == static_cast<int>(p)) position[axis] = value;
                }
                continue;
            }
            const double length = body.read(property.countType, what);
            if (!(length >= 0.0 && length <= static_cast<double>(body.remaining())) ||
                length != std::floor(length)) {
                throw InputError(path, what, "invalid list length");
            }
            for (size_t k = 0; k < static_cast<size_t>(length); ++k) {
                const double value = body.read(property.valueType, what);
                if (static_cast<int>(p) != indicesProperty) continue;
                if (!(value >= 0.0 && value <= std::numeric_limits<int>::max()) ||
                    value != std::floor(value)) {
                    throw InputError(path, what, "invalid vertex index " + formatNumber(value));
                }
                face.push_back(static_cast<int>(value));
            }
        }
        if (isVertex) soup.positions.push_back(position);
        if (isFace) soup.addFace(face.data(), face.size(), -1);
    }
}

PolygonSoup readPly(const std::string& path) {
    const std::string bytes = readFileBytes(path);
    const PlyHeader header = readPlyHeader(path, bytes);

    // Body: vertex x, y, z and face vertex_indices; other elements and properties skipped.
    PlyBody body(path, std::string_view(bytes).substr(std::min(header.bodyStart, bytes.size())),
                 header.encoding);
    PolygonSoup soup;
    std::vector<int> face;
    for (const PlyElement& element : header.elements) {
        if (element.properties.empty()) continue;  // occupies no bytes
        readPlyElement(path, element, body, soup, face);
    }
    return soup;
}

}  // namespace penumbra::mesh_io_detail
