#pragma once
// The display the lit-room drag tests use (tests/test_scenes.h makeLitRoom): small,
// synchronous (deterministic), a few more new samples a frame than the default.

#include "render/display/interactive_display.h"

namespace penumbra::test {

inline InteractiveDisplayOptions litRoomDisplayOptions(int size) {
    InteractiveDisplayOptions o;
    o.width = o.height = size;
    o.synchronous = true;
    o.sampleFraction = 0.05;
    return o;
}

}  // namespace penumbra::test
