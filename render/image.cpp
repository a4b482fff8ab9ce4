#include "render/image.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <stdexcept>
#include <system_error>

// Debian's libstb already holds the stb implementations: include declarations only.
#include <stb_image.h>
#include <stb_image_write.h>
// Debian's libtinyexr is a shared library (CMake target tinyexr::tinyexr): declarations only.
#include <tinyexr.h>

namespace penumbra {

namespace {

/// A temporary name next to `path`, so the final rename stays on one filesystem.
std::string temporaryPathFor(const std::string& path) { return path + ".tmp"; }

/// Moves a finished temporary file over `path`; removes it and throws on failure.
void commitTemporary(const std::string& temporary, const std::string& path) {
    std::error_code error;
    std::filesystem::rename(temporary, path, error);
    if (error) {
        std::filesystem::remove(temporary, error);
        throw std::runtime_error("cannot rename " + temporary + " to " + path + ": " +
                                 error.message());
    }
}

void discardTemporary(const std::string& temporary) {
    std::error_code ignored;
    std::filesystem::remove(temporary, ignored);
}

void checkImage(const Image& image, const std::string& path) {
    if (image.width <= 0 || image.height <= 0 ||
        image.pixels.size() != static_cast<size_t>(image.width) * image.height) {
        throw std::runtime_error("cannot write " + path + ": invalid image " + image.toString());
    }
}

std::uint8_t encodeByte(double linear) {
    double v = srgbEncode(linear);
    if (!(v > 0.0)) return 0;  // also NaN
    if (v >= 1.0) return 255;
    return static_cast<std::uint8_t>(std::lround(v * 255.0));
}

std::string lowerExtension(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return ext;
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
        bytes[3 * i + 0] = encodeByte(p.x);
        bytes[3 * i + 1] = encodeByte(p.y);
        bytes[3 * i + 2] = encodeByte(p.z);
    }

    const std::string temporary = temporaryPathFor(path);
    if (stbi_write_png(temporary.c_str(), image.width, image.height, 3, bytes.data(),
                       image.width * 3) == 0) {
        discardTemporary(temporary);
        throw std::runtime_error("cannot write PNG " + path);
    }
    commitTemporary(temporary, path);
}

void writeExr(const Image& image, const std::string& path) {
    checkImage(image, path);

    std::vector<float> values(static_cast<size_t>(image.width) * image.height * 3);
    for (size_t i = 0; i < image.pixels.size(); ++i) {
        values[3 * i + 0] = static_cast<float>(image.pixels[i].x);
        values[3 * i + 1] = static_cast<float>(image.pixels[i].y);
        values[3 * i + 2] = static_cast<float>(image.pixels[i].z);
    }

    const std::string temporary = temporaryPathFor(path);
    const char* error = nullptr;
    int status = SaveEXR(values.data(), image.width, image.height, 3, /*save_as_fp16=*/0,
                         temporary.c_str(), &error);
    if (status != TINYEXR_SUCCESS) {
        std::string message = error ? error : "error " + std::to_string(status);
        if (error) FreeEXRErrorMessage(error);
        // tinyexr messages may end in a newline; keep the report to one line.
        std::replace(message.begin(), message.end(), '\n', ' ');
        while (!message.empty() && message.back() == ' ') message.pop_back();
        discardTemporary(temporary);
        throw std::runtime_error("cannot write EXR " + path + ": " + message);
    }
    commitTemporary(temporary, path);
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
