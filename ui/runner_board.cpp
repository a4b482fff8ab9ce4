#include "ui/runner_board.h"

#include <cstdio>

namespace penumbra {

bool sameCamera(const Camera& a, const Camera& b) {
    return a.position == b.position && a.lookAt == b.lookAt && a.up == b.up && a.fovDeg == b.fovDeg;
}

const ObjectSummary* DocumentSummary::find(const std::string& id) const {
    for (const ObjectSummary& o : objects)
        if (o.id == id) return &o;
    return nullptr;
}

bool ViewRequest::sameAs(const ViewRequest& o) const {
    return width == o.width && height == o.height && highlight == o.highlight &&
           interactive == o.interactive && mode == o.mode &&
           referenceRequest == o.referenceRequest && settlingOverlay == o.settlingOverlay &&
           sameCamera(camera, o.camera);
}

std::string HolodeckStatus::toString() const {
    if (path.empty()) return "";
    if (!open) return error.empty() ? "holodeck: opening" : "holodeck: not used";
    auto count = [](std::int64_t n) {
        char text[32];
        if (n >= 10000000)
            std::snprintf(text, sizeof text, "%.0fM", n * 1e-6);
        else if (n >= 1000000)
            std::snprintf(text, sizeof text, "%.1fM", n * 1e-6);
        else if (n >= 1000)
            std::snprintf(text, sizeof text, "%.0fk", n * 1e-3);
        else
            std::snprintf(text, sizeof text, "%lld", static_cast<long long>(n));
        return std::string(text);
    };
    std::string text = "holodeck: " + count(samples) + " samples";
    if (served > 0) text += ", " + count(served) + " shown";
    if (stored > 0) text += ", " + count(stored) + " stored";
    if (invalidated > 0) text += ", " + count(invalidated) + " forgotten";
    return text;
}

SolutionView PublishedLight::solutionView() const {
    SolutionView view;
    view.irradiance = irradiance.get();
    view.fromEmission = fromEmission.get();
    view.previewRadiosity = previewBuffer.get();
    view.previewFromEmission = previewFromEmission.get();
    view.previewObject = previewVersion;
    view.previewComplete = previewComplete;
    return view;
}

void RunnerBoard::setLight(PublishedLight light) {
    std::lock_guard<std::mutex> lock(mMutex);
    mLight = std::move(light);
}

PublishedLight RunnerBoard::light() const {
    std::lock_guard<std::mutex> lock(mMutex);
    return mLight;
}

std::uint64_t RunnerBoard::lightSerial() const {
    std::lock_guard<std::mutex> lock(mMutex);
    return mLight.serial;
}

void RunnerBoard::setDocument(std::shared_ptr<const DocumentSummary> document) {
    std::lock_guard<std::mutex> lock(mMutex);
    mDocument = std::move(document);
}

std::shared_ptr<const DocumentSummary> RunnerBoard::document() const {
    std::lock_guard<std::mutex> lock(mMutex);
    return mDocument;
}

void RunnerBoard::setSolver(SolverSnapshot solver) {
    std::lock_guard<std::mutex> lock(mMutex);
    mSolver = std::move(solver);
}

SolverSnapshot RunnerBoard::solver() const {
    std::lock_guard<std::mutex> lock(mMutex);
    SolverSnapshot s = mSolver;
    s.holodeck = mHolodeck;
    return s;
}

void RunnerBoard::setHolodeck(HolodeckStatus status) {
    std::lock_guard<std::mutex> lock(mMutex);
    mHolodeck = std::move(status);
}

void RunnerBoard::setImage(std::shared_ptr<const ViewportImage> image) {
    std::lock_guard<std::mutex> lock(mMutex);
    mImage = std::move(image);
}

std::shared_ptr<const ViewportImage> RunnerBoard::image() const {
    std::lock_guard<std::mutex> lock(mMutex);
    return mImage;
}

void RunnerBoard::report(const std::string& message) {
    std::lock_guard<std::mutex> lock(mMutex);
    mMessages.push_back(message);
}

std::vector<std::string> RunnerBoard::takeMessages() {
    std::lock_guard<std::mutex> lock(mMutex);
    std::vector<std::string> out;
    out.swap(mMessages);
    return out;
}

bool RunnerBoard::hasMessages() const {
    std::lock_guard<std::mutex> lock(mMutex);
    return !mMessages.empty();
}

RunnerBoard::Glance RunnerBoard::glance() const {
    std::lock_guard<std::mutex> lock(mMutex);
    return {mSolver.idle, mSolver.selected, mImage, mLight.serial};
}

}  // namespace penumbra
