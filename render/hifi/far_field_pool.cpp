#include "render/hifi/far_field_pool.h"

#include <tbb/parallel_for.h>

#include <array>
#include <cmath>
#include <unordered_map>

#include "core/random.h"

namespace penumbra {

namespace {

/// The weighted least squares of F ≈ c0 + c1 u + c2 v about one sample.
class LocalLinearFit {
public:
    LocalLinearFit(const FarFieldSample& a, double r) : mA(a), mR(r) {
        mT = std::abs(a.n.x) > 0.5 ? glm::normalize(glm::cross(a.n, Vec3(0, 1, 0)))
                                   : glm::normalize(glm::cross(a.n, Vec3(1, 0, 0)));
        mB = glm::cross(a.n, mT);
    }

    /// Adds sample o when it lies in the sample's plane within the radius.
    void add(const FarFieldSample& o) {
        const Vec3 d = o.x - mA.x;
        const double d2 = glm::dot(d, d);
        if (d2 >= mR * mR || std::abs(glm::dot(d, mA.n)) > 1e-6 * mR) return;
        const double w0 = 1 - d2 / (mR * mR), w = w0 * w0;
        const double f[3] = {1, glm::dot(d, mT) / mR, glm::dot(d, mB) / mR};
        for (int row = 0; row < 3; ++row) {
            for (int q = 0; q < 3; ++q) mM[row][q] += w * f[row] * f[q];
            mRhs[row] += w * f[row] * o.indirect;
        }
        ++mCount;
    }

    /// c0 less the sample's own near part; false with too few neighbours or all on a line (a
    /// strip one sample wide).
    bool solve(Rgb& out) const {
        const double(&m)[3][3] = mM;
        const double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                           m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
        if (mCount < 8 || !(det > 1e-6 * m[0][0] * m[0][0] * m[0][0])) return false;
        // c0 by Cramer's rule.
        const Rgb c0 = (mRhs[0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                        m[0][1] * (mRhs[1] * m[2][2] - m[1][2] * mRhs[2]) +
                        m[0][2] * (mRhs[1] * m[2][1] - m[1][1] * mRhs[2])) /
                       det;
        out = glm::max(c0 - mA.near, Rgb(0.0));
        return true;
    }

private:
    const FarFieldSample& mA;
    const double mR;
    Vec3 mT{0.0}, mB{0.0};
    double mM[3][3] = {};
    Rgb mRhs[3] = {Rgb(0.0), Rgb(0.0), Rgb(0.0)};
    int mCount = 0;
};

/// Samples pool with those of their own group: plane and kind.
long long groupOf(const FarFieldSample& s) { return 2LL * s.plane + (s.open ? 1 : 0); }

/// A group's grid cell.
using CellKey = std::array<long long, 4>;

struct CellKeyHash {
    std::size_t operator()(const CellKey& k) const {
        std::uint64_t h = 0;
        for (long long v : k) h = hashPair(h, static_cast<std::uint64_t>(v));
        return static_cast<std::size_t>(h);
    }
};

/// The cell of `group`'s grid of cell size r that holds x.
CellKey cellOf(long long group, const Vec3& x, double r) {
    const Vec3 c = glm::floor(x / r);
    return CellKey{group, std::llround(c.x), std::llround(c.y), std::llround(c.z)};
}

/// Indices of samples by grid cell: a sample's neighbours within its cell size are in the 27
/// cells around its own.
class CellGrid {
public:
    void insert(const CellKey& key, int index) { mCells[key].push_back(index); }
    /// f(index) for every index in the 27 cells around `key`.
    template <class F>
    void forNeighbours(const CellKey& key, F&& f) const {
        for (long long di = -1; di <= 1; ++di)
            for (long long dj = -1; dj <= 1; ++dj)
                for (long long dk = -1; dk <= 1; ++dk) {
                    const auto it = mCells.find({key[0], key[1] + di, key[2] + dj, key[3] + dk});
                    if (it == mCells.end()) continue;
                    for (int j : it->second) f(j);
                }
    }

private:
    std::unordered_map<CellKey, std::vector<int>, CellKeyHash> mCells;
};

}  // namespace

PooledFarField poolFarField(const std::vector<FarFieldSample>& samples, double radius,
                            double nearRadius, PoolSearch search) {
    const int count = static_cast<int>(samples.size());
    PooledFarField out;
    out.value.assign(samples.size(), Rgb(0.0));
    out.fitted.assign(samples.size(), 0);
    auto radiusOf = [&](const FarFieldSample& s) { return s.open ? radius : nearRadius; };
    // Each group's samples by cells of its radius.
    CellGrid cells;
    if (search == PoolSearch::Grid)
        for (int i = 0; i < count; ++i) {
            const double r = radiusOf(samples[i]);
            if (r > 0) cells.insert(cellOf(groupOf(samples[i]), samples[i].x, r), i);
        }
    tbb::parallel_for(0, count, [&](int i) {
        const FarFieldSample& a = samples[i];
        const double r = radiusOf(a);
        if (!(r > 0)) return;
        const long long group = groupOf(a);
        LocalLinearFit fit(a, r);
        if (search == PoolSearch::Every) {
            for (const FarFieldSample& o : samples)
                if (groupOf(o) == group) fit.add(o);
        } else {
            cells.forNeighbours(cellOf(group, a.x, r), [&](int j) { fit.add(samples[j]); });
        }
        Rgb value;
        if (fit.solve(value)) {
            out.value[i] = value;
            out.fitted[i] = 1;
        }
    });
    return out;
}

PooledFarField fitFarField(const std::vector<FarFieldSample>& at,
                           const std::vector<FarFieldSample>& records,
                           const std::vector<double>& planeRadius, PoolSearch search) {
    PooledFarField out;
    out.value.assign(at.size(), Rgb(0.0));
    out.fitted.assign(at.size(), 0);
    auto radiusOf = [&](const FarFieldSample& s) {
        return s.plane >= 0 && std::size_t(s.plane) < planeRadius.size() ? planeRadius[s.plane]
                                                                         : 0.0;
    };
    // Each plane's records by cells of its radius.
    CellGrid cells;
    if (search == PoolSearch::Grid)
        for (std::size_t i = 0; i < records.size(); ++i) {
            const double r = radiusOf(records[i]);
            if (r > 0) cells.insert(cellOf(records[i].plane, records[i].x, r), static_cast<int>(i));
        }
    tbb::parallel_for(std::size_t(0), at.size(), [&](std::size_t i) {
        const FarFieldSample& a = at[i];
        const double r = radiusOf(a);
        if (!(r > 0)) return;
        LocalLinearFit fit(a, r);
        if (search == PoolSearch::Every) {
            for (const FarFieldSample& o : records)
                if (o.plane == a.plane) fit.add(o);
        } else {
            cells.forNeighbours(cellOf(a.plane, a.x, r), [&](int j) { fit.add(records[j]); });
        }
        Rgb value;
        if (fit.solve(value)) {
            out.value[i] = value;
            out.fitted[i] = 1;
        }
    });
    return out;
}

}  // namespace penumbra
