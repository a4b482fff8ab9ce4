#include "render/display/display_report.h"

#include "render/display/interactive_display.h"

namespace penumbra {

nlohmann::json displayFrameJson(const DisplayFrameStats& f) {
    const DisplayStageTimes& t = f.times;
    return {{"frame", f.frame},
            {"total_ms", t.totalMs},
            {"reconstruct_ms", t.reconstructMs()},
            {"new_sample_fraction", f.newSampleFraction},
            {"find_edges_ms", t.findEdgesMs},
            {"silhouette_ms", t.silhouetteMs},
            {"shadow_ms", t.shadowMs},
            {"project_ms", t.projectMs},
            {"rasterize_ms", t.rasterizeMs},
            {"points_ms", t.pointsMs},
            {"reachability_ms", t.reachabilityMs},
            {"interpolate_ms", t.interpolateMs},
            {"anti_alias_ms", t.antiAliasMs},
            {"complex_filter_ms", t.complexFilterMs},
            {"smooth_ms", t.smoothMs},
            {"fill_ms", t.fillMs},
            {"hide_ms", t.hideMs},
            {"shadow_drop_ms", t.shadowDropMs},
            {"shadow_reshade_ms", t.shadowReshadeMs},
            {"request_ms", t.requestMs},
            {"shade_ms", t.shadeMs},
            {"new_samples", f.newSamples},
            {"requested_samples", f.requestedSamples},
            {"visible_points", f.visiblePoints},
            {"silhouette_edges", f.silhouetteEdges},
            {"sharp_edges", f.sharpEdges},
            {"shadow_edges", f.shadowEdges},
            {"screen_edges", f.screenEdges},
            {"empty_pixels", f.emptyPixels},
            {"simple_pixels", f.simplePixels},
            {"complex_pixels", f.complexPixels},
            {"unsampled_pixels", f.unsampledPixels},
            {"unfilled_pixels", f.unfilledPixels},
            {"dropped_shadowed", f.droppedShadowed}};
}

}  // namespace penumbra
