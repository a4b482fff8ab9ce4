#include "render/image.h"

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <sstream>
#include <stdexcept>

// Debian's libstb already holds the stb implementations: include declarations only.
#include <stb_image.h>
#include <stb_image_write.h>
// Debian's libtinyexr is a shared library (CMake target tinyexr::tinyexr): declarations only.
#include <tinyexr.h>

#include "core/colour.h"
#include "core/durable_file.h"
#include "core/file_name.h"

namespace penumbra {

namespace {

/// The OpenEXR file of RGB `values` (width × height, interleaved) as tinyexr's SaveEXR
/// writes it: channels B, G, R as 32-bit floats, ZIP compressed (none when both sides are
/// under 16 pixels). Empty with `error` set when tinyexr fails.
std::string encodeExr(const std::vector<float>& values, int width, int height,
                      std::string& error) {
    const std::size_t n = static_cast<std::size_t>(width) * height;
    std::vector<float> planes[3];
    for (int c = 0; c < 3; ++c) {
        planes[c].resize(n);
        for (std::size_t i = 0; i < n; ++i) planes[c][i] = values[3 * i + c];
    }
    float* channels[3] = {planes[2].data(), planes[1].data(), planes[0].data()};  // B, G, R

    EXRImage exrImage;
    InitEXRImage(&exrImage);
    exrImage.num_channels = 3;
    exrImage.images = reinterpret_cast<unsigned char**>(channels);
    exrImage.width = width;
    exrImage.height = height;

    EXRHeader header;
    InitEXRHeader(&header);
    header.compression_type = width < 16 && height < 16 ? TINYEXR_COMPRESSIONTYPE_NONE
                                                        : TINYEXR_COMPRESSIONTYPE_ZIP;
    EXRChannelInfo info[3] = {};
    int pixelTypes[3], requestedTypes[3];
    for (int c = 0; c < 3; ++c) {
        info[c].name[0] = "BGR"[c];
        pixelTypes[c] = requestedTypes[c] = TINYEXR_PIXELTYPE_FLOAT;
    }
    header.num_channels = 3;
    header.channels = info;
    header.pixel_types = pixelTypes;
    header.requested_pixel_types = requestedTypes;

    unsigned char* memory = nullptr;
    const char* message = nullptr;
    const std::size_t size = SaveEXRImageToMemory(&exrImage, &header, &memory, &message);
    std::string bytes;
    if (size > 0 && memory) bytes.assign(reinterpret_cast<const char*>(memory), size);
    std::free(memory);
    if (bytes.empty()) {
        error = message ? message : "cannot encode";
        if (message) FreeEXRErrorMessage(message);
    }
    return bytes;
}

void checkImage(const Image& image, const std::string& path) {
    if (image.width <= 0 || image.height <= 0 ||
        image.pixels.size() != static_cast<size_t>(image.width) * image.height) {
        throw std::runtime_error("cannot write " + path + ": invalid image " + image.toString());
    }
}

}  // namespace

Image::Image(int w, int h, const Rgb& fill) : width(w), height(h) {
    if (w < 0 || h < 0) {
        throw std::invalid_argument("image size must not be negative: " + std::to_string(w) + "x" +
                                    std::to_string(h));
    }
    pixels.assign(static_cast<size_t>(w) * h, fill);
}

std::string Image::toString() const {
    std::ostringstream out;
    out << "Image{" << width << "x" << height << ", " << pixels.size() << " pixels}";
    return out.str();
}

void writePng(const Image& image, const std::string& path) {
    checkImage(image, path);

    // Encode to 8-bit sRGB, clipped.
    std::vector<std::uint8_t> bytes(static_cast<size_t>(image.width) * image.height * 3);
    for (size_t i = 0; i < image.pixels.size(); ++i) {
        const Rgb& p = image.pixels[i];
        bytes[3 * i + 0] = srgbByteExact(p.x);
        bytes[3 * i + 1] = srgbByteExact(p.y);
        bytes[3 * i + 2] = srgbByteExact(p.z);
    }

    writeFileAtomically(path, [&](std::ostream& out) {
        const auto append = [](void* context, void* data, int size) {
            static_cast<std::ostream*>(context)->write(static_cast<const char*>(data), size);
        };
        if (stbi_write_png_to_func(append, &out, image.width, image.height, 3, bytes.data(),
                                   image.width * 3) == 0)
            throw std::runtime_error("cannot write PNG " + path + ": encoding failed");
    });
}

void writeExr(const Image& image, const std::string& path) {
    checkImage(image, path);

    std::vector<float> values(static_cast<size_t>(image.width) * image.height * 3);
    for (size_t i = 0; i < image.pixels.size(); ++i) {
        values[3 * i + 0] = static_cast<float>(image.pixels[i].x);
        values[3 * i + 1] = static_cast<float>(image.pixels[i].y);
        values[3 * i + 2] = static_cast<float>(image.pixels[i].z);
    }

    std::string message;
    const std::string bytes = encodeExr(values, image.width, image.height, message);
    if (bytes.empty()) {
        // tinyexr messages may end in a newline; keep the report to one line.
        std::replace(message.begin(), message.end(), '\n', ' ');
        while (!message.empty() && message.back() == ' ') message.pop_back();
        throw std::runtime_error("cannot write EXR " + path + ": " + message);
    }
    writeFileAtomically(path, bytes);
}

void writeImage(const Image& image, const std::string& path) {
    const std::string ext = lowerExtension(path);
    if (ext == ".png") return writePng(image, path);
    if (ext == ".exr") return writeExr(image, path);
    throw std::invalid_argument("unsupported image extension '" + ext + "' for " + path +
                                " (expected .png or .exr)");
}

Image readPng(const std::string& path) {
    int width = 0, height = 0, channels = 0;
    stbi_uc* data = stbi_load(path.c_str(), &width, &height, &channels, 3);
    if (!data) {
        const char* reason = stbi_failure_reason();
        throw std::runtime_error("cannot read PNG " + path + ": " +
                                 (reason ? reason : "unknown error"));
    }

    // Decode sRGB bytes to linear values.
    double table[256];
    for (int i = 0; i < 256; ++i) table[i] = srgbDecode(i / 255.0);
    Image image(width, height);
    for (size_t i = 0; i < image.pixels.size(); ++i) {
        image.pixels[i] = Rgb(table[data[3 * i]], table[data[3 * i + 1]], table[data[3 * i + 2]]);
    }
    stbi_image_free(data);
    return image;
}

Image readExr(const std::string& path) {
    float* rgba = nullptr;
    int width = 0, height = 0;
    const char* err = nullptr;
    if (LoadEXR(&rgba, &width, &height, path.c_str(), &err) != TINYEXR_SUCCESS) {
        std::string reason = err ? err : "unknown error";
        if (err) FreeEXRErrorMessage(err);
        while (!reason.empty() && (reason.back() == '\n' || reason.back() == '\r'))
            reason.pop_back();
        throw std::runtime_error("cannot read EXR " + path + ": " + reason);
    }
    Image image(width, height);
    for (std::size_t i = 0; i < image.pixels.size(); ++i)
        image.pixels[i] = Rgb(rgba[4 * i], rgba[4 * i + 1], rgba[4 * i + 2]);
    std::free(rgba);
    return image;
}

}  // namespace penumbra
