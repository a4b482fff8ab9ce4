#include "core/random.h"

namespace penumbra {

std::uint64_t splitmix64(std::uint64_t state) {
    std::uint64_t x = state + 0x9e3779b97f4a7c15ull;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
    return x ^ (x >> 31);
}

std::uint64_t hashPair(std::uint64_t a, std::uint64_t b) {
    return splitmix64(splitmix64(a) ^ (b + 0x632be59bd9b4e019ull + (a << 6) + (a >> 2)));
}

}  // namespace penumbra
