#pragma once
// Linear RGB images and their files: PNG (sRGB-encoded, clipped, 8-bit) through stb and
// EXR (linear 32-bit float) through tinyexr. See DESIGN.md "Images".
//
// Index: Image · writing · reading (the sRGB transfer function: core/colour.h)

#include <cstdint>
#include <string>
#include <vector>

#include "core/colour.h"
#include "solver/scene.h"

namespace penumbra {

/// A linear RGB image, row-major, top row first. For renders the unit is radiance
/// (W/m²/sr = radiosity/π).
struct Image {
    int width = 0;
    int height = 0;
    std::vector<Rgb> pixels;  ///< width·height values; pixel (x, y) at y·width + x

    Image() = default;
    /// A width × height image filled with `fill`. Throws std::invalid_argument for negative
    /// sizes.
    Image(int width, int height, const Rgb& fill = Rgb(0.0));

    Rgb& at(int x, int y) { return pixels[static_cast<size_t>(y) * width + x]; }
    const Rgb& at(int x, int y) const { return pixels[static_cast<size_t>(y) * width + x]; }
    std::string toString() const;
};

/// Writes 8-bit RGB PNG: each channel sRGB-encoded, clipped to [0,1] (NaN → 0) and rounded.
/// Written with writeFileAtomically (core/durable_file.h). Throws std::runtime_error (InputError
/// when the file cannot be written) with a one-line message naming the file on failure.
void writePng(const Image& image, const std::string& path);

/// Writes the linear values as a 32-bit float RGB OpenEXR file (tinyexr; ZIP compressed
/// except for tiny images), encoded in memory and written with writeFileAtomically; throws
/// std::runtime_error as writePng.
void writeExr(const Image& image, const std::string& path);

/// Writes by extension (case-insensitive): `.png` → writePng, `.exr` → writeExr.
/// Throws std::invalid_argument naming the extension when it is neither.
void writeImage(const Image& image, const std::string& path);

/// Reads an 8-bit PNG (any channel count; grey is replicated, alpha is dropped) and returns
/// linear values (sRGB-decoded). Throws std::runtime_error naming the file on failure.
Image readPng(const std::string& path);

/// Reads an OpenEXR file's RGB as linear values (tinyexr). Throws std::runtime_error naming
/// the file on failure.
Image readExr(const std::string& path);

}  // namespace penumbra
