// The edge-and-point image's reconstruction (Bala, Walter, Greenberg 2003 §5.3–5.4), from the
// points, edges and pixel classes edge_point_image.cpp builds; see edge_point_image.h.
//
// Index: interpolation (§5.3) · anti-aliasing (§5.3) · complex filter (§5.4) · dense complex
// regions · reconstruct · edge-free smoothing · own points · classification image

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

#include "core/timing.h"
#include "render/display/edge_point_image.h"
#include "render/display/edge_point_image_internal.h"

namespace penumbra {

using namespace epi_detail;

// ---- Interpolation (§5.3) -----------------------------------------------------------------

void EdgePointImage::interpolatePlain() {
    // The render cache's interpolation: the same separable filter over every point of the
    // 5×5 neighbourhood, ignoring edges, in two 1D passes over the padded points.
    const float g1 = kFilter[1];
    const float g2 = kFilter[2];
    forRows(mOptions.parallel, mHeight + 4, [&](int py) {
        const glm::vec4* row = &mPaddedAll[static_cast<size_t>(py) * (mWidth + 4) + 2];
        glm::vec4* out = &mRowSums[static_cast<size_t>(py) * mWidth];
        for (int x = 0; x < mWidth; ++x) {
            const Quad sum = addQuad(
                loadQuad(row[x]),
                addQuad(scaleQuad(addQuad(loadQuad(row[x - 1]), loadQuad(row[x + 1])), g1),
                        scaleQuad(addQuad(loadQuad(row[x - 2]), loadQuad(row[x + 2])), g2)));
            storeQuad(out[x], sum);
        }
    });
    forRows(mOptions.parallel, mHeight, [&](int y) {
        const glm::vec4* r = &mRowSums[static_cast<size_t>(y + 2) * mWidth];
        const ptrdiff_t stride = mWidth;
        for (int x = 0; x < mWidth; ++x) {
            const glm::vec4 sum = toVec4(addQuad(
                loadQuad(r[x]),
                addQuad(scaleQuad(addQuad(loadQuad(r[x - stride]), loadQuad(r[x + stride])), g1),
                        scaleQuad(addQuad(loadQuad(r[x - 2 * stride]), loadQuad(r[x + 2 * stride])),
                                  g2))));
            const size_t i = index(x, y);
            mPlainWeight[i] = sum.w;
            mPlain[i] = sum.w > 0.0f ? glm::vec3(sum) / sum.w : glm::vec3(0.0f);
        }
    });
}

void EdgePointImage::interpolatePrimary(Image& out) {
    // Padded-index offsets and filter weights of the 24 mask bits.
    std::array<ptrdiff_t, 24> offset;
    std::array<float, 24> weight;
    for (int k = 0; k < 24; ++k) {
        const int dx = kBitCell[k] % 5 - 2;
        const int dy = kBitCell[k] / 5 - 2;
        offset[k] = static_cast<ptrdiff_t>(dy) * (mWidth + 4) + dx;
        weight[k] = filterWeight(dx, dy);
    }
    forRows(mOptions.parallel, mHeight, [&](int y) {
        for (int x = 0; x < mWidth; ++x) {
            const size_t i = index(x, y);
            const uint32_t reach = mReach[i];
            glm::vec3 colour;
            float total;
            if ((reach & kAllEmptyFlag) || mEdgeCode[i] == kEdgeCodeComplex) {
                // No edge within 5×5 (the plain result is exact), or a complex pixel, whose
                // first estimate ignores reachability (§5.4).
                colour = mPlain[i];
                total = mPlainWeight[i];
            } else {
                // Renormalized filter over the reachable samples (§5.3).
                const glm::vec4* centre = &mPaddedUsable[paddedIndex(x, y)];
                Quad acc = loadQuad(centre[0]);
                for (uint32_t bits = reach; bits; bits &= bits - 1) {
                    const int k = std::countr_zero(bits);
                    acc = addQuad(acc, scaleQuad(loadQuad(centre[offset[k]]), weight[k]));
                }
                const glm::vec4 sum = toVec4(acc);
                total = sum.w;
                colour = total > 0.0f ? glm::vec3(sum) / total : glm::vec3(0.0f);
            }
            mWeight[i] = total;
            mPrimary[i] = colour;
            out.at(x, y) = Rgb(colour);
        }
    });
    // Pixels near edges with samples in their 5×5 neighbourhood, none of them reachable,
    // take the filtered primary colours of the reachable pixels that have one (one more ring
    // of reach, still edge-respecting); failing that, the plain estimate. (Pixels with no
    // sample within 5×5 at all stay black, as in the render cache's interpolation.) Only
    // zero-weight pixels are written and only positive-weight pixels read, so rows can run in
    // parallel.
    forRows(mOptions.parallel, mHeight, [&](int y) {
        for (int x = 0; x < mWidth; ++x) {
            const size_t i = index(x, y);
            const uint32_t reach = mReach[i];
            if (mWeight[i] > 0.0f || mPlainWeight[i] == 0.0f || (reach & kAllEmptyFlag) ||
                mEdgeCode[i] == kEdgeCodeComplex) {
                continue;
            }
            glm::vec3 sum(0.0f);
            float total = 0.0f;
            for (uint32_t bits = reach; bits; bits &= bits - 1) {
                const int k = std::countr_zero(bits);
                const int px = x + kBitCell[k] % 5 - 2;
                const int py = y + kBitCell[k] / 5 - 2;
                if (px < 0 || py < 0 || px >= mWidth || py >= mHeight) continue;
                const size_t j = index(px, py);
                if (!(mWeight[j] > 0.0f)) continue;
                sum += weight[k] * mPrimary[j];
                total += weight[k];
            }
            mPrimary[i] = total > 0.0f ? sum / total : mPlain[i];
            out.at(x, y) = Rgb(mPrimary[i]);
        }
    });
}

// ---- Anti-aliasing (§5.3) -----------------------------------------------------------------

void EdgePointImage::antiAlias(Image& out) const {
    const EdgeCodeTables& tables = EdgeCodeTables::pixel();
    forRows(mOptions.parallel, mHeight, [&](int y) {
        for (int x = 0; x < mWidth; ++x) {
            const size_t i = index(x, y);
            const uint16_t code = mEdgeCode[i];
            if (code == kEdgeCodeEmpty || code == kEdgeCodeComplex) continue;
            // Area-weighted primary and secondary colours; the secondary colour is the
            // primary colour of the edge-indexed neighbour, the first whose primary region
            // the secondary region reaches.
            const int secondary = (mNeighbourCode[i] & kNeighbourPrimaryIsRegion1) ? 0 : 1;
            const float area0 = tables.region0Area[code];
            const float secondaryArea = secondary == 0 ? area0 : 1.0f - area0;
            const auto& choice =
                tables.antiAliasNeighbours[static_cast<size_t>(code) * 2 + secondary];
            for (int k = 0; k < choice.count; ++k) {
                const int dx = choice.dx[k];
                const int dy = choice.dy[k];
                const int px = x + dx;
                const int py = y + dy;
                if (px < 0 || py < 0 || px >= mWidth || py >= mHeight) continue;
                if (!(mSecondaryReach[i] & (1u << ringBit(dx, dy)))) continue;
                const glm::vec3 c =
                    (1.0f - secondaryArea) * mPrimary[i] + secondaryArea * mPrimary[index(px, py)];
                out.at(x, y) = Rgb(c);
                break;
            }
        }
    });
}

// ---- Complex filter (§5.4) ----------------------------------------------------------------

namespace {

/// §5.4 region adjacency of subpixel neighbour types, to the right (0) and below (1):
/// [direction][type · 8 + neighbour's type].
const std::array<std::array<uint8_t, 64>, 2>& subpixelAdjacency() {
    static const auto adjacency = [] {
        std::array<std::array<uint8_t, 64>, 2> t{};
        for (int d = 0; d < 2; ++d) {
            for (int k = 0; k < 64; ++k) {
                t[d][k] = regionAdjacency(static_cast<NeighbourDirection>(d),
                                          static_cast<uint8_t>(k / 8), static_cast<uint8_t>(k % 8));
            }
        }
        return t;
    }();
    return adjacency;
}

/// §5.4 neighbour type of each subpixel edge code.
const std::array<uint8_t, kEdgeCodeCount>& subpixelTypes() {
    static const std::array<uint8_t, kEdgeCodeCount> subpixelType = [] {
        std::array<uint8_t, kEdgeCodeCount> t{};
        for (int code = 0; code < kEdgeCodeCount; ++code)
            t[code] = neighbourType(static_cast<uint16_t>(code), kSubpixelPiecesPerSide);
        return t;
    }();
    return subpixelType;
}

}  // namespace

/// §5.4 working state of one complex pixel: the subpixel edge codes and types over the 6×6
/// subpixels of its 3×3 pixel neighbourhood, the adjacency of their regions, the connected
/// regions found so far, and the points of the 3×3 pixels placed in their subpixel regions
/// (node = subpixel · 2 + region).
struct EdgePointImage::ComplexNeighbourhood {
    std::array<uint16_t, 36> codes;
    std::array<uint8_t, 36> types;
    /// edges[dir][ra][rb] has bit a set when region ra of subpixel a meets region rb of its
    /// neighbour to the right (dir 0, a + 1) or below (dir 1, a + 6).
    uint64_t edges[2][2][2] = {};
    std::array<int8_t, 72> label;
    std::array<std::array<uint64_t, 2>, 8> component;
    int labels = 0;
    struct SubSample {
        int node, u, v;
        glm::vec3 colour;
    };
    std::array<SubSample, 9> samples;
    int sampleCount = 0;

    /// The region adjacency `edges` from the subpixel types, and no component labelled yet.
    void connectRegions() {
        // Branch-free: adjacency bit 2·ra + rb selects edges[dir][ra][rb].
        const std::array<std::array<uint8_t, 64>, 2>& adjacency = subpixelAdjacency();
        auto addEdges = [this](int dir, unsigned m, int a) {
            const uint64_t bit = uint64_t(1) << a;
            edges[dir][0][0] |= bit & (uint64_t(0) - (m & 1u));
            edges[dir][0][1] |= bit & (uint64_t(0) - ((m >> 1) & 1u));
            edges[dir][1][0] |= bit & (uint64_t(0) - ((m >> 2) & 1u));
            edges[dir][1][1] |= bit & (uint64_t(0) - ((m >> 3) & 1u));
        };
        for (int v = 0; v < 6; ++v) {
            for (int u = 0; u < 6; ++u) {
                const int a = v * 6 + u;
                if (u + 1 < 6) addEdges(0, adjacency[0][types[a] * 8 + types[a + 1]], a);
                if (v + 1 < 6) addEdges(1, adjacency[1][types[a] * 8 + types[a + 6]], a);
            }
        }
        label.fill(-1);
    }

    /// The label of the connected region holding `node`, flood-filled bit-parallel on first
    /// demand (only the labels' equality matters).
    int find(int node) {
        if (label[node] >= 0) return label[node];
        uint64_t c[2] = {0, 0};
        c[node & 1] = uint64_t(1) << (node >> 1);
        for (;;) {
            const uint64_t c0 = c[0], c1 = c[1];
            for (int ra = 0; ra < 2; ++ra) {
                for (int rb = 0; rb < 2; ++rb) {
                    c[rb] |= (c[ra] & edges[0][ra][rb]) << 1;
                    c[ra] |= (c[rb] >> 1) & edges[0][ra][rb];
                    c[rb] |= (c[ra] & edges[1][ra][rb]) << 6;
                    c[ra] |= (c[rb] >> 6) & edges[1][ra][rb];
                }
            }
            if (c[0] == c0 && c[1] == c1) break;
        }
        const int8_t id = static_cast<int8_t>(labels++);
        component[id] = {c[0], c[1]};
        for (int r = 0; r < 2; ++r)
            for (uint64_t m = c[r]; m; m &= m - 1) label[std::countr_zero(m) * 2 + r] = id;
        return id;
    }

    /// The pixel's value: each region of its own 4 subpixels coloured from the samples it
    /// reaches, area-weighted; complex or unreached regions keep the estimate.
    glm::vec3 colourOwnRegions(const EdgeCodeTables& sub, const glm::vec3& estimate) {
        glm::vec3 total(0.0f);
        for (int v = 2; v < 4; ++v) {
            for (int u = 2; u < 4; ++u) {
                const int s = v * 6 + u;
                const uint8_t type = types[s];
                if (type == kNeighbourTypeComplex) {
                    total += 0.25f * estimate;
                    continue;
                }
                const int regions = type == kNeighbourTypeEmpty ? 1 : 2;
                for (int r = 0; r < regions; ++r) {
                    const float area0 = sub.region0Area[codes[s]];
                    const float area = regions == 1 ? 1.0f : (r == 0 ? area0 : 1.0f - area0);
                    const std::array<uint64_t, 2>& reached = component[find(s * 2 + r)];
                    glm::vec3 sum(0.0f);
                    float weight = 0.0f;
                    for (int k = 0; k < sampleCount; ++k) {
                        const int node = samples[k].node;
                        if (!((reached[node & 1] >> (node >> 1)) & 1)) continue;
                        const float w = filterWeight(samples[k].u - u, samples[k].v - v);
                        sum += w * samples[k].colour;
                        weight += w;
                    }
                    total += 0.25f * area * (weight > 0.0f ? sum / weight : estimate);
                }
            }
        }
        return total;
    }
};

std::vector<size_t> EdgePointImage::listComplexPixels() {
    // The complex pixels in pixel order, rows in parallel at offsets from the per-row counts.
    const int W = mWidth;
    const int H = mHeight;
    std::vector<int>& complexPixels = mComplexPixels;
    std::vector<size_t> rowStart(static_cast<size_t>(H) + 1, 0);
    for (int y = 0; y < H; ++y) rowStart[y + 1] = rowStart[y] + mRowCounts[y][2];
    complexPixels.resize(rowStart[H]);
    forRows(mOptions.parallel, H, [&](int y) {
        size_t k = rowStart[y];
        if (k == rowStart[y + 1]) return;
        for (int x = 0; x < W; ++x)
            if (mEdgeCode[index(x, y)] == kEdgeCodeComplex)
                complexPixels[k++] = static_cast<int>(index(x, y));
    });
    return rowStart;
}

void EdgePointImage::keepDenseComplexEstimates(const std::vector<size_t>& rowStart, Image& out) {
    // Complex pixels in dense clusters keep their estimate now and leave the list; the others
    // are marked in mFiltered (complex pixels only) so that subpixel codes are computed around
    // them alone. (Within a dense cluster the subpixel regions reach few usable samples, those
    // in complex subpixels being skipped, and came out noisier than the estimate, the render
    // cache's reconstruction: §7.5.)
    const int W = mWidth;
    const int H = mHeight;
    std::vector<int>& complexPixels = mComplexPixels;
    mFiltered.assign(static_cast<size_t>(W) * H, 0);
    forRows(mOptions.parallel, H, [&](int y) {
        for (size_t k = rowStart[y]; k < rowStart[y + 1]; ++k) {
            const int pixel = complexPixels[k];
            if (mDense[pixel]) {
                out.at(pixel % W, y) = Rgb(mPrimary[pixel]);
            } else {
                mFiltered[pixel] = 1;
            }
        }
    });
    complexPixels.erase(std::remove_if(complexPixels.begin(), complexPixels.end(),
                                       [&](int pixel) { return !mFiltered[pixel]; }),
                        complexPixels.end());
}

void EdgePointImage::computeSubpixelCodes(bool dense) {
    const int W = mWidth;
    const int H = mHeight;
    // 4 bits of a boundary line at twice-pixel coordinate k2 (even: pixel boundary, odd:
    // half-pixel line) over the half of pixel segment `cell` selected by `half`.
    auto horizontalBits = [&](int k2, int column, int half) -> unsigned {
        const uint8_t m = (k2 & 1) == 0 ? mHorizontal[static_cast<size_t>(k2 / 2) * W + column]
                                        : mHorizontalMid[static_cast<size_t>(k2 / 2) * W + column];
        return (m >> (4 * half)) & 15u;
    };
    auto verticalBits = [&](int k2, int row, int half) -> unsigned {
        const uint8_t m = (k2 & 1) == 0 ? mVertical[static_cast<size_t>(row) * (W + 1) + k2 / 2]
                                        : mVerticalMid[static_cast<size_t>(row) * W + k2 / 2];
        return (m >> (4 * half)) & 15u;
    };

    const std::array<uint8_t, kEdgeCodeCount>& subpixelType = subpixelTypes();
    // Subpixel edge codes of every pixel in some complex pixel's 3×3 neighbourhood, once
    // (complex pixels cluster along dense edges, so neighbourhoods overlap): subpixel
    // (sx, sy) of pixel (px, py) lies between lines 2·px + sx, 2·px + sx + 1 (x) and
    // 2·py + sy, 2·py + sy + 1 (y) on the half-pixel grid.
    forRows(mOptions.parallel, H, [&](int py) {
        const int y0 = std::max(0, py - 1), y1 = std::min(H - 1, py + 1);
        bool anyComplex = false;
        for (int y = y0; y <= y1; ++y) anyComplex |= mRowCounts[y][2] > 0;
        if (!anyComplex) return;
        // Whether column x of rows y0..y1 holds a complex pixel to filter.
        auto columnComplex = [&](int x) {
            if (x < 0 || x >= W) return false;
            for (int y = y0; y <= y1; ++y)
                if (dense ? mFiltered[index(x, y)] != 0
                          : mEdgeCode[index(x, y)] == kEdgeCodeComplex)
                    return true;
            return false;
        };
        bool left = false, centre = columnComplex(0);
        for (int px = 0; px < W; ++px) {
            const bool right = columnComplex(px + 1);
            const bool marked = left || centre || right;
            left = centre;
            centre = right;
            if (!marked) continue;
            const size_t i = index(px, py);
            for (int sy = 0; sy < 2; ++sy) {
                for (int sx = 0; sx < 2; ++sx) {
                    const int k2y = 2 * py + sy;
                    const int k2x = 2 * px + sx;
                    const uint16_t code =
                        codeFromMasks(horizontalBits(k2y, px, sx), verticalBits(k2x + 1, py, sy),
                                      horizontalBits(k2y + 1, px, sx), verticalBits(k2x, py, sy),
                                      kSubpixelPiecesPerSide);
                    mSubCode[4 * i + 2 * sy + sx] = code;
                    mSubType[4 * i + 2 * sy + sx] = subpixelType[code];
                }
            }
        }
    });
}

bool EdgePointImage::filterSampleFreeComplexPixel(int pixel, Image& out) const {
    // No sample in the 3×3 neighbourhood: every region keeps the estimate; the same sums in
    // the same order as the general filter's (ComplexNeighbourhood::colourOwnRegions).
    const EdgeCodeTables& sub = EdgeCodeTables::subpixel();
    const int W = mWidth;
    const int H = mHeight;
    const int cx = pixel % W, cy = pixel / W;
    bool anySample = false;
    for (int py = std::max(0, cy - 1); py <= std::min(H - 1, cy + 1); ++py)
        for (int px = std::max(0, cx - 1); px <= std::min(W - 1, cx + 1); ++px)
            anySample |= mSamplePos[index(px, py)] != 0xFF;
    if (anySample) return false;
    const glm::vec3 estimate = mPrimary[pixel];
    glm::vec3 total(0.0f);
    for (int s = 0; s < 4; ++s) {
        const uint8_t type = mSubType[4 * static_cast<size_t>(pixel) + s];
        if (type == kNeighbourTypeComplex) {
            total += 0.25f * estimate;
            continue;
        }
        const int regions = type == kNeighbourTypeEmpty ? 1 : 2;
        const float area0 = sub.region0Area[mSubCode[4 * static_cast<size_t>(pixel) + s]];
        for (int r = 0; r < regions; ++r) {
            const float area = regions == 1 ? 1.0f : (r == 0 ? area0 : 1.0f - area0);
            total += 0.25f * area * estimate;
        }
    }
    out.at(cx, cy) = Rgb(total);
    return true;
}

void EdgePointImage::gatherSubpixelCodes(int x, int y, ComplexNeighbourhood& nb) const {
    // Subpixel edge codes over the 6×6 subpixels of the 3×3 pixel neighbourhood (outside the
    // image: complex).
    const int W = mWidth;
    const int H = mHeight;
    for (int v = 0; v < 6; ++v) {
        for (int u = 0; u < 6; ++u) {
            const int px = x - 1 + u / 2;
            const int py = y - 1 + v / 2;
            uint16_t code = kEdgeCodeComplex;
            uint8_t type = kNeighbourTypeComplex;
            if (px >= 0 && py >= 0 && px < W && py < H) {
                const size_t s = 4 * index(px, py) + 2 * (v & 1) + (u & 1);
                code = mSubCode[s];
                type = mSubType[s];
            }
            nb.codes[v * 6 + u] = code;
            nb.types[v * 6 + u] = type;
        }
    }
}

void EdgePointImage::gatherSubpixelSamples(int x, int y, ComplexNeighbourhood& nb) const {
    // Samples of the 3×3 pixels placed in their subpixel regions (node = subpixel · 2 +
    // region); those in complex subpixels or on an ambiguous side are skipped.
    const EdgeCodeTables& sub = EdgeCodeTables::subpixel();
    const int W = mWidth;
    const int H = mHeight;
    for (int py = y - 1; py <= y + 1; ++py) {
        for (int px = x - 1; px <= x + 1; ++px) {
            if (px < 0 || py < 0 || px >= W || py >= H) continue;
            const uint8_t pos = mSamplePos[index(px, py)];
            if (pos == 0xFF) continue;
            const int sx = pos & 3;
            const int sy = pos >> 2;
            const int u = 2 * (px - x + 1) + sx / 2;
            const int v = 2 * (py - y + 1) + sy / 2;
            const uint8_t type = nb.types[v * 6 + u];
            if (type == kNeighbourTypeComplex) continue;
            int region = 0;
            if (type != kNeighbourTypeEmpty) {
                const SampleSide side = sub.side(nb.codes[v * 6 + u], (sx & 1) + 2 * (sy & 1));
                if (side == SampleSide::Ambiguous) continue;
                region = side == SampleSide::Region1 ? 1 : 0;
            }
            nb.samples[nb.sampleCount++] = {(v * 6 + u) * 2 + region, u, v,
                                            mSampleColour[index(px, py)]};
        }
    }
}

void EdgePointImage::filterComplexPixel(int pixel, Image& out) const {
    if (mOptions.complexFilterShortcut && filterSampleFreeComplexPixel(pixel, out)) return;
    const int x = pixel % mWidth;
    const int y = pixel / mWidth;
    const glm::vec3 estimate = mPrimary[pixel];
    // All 4 own subpixels complex (common inside dense geometry): the pixel keeps its
    // estimate, summed as colourOwnRegions sums it.
    const uint8_t* own = &mSubType[4 * static_cast<size_t>(pixel)];
    if (own[0] == kNeighbourTypeComplex && own[1] == kNeighbourTypeComplex &&
        own[2] == kNeighbourTypeComplex && own[3] == kNeighbourTypeComplex) {
        glm::vec3 total(0.0f);
        for (int s = 0; s < 4; ++s) total += 0.25f * estimate;
        out.at(x, y) = Rgb(total);
        return;
    }
    // Connected subpixel regions by bit-parallel flood fill. Only the components of the
    // pixel's own 4 subpixels' regions are needed: they are flood-filled on demand (at most
    // 8, usually 2–4), and a sample counts for a region when its node lies in the region's
    // component.
    ComplexNeighbourhood nb;
    gatherSubpixelCodes(x, y, nb);
    nb.connectRegions();
    gatherSubpixelSamples(x, y, nb);
    out.at(x, y) = Rgb(nb.colourOwnRegions(EdgeCodeTables::subpixel(), estimate));
}

void EdgePointImage::filterComplexPixels(Image& out) {
    const std::vector<size_t> rowStart = listComplexPixels();
    // EpiOptions::denseComplexLimit: complex pixels in dense clusters keep their estimate.
    const bool dense = mOptions.denseComplexLimit > 0;
    if (dense) keepDenseComplexEstimates(rowStart, out);
    computeSubpixelCodes(dense);
    const std::vector<int>& complexPixels = mComplexPixels;
    if (!mOptions.parallel) {
        for (int pixel : complexPixels) filterComplexPixel(pixel, out);
        return;
    }
    tbb::parallel_for(tbb::blocked_range<size_t>(0, complexPixels.size(), 16),
                      [&](const tbb::blocked_range<size_t>& range) {
                          for (size_t n = range.begin(); n < range.end(); ++n)
                              filterComplexPixel(complexPixels[n], out);
                      });
}

// ---- Dense complex regions ---------------------------------------------------------------

void EdgePointImage::markDenseComplex() {
    // EpiOptions::denseComplexLimit: the pixels, of any class, with at least that many complex
    // pixels in their 3×3 (itself included), from per-row sums of three. The complex filter
    // leaves such complex pixels to their estimate, and the smoothing's dense regions
    // (denseRadius) take their box means.
    const size_t n = static_cast<size_t>(mWidth) * mHeight;
    mComplexRow.resize(n);
    mDense.resize(n);
    forRows(mOptions.parallel, mHeight, [&](int y) {
        uint8_t* row = &mComplexRow[static_cast<size_t>(y) * mWidth];
        if (mRowCounts[y][2] == 0) {
            std::fill_n(row, mWidth, uint8_t{0});
            return;
        }
        const uint16_t* codes = &mEdgeCode[static_cast<size_t>(y) * mWidth];
        for (int x = 0; x < mWidth; ++x) {
            int c = codes[x] == kEdgeCodeComplex;
            if (x > 0) c += codes[x - 1] == kEdgeCodeComplex;
            if (x + 1 < mWidth) c += codes[x + 1] == kEdgeCodeComplex;
            row[x] = static_cast<uint8_t>(c);
        }
    });
    forRows(mOptions.parallel, mHeight, [&](int y) {
        uint8_t* __restrict mask = &mDense[static_cast<size_t>(y) * mWidth];
        const int y0 = std::max(0, y - 1), y1 = std::min(mHeight - 1, y + 1);
        bool any = false;
        for (int yy = y0; yy <= y1; ++yy) any = any || mRowCounts[yy][2] > 0;
        if (!any) {
            std::fill_n(mask, mWidth, uint8_t{0});
            return;
        }
        const int W = mWidth, limit = mOptions.denseComplexLimit;
        const uint8_t* __restrict r0 = &mComplexRow[static_cast<size_t>(y0) * W];
        const uint8_t* __restrict r1 = &mComplexRow[static_cast<size_t>(y) * W];
        const uint8_t* __restrict r2 = &mComplexRow[static_cast<size_t>(y1) * W];
        const int rows = y1 - y0 + 1;  // 3 inside the image, fewer at its borders
        for (int x = 0; x < W; ++x) {
            const int c = r0[x] + (rows >= 2 ? r2[x] : 0) + (rows == 3 ? r1[x] : 0);
            mask[x] = c >= limit;
        }
    });
}

// ---- Reconstruct --------------------------------------------------------------------------

Image EdgePointImage::reconstruct(bool useEdges) {
    mTimes.reachabilityMs = mTimes.interpolateMs = mTimes.antiAliasMs = 0.0;
    mTimes.complexFilterMs = mTimes.smoothMs = 0.0;
    Image out(mWidth, mHeight);

    // The smoothing passes mark the pixels they give a value (1), markHoles the rest.
    mHole.assign(static_cast<size_t>(mWidth) * mHeight, 0);
    if (!useEdges) {
        auto start = std::chrono::steady_clock::now();
        interpolatePlain();
        mWeight = mPlainWeight;
        std::fill(mReach.begin(), mReach.end(), kAllNeighbours | kAllEmptyFlag);
        forRows(mOptions.parallel, mHeight, [&](int y) {
            for (int x = 0; x < mWidth; ++x) out.at(x, y) = Rgb(mPlain[index(x, y)]);
        });
        mTimes.interpolateMs = msSince(start);
        markHoles(false);
        return out;
    }

    auto start = std::chrono::steady_clock::now();
    computeReachabilityMap();
    mTimes.reachabilityMs = msSince(start);

    start = std::chrono::steady_clock::now();
    interpolatePlain();
    interpolatePrimary(out);
    mTimes.interpolateMs = msSince(start);

    if (mOptions.antiAlias) {
        start = std::chrono::steady_clock::now();
        antiAlias(out);
        mTimes.antiAliasMs = msSince(start);
    }
    if (mOptions.denseComplexLimit > 0) markDenseComplex();
    if (mOptions.complexFilter) {
        start = std::chrono::steady_clock::now();
        filterComplexPixels(out);
        mTimes.complexFilterMs = msSince(start);
    }
    if (mOptions.smoothRadius > 0) {
        // Last: it replaces whole pixels, whatever the stages above gave them. A stage of
        // its own (not one of the paper's three filters).
        start = std::chrono::steady_clock::now();
        smoothEdgeFreeRegions(out);
        mTimes.smoothMs = msSince(start);
    }
    if (mOptions.ownPointPrior > 0) {
        start = std::chrono::steady_clock::now();
        showOwnPoints(out);
        mTimes.smoothMs += msSince(start);
    }
    markHoles(true);
    return out;
}

void EdgePointImage::markHoles(bool useEdges) {
    // A pixel has a value from the points when its filter reached one (its own, or for a
    // complex pixel the plain 5×5 estimate the complex filter starts from), or when the
    // smoothing wrote it (mHole 1 on entry); the rest is a hole, which the display fills from
    // the surface its eye ray meets. A pixel whose reachable neighbourhood holds no point
    // while points lie across its edges (an object's silhouette over what a drag just
    // uncovered) is a hole too: the plain estimate interpolatePrimary leaves it would show the
    // other side's colours, a ragged band along the edge. A pixel of a simple pixel's
    // secondary region takes a neighbour's colour only through anti-aliasing, which mixes it
    // with the primary: with neither weight it is a hole too.
    std::vector<size_t> rowHoles(static_cast<size_t>(mHeight), 0);
    forRows(mOptions.parallel, mHeight, [&](int y) {
        size_t holes = 0;
        for (int x = 0; x < mWidth; ++x) {
            const size_t i = index(x, y);
            const bool reached =
                mWeight[i] > 0.0f ||
                (useEdges && mPlainWeight[i] > 0.0f && mEdgeCode[i] == kEdgeCodeComplex) ||
                mHole[i] != 0;
            mHole[i] = reached ? 0 : 1;
            holes += reached ? 0 : 1;
        }
        rowHoles[static_cast<size_t>(y)] = holes;
    });
    mHoleCount = 0;
    for (size_t h : rowHoles) mHoleCount += h;
}

// ---- Edge-free smoothing ------------------------------------------------------------------

namespace {

/// Edge-free smoothing: empty pixels at most this far (Chebyshev) from a simple or complex
/// pixel are filtered by reachability, the others by boxes.
constexpr int kRingDistance = 2;

}  // namespace

void EdgePointImage::computeEdgeDistance(int cap) {
    const size_t n = static_cast<size_t>(mWidth) * mHeight;
    // Chebyshev distance to the nearest simple or complex pixel, capped at R + 1: along each
    // row first (two sweeps), then the minimum over the rows within the cap of
    // max(|dy|, row distance). Pixels beyond the image count as empty.
    mEdgeDistanceRow.resize(n);
    mEdgeDistance.resize(n);
    forRows(mOptions.parallel, mHeight, [&](int y) {
        uint8_t* row = &mEdgeDistanceRow[static_cast<size_t>(y) * mWidth];
        const uint16_t* codes = &mEdgeCode[static_cast<size_t>(y) * mWidth];
        int d = cap;
        for (int x = 0; x < mWidth; ++x) {
            d = codes[x] != kEdgeCodeEmpty ? 0 : std::min(d + 1, cap);
            row[x] = static_cast<uint8_t>(d);
        }
        d = cap;
        for (int x = mWidth - 1; x >= 0; --x) {
            d = row[x] == 0 ? 0 : std::min(d + 1, cap);
            row[x] = static_cast<uint8_t>(std::min<int>(row[x], d));
        }
    });
    forRows(mOptions.parallel, mHeight, [&](int y) {
        const int y0 = std::max(0, y - cap), y1 = std::min(mHeight - 1, y + cap);
        // (Restrict, and the width in a local: byte pointers may alias anything, the member
        // mWidth included, which would keep this loop scalar.)
        const int W = mWidth;
        uint8_t* __restrict dst = &mEdgeDistance[static_cast<size_t>(y) * W];
        for (int x = 0; x < W; ++x) dst[x] = static_cast<uint8_t>(cap);
        for (int yy = y0; yy <= y1; ++yy) {
            const uint8_t dy = static_cast<uint8_t>(std::abs(yy - y));
            const uint8_t* __restrict row = &mEdgeDistanceRow[static_cast<size_t>(yy) * W];
            for (int x = 0; x < W; ++x) {
                const uint8_t far = row[x] > dy ? row[x] : dy;
                dst[x] = dst[x] < far ? dst[x] : far;
            }
        }
    });
}

void EdgePointImage::buildSummedAreaTable() {
    // Summed-area table of (colour, 1) over the points, in double (float sums of 262k terms
    // lose the colour's low bits): S(x, y) = Σ over x' < x, y' < y. Rows in parallel, then
    // columns in parallel blocks.
    // Every entry is written below; only row 0 and column 0 are zeros.
    const int sw = mWidth + 1;
    mSummedArea.resize(static_cast<size_t>(sw) * (mHeight + 1));
    std::fill_n(mSummedArea.begin(), sw, glm::dvec4(0.0));
    const int pw = mWidth + 4;
    forRows(mOptions.parallel, mHeight, [&](int y) {
        const glm::vec4* src = &mPaddedAll[static_cast<size_t>(y + 2) * pw + 2];
        glm::dvec4* dst = &mSummedArea[static_cast<size_t>(y + 1) * sw];
        glm::dvec4 sum(0.0);
        dst[0] = sum;
        for (int x = 0; x < mWidth; ++x) dst[x + 1] = sum += glm::dvec4(src[x]);
    });
    constexpr int kColumns = 32;
    forRows(mOptions.parallel, (sw + kColumns - 1) / kColumns, [&](int block) {
        const int x0 = block * kColumns, x1 = std::min(sw, x0 + kColumns);
        for (int y = 1; y <= mHeight; ++y) {
            glm::dvec4* row = &mSummedArea[static_cast<size_t>(y) * sw];
            const glm::dvec4* above = row - sw;
            for (int x = x0; x < x1; ++x) row[x] += above[x];
        }
    });
}

glm::dvec4 EdgePointImage::boxSum(int x, int y, int r) const {
    const int sw = mWidth + 1;
    const int xa = std::max(0, x - r), xb = std::min(mWidth, x + r + 1);
    const int ya = std::max(0, y - r), yb = std::min(mHeight, y + r + 1);
    return mSummedArea[static_cast<size_t>(yb) * sw + xb] -
           mSummedArea[static_cast<size_t>(yb) * sw + xa] -
           mSummedArea[static_cast<size_t>(ya) * sw + xb] +
           mSummedArea[static_cast<size_t>(ya) * sw + xa];
}

bool EdgePointImage::writeDenseMean(Image& out, int x, int y) {
    const glm::dvec4 sum = boxSum(x, y, mOptions.denseRadius);
    if (!(sum.w >= 1.5)) return false;
    out.at(x, y) = Rgb(glm::dvec3(sum) / sum.w);
    mHole[index(x, y)] = 1;  // written: not a hole (markHoles)
    return true;
}

void EdgePointImage::smoothBoxes(Image& out, int R) {
    // Each empty pixel whose nearest edge pixel is d > kRingDistance away takes the box
    // average of radius min(d − 1, R) (a box no edge crosses), when the box holds at least two
    // points; nearer ones are filtered by smoothNearEdges().
    forRows(mOptions.parallel, mHeight, [&](int y) {
        for (int x = 0; x < mWidth; ++x) {
            const int d = mEdgeDistance[index(x, y)];
            if (d <= kRingDistance) continue;
            const glm::dvec4 sum = boxSum(x, y, std::min(d - 1, R));
            if (sum.w >= 1.5) {
                out.at(x, y) = Rgb(glm::dvec3(sum) / sum.w);
                mHole[index(x, y)] = 1;  // written: not a hole (markHoles)
            }
        }
    });
}

void EdgePointImage::smoothNearEdges(Image& out, bool dense) {
    // Empty pixels next to an edge pixel (d = 1: any box would cross it) and at d = 2 (a box
    // of radius 1, a handful of points): the filter of §5.3 applied once more, to the primary
    // colours of the pixel and of its reachable 5×5 neighbours, each already a filtered
    // average of the samples it reaches. Still edge-respecting (mReach), with about twice the
    // support. (armadillo-field against the converged reference: the error in these pixels
    // fell by a fifth, 0.000534 → 0.000434 of the mean squared error; the boxes did better
    // from d = 3 on.)
    std::array<float, 24> weight;
    std::array<std::ptrdiff_t, 24> offset;  // of each 5×5 cell from the centre, in pixels
    for (int k = 0; k < 24; ++k) {
        const int dx = kBitCell[k] % 5 - 2, dy = kBitCell[k] / 5 - 2;
        weight[k] = filterWeight(dx, dy);
        offset[k] = static_cast<std::ptrdiff_t>(dy) * mWidth + dx;
    }
    forRows(mOptions.parallel, mHeight, [&](int y) {
        // Rows and columns two or more pixels inside the image reach no cell outside it.
        const bool innerRow = y >= 2 && y + 2 < mHeight;
        for (int x = 0; x < mWidth; ++x) {
            const size_t i = index(x, y);
            const int d = mEdgeDistance[i];
            if (d < 1 || d > kRingDistance) continue;
            if (dense && mDense[i] && writeDenseMean(out, x, y)) continue;
            glm::vec3 sum = mWeight[i] > 0.0f ? mPrimary[i] : glm::vec3(0.0f);
            float total = mWeight[i] > 0.0f ? 1.0f : 0.0f;
            const bool inner = innerRow && x >= 2 && x + 2 < mWidth;
            for (uint32_t bits = mReach[i] & 0xFFFFFFu; bits; bits &= bits - 1) {
                const int k = std::countr_zero(bits);
                if (!inner) {
                    const int px = x + kBitCell[k] % 5 - 2, py = y + kBitCell[k] / 5 - 2;
                    if (px < 0 || py < 0 || px >= mWidth || py >= mHeight) continue;
                }
                const size_t j = i + offset[k];
                if (!(mWeight[j] > 0.0f)) continue;
                sum += weight[k] * mPrimary[j];
                total += weight[k];
            }
            if (total > 0.0f) {
                out.at(x, y) = Rgb(sum / total);
                mHole[i] = 1;  // written: not a hole (markHoles)
            }
        }
    });
}

void EdgePointImage::smoothEdgeFreeRegions(Image& out) {
    const int R = std::clamp(mOptions.smoothRadius, 1, 100);
    // Distances are capped where they stop mattering: past the largest box, and past the
    // pixels the reachability pass takes (so that R = 1 still leaves d ≥ 3 to the boxes).
    const int cap = std::max(R, kRingDistance) + 1;
    computeEdgeDistance(cap);
    buildSummedAreaTable();
    // EpiOptions::denseRadius: a dense pixel takes the mean of every point in its box,
    // whatever its class, when the box holds two or more (writeDenseMean; else it keeps what
    // it has).
    const bool dense = mOptions.denseRadius > 0 && mOptions.denseComplexLimit > 0;
    smoothBoxes(out, R);
    smoothNearEdges(out, dense);
    // Dense regions' simple and complex pixels (d = 0; the ring pass wrote the empty ones).
    if (dense) {
        forRows(mOptions.parallel, mHeight, [&](int y) {
            for (int x = 0; x < mWidth; ++x) {
                const size_t i = index(x, y);
                if (mDense[i] && mEdgeDistance[i] == 0) writeDenseMean(out, x, y);
            }
        });
    }
}

// ---- Classification image -----------------------------------------------------------------

void EdgePointImage::showOwnPoints(Image& out) const {
    const double k = mOptions.ownPointPrior;
    forRows(mOptions.parallel, mHeight, [&](int y) {
        for (int x = 0; x < mWidth; ++x) {
            const size_t i = index(x, y);
            if (mSamplePos[i] == 0xFF || mEdgeCode[i] != kEdgeCodeEmpty || mSampleTrust[i] == 0)
                continue;
            const Rgb own(mSampleColour[i]);
            if (mSampleTrust[i] == kEpiTrustExact) {
                out.at(x, y) = own;
                continue;
            }
            const double n = mSampleTrust[i];
            out.at(x, y) = (own * n + out.at(x, y) * k) / (n + k);
        }
    });
}

Image EdgePointImage::classificationImage() const {
    Image image(mWidth, mHeight);
    for (int y = 0; y < mHeight; ++y) {
        for (int x = 0; x < mWidth; ++x) {
            const size_t i = index(x, y);
            switch (pixelClass(x, y)) {
                case PixelClass::Empty:
                    image.at(x, y) = mSamplePos[i] != 0xFF ? Rgb(0.05) : Rgb(0.0);
                    break;
                case PixelClass::Simple:
                    image.at(x, y) = Rgb(0.6, 0.1, 0.8);
                    break;
                case PixelClass::Complex:
                    image.at(x, y) = Rgb(0.1, 0.8, 0.1);
                    break;
            }
        }
    }
    return image;
}

}  // namespace penumbra
