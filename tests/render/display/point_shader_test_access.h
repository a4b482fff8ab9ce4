#pragma once
// PointShader's drag and refresh steps are InteractiveDisplay's (it takes them in apply()); the
// tests that check one of them alone on a standalone shader call them through this friend.

#include <vector>

#include "render/display/point_shader.h"

namespace penumbra {

struct PointShaderTestAccess {
    static void refreshDirect(PointShader& shader, const std::vector<int>& changedObjects) {
        shader.refreshDirect(changedObjects);
    }
    static void beginDrag(PointShader& shader, int origin, const Visibility& originOnly = {}) {
        shader.beginDrag(origin, originOnly);
    }
    static std::vector<int> setPreview(PointShader& shader, int object,
                                       const Visibility& previewOnly = {}) {
        return shader.setPreview(object, previewOnly);
    }
};

}  // namespace penumbra
