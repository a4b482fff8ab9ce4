#pragma once
// The one source of pseudo-random numbers: SplitMix64 (Steele, Lea, Flood 2014) and a pair hash
// on top of it. Sample patterns are seeded by what they sample (a pair, a point), never by
// time or thread, so every result is reproducible bit for bit.

#include <cstdint>

namespace penumbra {

/// SplitMix64's output for generator state `state`: the state advanced by the golden-ratio
/// increment, through the 64-bit mixer. The next state is state + 0x9e3779b97f4a7c15.
std::uint64_t splitmix64(std::uint64_t state);

/// Deterministic 64-bit hash of a pair, for pair-seeded sample patterns.
std::uint64_t hashPair(std::uint64_t a, std::uint64_t b);

/// A uniform double in [0, 1) from a 64-bit key (its hashPair with a fixed constant).
inline double unitFromKey(std::uint64_t key) {
    return static_cast<double>(hashPair(key, 0x9E3779B97F4A7C15ULL) >> 11) * 0x1.0p-53;
}

/// A SplitMix64 stream of uniform doubles in [0, 1).
class SplitMix {
public:
    explicit SplitMix(std::uint64_t seed) : mState(seed) {}
    double next() {
        const std::uint64_t r = splitmix64(mState);
        mState += 0x9e3779b97f4a7c15ull;
        return static_cast<double>(r >> 11) * 0x1.0p-53;
    }

private:
    std::uint64_t mState;
};

}  // namespace penumbra
