#include "render/hifi/far_field.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/math.h"
#include "core/random.h"

namespace penumbra {

FarFieldEstimate estimateFarField(const Vec3& n, std::uint64_t seed, const FarFieldRays& rays,
                                  double gathered, const std::function<Rgb(const Vec3&)>& read,
                                  const FarFieldEstimate* from) {
    return estimateFarFieldBatched(
        n, seed, rays, gathered,
        [&](const Vec3* dirs, int count, Rgb* out) {
            for (int k = 0; k < count; ++k) out[k] = read(dirs[k]);
        },
        from);
}

FarFieldEstimate estimateFarFieldBatched(const Vec3& n, std::uint64_t seed,
                                         const FarFieldRays& rays, double gathered,
                                         const FarFieldBatchRead& read,
                                         const FarFieldEstimate* from) {
    // An even side, so that the four subgrids hold the same number of strata.
    const int side0 = std::max(
        2, 2 * static_cast<int>(std::lround(0.5 * std::sqrt(double(std::max(1, rays.perPass))))));
    const Vec3 t = std::abs(n.x) > 0.5 ? glm::normalize(glm::cross(n, Vec3(0, 1, 0)))
                                       : glm::normalize(glm::cross(n, Vec3(1, 0, 0)));
    const Vec3 b = glm::cross(n, t);
    const int maxPasses = std::max(1, rays.maxPasses);
    // Passes are combined with weights by their expected precision: a stratified estimate's
    // variance falls as N^-3/2 where the integrand has edges.
    auto weightOf = [&](int side) { return std::pow(double(side) * side, 1.5); };
    FarFieldEstimate out;
    double weights = 0;
    Rgb weighted(0.0);
    int first = 0;
    if (from && from->passes > 0) {
        out = *from;
        first = from->passes;
        for (int pass = 0; pass < first; ++pass) weights += weightOf(side0 << pass);
        weighted = weights * from->value;
    }
    for (int pass = first, side = side0 << first; pass < maxPasses; ++pass, side *= 2) {
        SplitMix random(pass == 0 ? seed : hashPair(seed, static_cast<std::uint64_t>(pass)));
        // The pass's directions, stratum (i, k) at i·side + k, read at once.
        thread_local std::vector<Vec3> dirs;
        thread_local std::vector<Rgb> found;
        dirs.resize(std::size_t(side) * side);
        found.resize(dirs.size());
        for (int i = 0; i < side; ++i)
            for (int k = 0; k < side; ++k) {
                // Malley: a stratified point of the disc lifted to the hemisphere.
                const double u = (i + random.next()) / side, v = (k + random.next()) / side;
                const double r = std::sqrt(u), phi = 2 * M_PI * v;
                dirs[std::size_t(i) * side + k] = r * std::cos(phi) * t + r * std::sin(phi) * b +
                                                  std::sqrt(std::max(0.0, 1 - u)) * n;
            }
        read(dirs.data(), static_cast<int>(dirs.size()), found.data());
        Rgb sub[4] = {Rgb(0.0), Rgb(0.0), Rgb(0.0), Rgb(0.0)};
        for (int i = 0; i < side; ++i)
            for (int k = 0; k < side; ++k)
                sub[(i & 1) * 2 + (k & 1)] += found[std::size_t(i) * side + k];
        const double count = double(side) * side;
        const Rgb value = (sub[0] + sub[1] + sub[2] + sub[3]) / count;
        // The pass's standard error from its four subgrids' means (each over count / 4 rays):
        // their spread over 2 is the error of the mean of four independent estimates, and a
        // stratified estimate's error falls as N^-3/4 where the integrand has edges (a
        // silhouette, an element's edge), so the whole pass's is 4^-1/4 of that again.
        double mean = 0, squares = 0;
        for (const Rgb& s : sub) {
            const double y = luminance(s) * 4 / count;
            mean += 0.25 * y;
            squares += y * y;
        }
        const double passError =
            std::sqrt(std::max(0.0, squares - 4 * mean * mean) / 3) / (2 * std::sqrt(2.0));
        const double w = weightOf(side);
        const double previous = weights;
        weights += w;
        weighted += w * value;
        out.value = weighted / weights;
        out.standardError = pass == 0
                                ? passError
                                : std::hypot(previous * out.standardError, w * passError) / weights;
        out.rays += side * side;
        out.passes = pass + 1;
        const double tolerance =
            std::max(rays.relativeError * (gathered + luminance(out.value)), rays.absoluteError);
        if (out.standardError <= tolerance) break;
    }
    return out;
}

}  // namespace penumbra
