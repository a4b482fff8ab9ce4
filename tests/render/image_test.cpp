// Image files: the sRGB transfer function against IEC 61966-2-1, PNG and EXR round trips.

#include "render/image.h"

#include <gtest/gtest.h>
#include <tinyexr.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <utility>

namespace penumbra {
namespace {

/// IEC 61966-2-1 §5.2 written out independently of the library.
double referenceEncode(double l) {
    return l <= 0.0031308 ? 12.92 * l : 1.055 * std::pow(l, 1.0 / 2.4) - 0.055;
}
double referenceDecode(double v) {
    return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
}

std::filesystem::path testDir() {
    auto dir = std::filesystem::temp_directory_path() /
               ("penumbra_image_test_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    return dir;
}

/// A deterministic gradient with values below, inside and above [0,1].
Image makeGradient(int w, int h) {
    Image image(w, h);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            image.at(x, y) =
                Rgb(x / double(w - 1), y / double(h - 1), 1.5 * (x + y) / double(w + h - 2) - 0.1);
        }
    }
    return image;
}

TEST(Srgb, EncodeMatchesTabulatedValues) {
    // Values of the piecewise formula computed offline (Python, double precision).
    const double table[][2] = {{0.0, 0.0},
                               {0.001, 0.01292},
                               {0.0031308, 0.040449936},
                               {0.01, 0.09985282273412832},
                               {0.18, 0.46135612950044164},
                               {0.5, 0.7353569830524495},
                               {0.9, 0.9546871718858662},
                               {1.0, 1.0}};
    for (const auto& row : table) {
        EXPECT_NEAR(srgbEncode(row[0]), row[1], 1e-12) << "linear " << row[0];
        EXPECT_NEAR(srgbDecode(row[1]), row[0], 1e-12) << "encoded " << row[1];
    }
}

TEST(Srgb, EncodeDecodeMatchReferenceFormula) {
    for (int i = 0; i <= 2000; ++i) {
        const double x = i / 2000.0;
        EXPECT_NEAR(srgbEncode(x), referenceEncode(x), 1e-14) << "linear " << x;
        EXPECT_NEAR(srgbDecode(x), referenceDecode(x), 1e-14) << "encoded " << x;
        EXPECT_NEAR(srgbDecode(srgbEncode(x)), x, 1e-12) << "round trip of " << x;
    }
    // The two branches meet at the breakpoint (continuity within 1e-7).
    EXPECT_NEAR(12.92 * 0.0031308, 1.055 * std::pow(0.0031308, 1 / 2.4) - 0.055, 1e-7);
    EXPECT_NEAR(srgbEncode(0.0031308 - 1e-12), srgbEncode(0.0031308 + 1e-12), 1e-7);
}

TEST(Png, RoundTripQuantizesSrgb) {
    const auto dir = testDir();
    const std::string path = (dir / "gradient.png").string();
    const Image image = makeGradient(37, 23);
    writePng(image, path);
    EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));

    const Image read = readPng(path);
    ASSERT_EQ(read.width, image.width);
    ASSERT_EQ(read.height, image.height);
    for (int y = 0; y < image.height; ++y) {
        for (int x = 0; x < image.width; ++x) {
            for (int c = 0; c < 3; ++c) {
                const double v = image.at(x, y)[c];
                // Expected: clip(encode(v)) rounded to 8 bits, decoded.
                const double encoded = std::min(1.0, std::max(0.0, referenceEncode(v)));
                const double expected = referenceDecode(std::round(encoded * 255.0) / 255.0);
                EXPECT_NEAR(read.at(x, y)[c], expected, 1e-9)
                    << "pixel (" << x << ", " << y << ") channel " << c << " value " << v;
            }
        }
    }
    std::filesystem::remove_all(dir);
}

TEST(Png, WriteImageChoosesByExtensionAndRejectsOthers) {
    const auto dir = testDir();
    const Image image(4, 3, Rgb(0.25));
    writeImage(image, (dir / "upper.PNG").string());
    EXPECT_EQ(readPng((dir / "upper.PNG").string()).width, 4);
    EXPECT_THROW(writeImage(image, (dir / "image.bmp").string()), std::invalid_argument);
    EXPECT_THROW(writePng(image, (dir / "missing" / "x.png").string()), std::runtime_error);
    EXPECT_THROW(readPng((dir / "absent.png").string()), std::runtime_error);
    std::filesystem::remove_all(dir);
}

TEST(Exr, WrittenFloatsReadBackExactly) {
    const auto dir = testDir();
    // Large enough that tinyexr compresses (it skips compression below 16x16).
    for (auto [w, h] : {std::pair{40, 30}, std::pair{5, 3}}) {
        const std::string path = (dir / ("gradient.exr")).string();
        Image image = makeGradient(w, h);
        image.at(0, 0) = Rgb(123.456, 1e-6, 0.0);  // HDR and tiny values survive
        writeImage(image, path);

        float* rgba = nullptr;
        int width = 0, height = 0;
        const char* error = nullptr;
        ASSERT_EQ(LoadEXR(&rgba, &width, &height, path.c_str(), &error), TINYEXR_SUCCESS)
            << (error ? error : "");
        ASSERT_EQ(width, w);
        ASSERT_EQ(height, h);
        for (int y = 0; y < h; ++y) {
            for (int x = 0; x < w; ++x) {
                const float* p = rgba + 4 * (static_cast<size_t>(y) * w + x);
                for (int c = 0; c < 3; ++c) {
                    EXPECT_EQ(p[c], static_cast<float>(image.at(x, y)[c]))
                        << "pixel (" << x << ", " << y << ") channel " << c;
                }
            }
        }
        free(rgba);
    }
    std::filesystem::remove_all(dir);
}

TEST(ImageType, RejectsInvalidImages) {
    EXPECT_THROW(Image(-1, 2), std::invalid_argument);
    const Image empty;
    EXPECT_THROW(writePng(empty, "/tmp/never_written.png"), std::runtime_error);
    Image broken(2, 2);
    broken.pixels.pop_back();
    EXPECT_THROW(writeExr(broken, "/tmp/never_written.exr"), std::runtime_error);
    EXPECT_EQ(Image(3, 2).toString(), "Image{3x2, 6 pixels}");
}

}  // namespace
}  // namespace penumbra
