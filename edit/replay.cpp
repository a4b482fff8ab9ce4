// Index: references and George et al.'s eq. 7 · runReplay · golden comparison
#include "edit/replay.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <sstream>

#include "core/input_error.h"
#include "core/timing.h"
#include "edit/edit_log.h"
#include "edit/edit_session.h"
#include "edit/lit_scene.h"

namespace penumbra {

namespace {

// ---------------------------------------------------------------------------------------------
// References and George et al.'s eq. 7.

/// A from-scratch converged solve of the lit scene as it stands, on the session's own
/// discretization and tracer (same elements, same pair-seeded samples). A fresh solver starts
/// from the objects in the solution only; it never subdivides. It solves as the session does:
/// deterministic shots for the strong shooters, then the stochastic tail, whose cost does not
/// grow with the element count (a deterministic robot-room reference took minutes).
std::vector<Rgb> solveReference(EditSession& session, const ReplayOptions& options) {
    SolverOptions reference = options.solver;
    reference.gradientThreshold = 0;
    ProgressiveSolver solver(session.discretization(), session.tracer(), reference);
    solver.converge(options.referenceEps >= 0 ? options.referenceEps : options.converge,
                    options.maxShots);
    return solver.radiosity();
}

/// George et al. eq. 7: sqrt(Σ (Y_ref − Y_cur)² A / Σ Y_ref² A) over `elements`.
double relativeLuminanceError(const Discretization& disc, const std::vector<Rgb>& reference,
                              const std::vector<Rgb>& current, const std::vector<int>& elements) {
    double num = 0, den = 0;
    for (int e : elements) {
        const double area = disc.elements()[e].area;
        const double yRef = luminance(reference[e]);
        const double yCur = luminance(current[e]);
        num += (yRef - yCur) * (yRef - yCur) * area;
        den += yRef * yRef * area;
    }
    return den > 0 ? std::sqrt(num / den) : 0.0;
}

/// The fraction of `elements` whose luminance changes by no more than the settling estimate's
/// bound from `current` to `reference`.
double boundCoverage(const std::vector<Rgb>& reference, const std::vector<Rgb>& current,
                     const SettlingEstimate& settling, const std::vector<int>& elements) {
    if (elements.empty()) return 1.0;
    std::size_t bounded = 0;
    for (int e : elements)
        if (std::abs(luminance(reference[e]) - luminance(current[e])) <= settling.bound(e))
            ++bounded;
    return static_cast<double>(bounded) / static_cast<double>(elements.size());
}

/// The 1% of `alive` (at least one) whose reference luminance changed most from `before`
/// to `after` (elements new since `before` count from zero). Ties go to the lower index.
std::vector<int> mostChanged(const std::vector<int>& alive, const std::vector<Rgb>& before,
                             const std::vector<Rgb>& after) {
    if (alive.empty()) return {};
    std::vector<std::pair<double, int>> change;
    change.reserve(alive.size());
    for (int e : alive) {
        const double yBefore = e < static_cast<int>(before.size()) ? luminance(before[e]) : 0.0;
        change.push_back({std::abs(luminance(after[e]) - yBefore), e});
    }
    const std::size_t count = std::max<std::size_t>(1, alive.size() / 100);
    std::partial_sort(change.begin(), change.begin() + count, change.end(),
                      [](const auto& a, const auto& b) {
                          return a.first != b.first ? a.first > b.first : a.second < b.second;
                      });
    std::vector<int> top;
    for (std::size_t k = 0; k < count; ++k) top.push_back(change[k].second);
    std::sort(top.begin(), top.end());
    return top;
}

/// Σ Y·A over the elements in the solution: a cheap fingerprint of the radiosity.
double radiosityChecksum(const Discretization& disc, const std::vector<Rgb>& b) {
    double sum = 0;
    for (std::size_t e = 0; e < b.size(); ++e)
        if (disc.elementAlive(static_cast<int>(e)))
            sum += luminance(b[e]) * disc.elements()[e].area;
    return sum;
}

/// Σ Y·A over each alive object's elements, by document id: which objects' lighting an edit
/// (or a code change, against a golden report) changed, and by how much.
nlohmann::json objectChecksums(const Discretization& disc, const std::vector<Rgb>& b) {
    std::vector<double> sum(disc.objects().size(), 0.0);
    for (std::size_t e = 0; e < b.size() && e < disc.elements().size(); ++e)
        if (disc.elementAlive(static_cast<int>(e)))
            sum[disc.elements()[e].object] += luminance(b[e]) * disc.elements()[e].area;
    nlohmann::json out = nlohmann::json::object();
    for (std::size_t o = 0; o < sum.size(); ++o)
        if (disc.objects()[o].alive) out[disc.objects()[o].id] = sum[o];
    return out;
}

/// The objects (up to three) whose lighting checksums differ most between two edit entries,
/// as "id +4.1%, other -0.8%" (relative to the golden value; "new"/"gone" for objects only
/// one side has). Empty when neither entry has per-object checksums or none differs.
std::string objectDifferences(const nlohmann::json& ours, const nlohmann::json& golden,
                              double tolerance) {
    if (!ours.contains("objects") || !golden.contains("objects")) return {};
    std::vector<std::pair<double, std::string>> differences;
    for (const auto& [id, value] : ours["objects"].items()) {
        if (!golden["objects"].contains(id)) {
            differences.push_back({1e300, id + " new"});
            continue;
        }
        const double a = value.get<double>(), g = golden["objects"][id].get<double>();
        if (std::abs(a - g) <= tolerance * std::max(std::abs(a), std::abs(g))) continue;
        const double relative = g != 0 ? (a - g) / std::abs(g) : 1e300;
        char text[64];
        std::snprintf(text, sizeof text, " %+.2g%%", 100.0 * relative);
        differences.push_back({std::abs(relative), id + text});
    }
    for (const auto& [id, value] : golden["objects"].items())
        if (!ours["objects"].contains(id)) differences.push_back({1e300, id + " gone"});
    std::stable_sort(differences.begin(), differences.end(),
                     [](const auto& x, const auto& y) { return x.first > y.first; });
    std::string out;
    for (std::size_t k = 0; k < differences.size() && k < 3; ++k)
        out += (k ? ", " : "") + differences[k].second;
    if (differences.size() > 3) out += ", and " + std::to_string(differences.size() - 3) + " more";
    return out;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// runReplay.

nlohmann::json runReplay(const ReplayOptions& options) {
    // Read every input before solving anything, so bad input fails fast.
    std::vector<ProbePoint> points;
    if (!options.pointsPath.empty()) points = readProbePoints(options.pointsPath);
    std::unique_ptr<EditSession> session =
        EditSession::open(options.scenePath, options.solver, options.import);
    const std::string sceneDir = std::filesystem::path(options.scenePath).parent_path().string();
    const std::vector<LoggedEdit> edits = readEditLog(options.logPath, sceneDir);
    RayTracer& tracer = session->tracer();

    // Edits start from a solved scene, as in the paper.
    auto start = Clock::now();
    unsigned long long rays0 = tracer.rayCount();
    std::uint64_t totalShots = session->converge(options.converge, options.maxShots);
    unsigned long long totalRays = tracer.rayCount() - rays0;
    double totalMs = msSince(start);
    nlohmann::json initial = {{"shots", totalShots},
                              {"rays", totalRays},
                              {"ms", totalMs},
                              {"unshot_fraction", session->solver().unshotFraction()}};

    std::vector<Rgb> reference, topSetReference;
    std::vector<int> topSet;
    if (options.reference) reference = solveReference(*session, options);
    if (options.afterConverge) options.afterConverge(*session);

    nlohmann::json editReports = nlohmann::json::array();
    double estimateTotalMs = 0;
    for (const LoggedEdit& logged : edits) {
        const EditCommand& command = logged.command;
        start = Clock::now();
        rays0 = tracer.rayCount();
        EditEvent result = session->apply(command, EditSource{options.logPath, logged.line});
        std::uint64_t shots = result.shots;
        if (!command.isSolverWork() && options.budgetShots > 0)
            shots += session->solve(options.budgetShots);
        const double ms = msSince(start);
        const unsigned long long rays = tracer.rayCount() - rays0;
        totalShots += shots;
        totalRays += rays;
        totalMs += ms;

        const Discretization& disc = session->discretization();
        const std::vector<Rgb>& b = session->solver().radiosity();
        nlohmann::json entry = {{"line", logged.line}, {"op", command.opName()}};
        if (!command.objectId().empty()) entry["id"] = command.objectId();
        entry["shots"] = shots;
        entry["rays"] = rays;
        entry["ms"] = ms;
        entry["checksum"] = radiosityChecksum(disc, b);
        entry["objects"] = objectChecksums(disc, b);
        entry["unshot_fraction"] = session->solver().unshotFraction();
        entry["pending_changes"] = session->solver().pendingChanges();
        const auto estimateStart = Clock::now();
        const SettlingEstimate settling = session->solver().computeSettlingSummary();
        const double estimateMs = msSince(estimateStart);
        estimateTotalMs += estimateMs;
        entry["error_estimate"] = settling.relativeRms;
        entry["estimate_ms"] = estimateMs;
        if (options.reference) {
            const std::vector<int> alive = disc.aliveElements();
            if (result.solutionChanged()) {
                std::vector<Rgb> after = solveReference(*session, options);
                topSet = mostChanged(alive, reference, after);
                reference = std::move(after);
            }
            entry["error_rms"] = relativeLuminanceError(disc, reference, b, alive);
            entry["error_top1"] = relativeLuminanceError(disc, reference, b, topSet);
            // The per-element bound, for its coverage (not in estimate_ms: only with references).
            entry["estimate_coverage"] =
                boundCoverage(reference, b, session->solver().computeSettling(), alive);
        }
        if (options.afterEdit) options.afterEdit(*session, result, entry);
        editReports.push_back(std::move(entry));
    }

    // After the last line.
    nlohmann::json report = session->reportJson();
    report["shots"] = totalShots;
    report["rays"] = totalRays;
    report["seconds"] = totalMs / 1000.0;
    report["estimate_seconds"] = estimateTotalMs / 1000.0;
    report["scene"] = options.scenePath;
    report["log"] = options.logPath;
    report["converge"] = options.converge;
    report["budget_shots"] = options.budgetShots;
    report["seed"] = options.solver.seed;
    report["reference"] = options.reference;
    if (options.reference)
        report["reference_eps"] =
            options.referenceEps >= 0 ? options.referenceEps : options.converge;
    report["initial"] = std::move(initial);
    report["edits"] = std::move(editReports);
    if (!points.empty()) {
        nlohmann::json irradiance = nlohmann::json::array();
        for (const ProbePoint& p : points) {
            const Rgb h = session->solver().irradianceAt(p.position, p.normal, 64);
            irradiance.push_back({h.x, h.y, h.z});
        }
        report["points"] = std::move(irradiance);
    }
    if (!options.exportPath.empty()) session->exportLitScene(options.exportPath);
    if (!options.saveScenePath.empty()) session->saveScene(options.saveScenePath);
    return report;
}

// ---------------------------------------------------------------------------------------------
// Golden comparison.

nlohmann::json readReplayReport(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path, "", "cannot read golden report");
    std::stringstream text;
    text << in.rdbuf();
    nlohmann::json json;
    try {
        json = nlohmann::json::parse(text.str());
    } catch (const nlohmann::json::exception& e) {
        // parse_error, and out_of_range for a number beyond a double ("1e999").
        throw InputError(path, "", std::string("not valid JSON: ") + e.what());
    }
    if (!json.is_object() || !json.contains("edits") || !json["edits"].is_array())
        throw InputError(path, "edits", "missing: not a replay report");
    for (std::size_t i = 0; i < json["edits"].size(); ++i) {
        const nlohmann::json& e = json["edits"][i];
        const std::string where = "edits[" + std::to_string(i) + "]";
        if (!e.is_object()) throw InputError(path, where, "expected an object");
        if (!e.contains("op") || !e["op"].is_string())
            throw InputError(path, where + ".op", "expected a string");
        if (!e.contains("shots") || !e["shots"].is_number_integer())
            throw InputError(path, where + ".shots", "expected an integer");
        if (!e.contains("checksum") || !e["checksum"].is_number())
            throw InputError(path, where + ".checksum", "expected a number");
    }
    return json;
}

std::optional<std::string> compareReplayReports(const nlohmann::json& report,
                                                const nlohmann::json& golden,
                                                const std::string& goldenName,
                                                double checksumTolerance) {
    const nlohmann::json& ours = report.at("edits");
    const nlohmann::json& theirs = golden.at("edits");
    auto name = [](const nlohmann::json& e) {
        std::ostringstream s;
        s << "line " << e.value("line", 0) << " (" << e.value("op", std::string("?"));
        if (e.contains("id") && e["id"].is_string()) s << " " << e["id"].get<std::string>();
        s << ")";
        return s.str();
    };
    auto number = [](const nlohmann::json& v) {
        std::ostringstream s;
        s.precision(17);
        s << v.get<double>();
        return s.str();
    };
    const std::size_t n = std::min(ours.size(), theirs.size());
    for (std::size_t i = 0; i < n; ++i) {
        const nlohmann::json& a = ours[i];
        const nlohmann::json& g = theirs[i];
        const std::string prefix = "check against " + goldenName + " failed: edit " +
                                   std::to_string(i + 1) + ", " + name(a) + ": ";
        if (a.at("op") != g.at("op"))
            return prefix + "op: '" + a["op"].get<std::string>() + "' here, '" +
                   g["op"].get<std::string>() + "' in the golden report";
        if (a.at("shots") != g.at("shots"))
            return prefix + "shots: " + a["shots"].dump() + " here, " + g["shots"].dump() +
                   " in the golden report";
        const double ca = a.at("checksum").get<double>(), cg = g.at("checksum").get<double>();
        if (!(std::abs(ca - cg) <= checksumTolerance * std::max(std::abs(ca), std::abs(cg)))) {
            std::ostringstream tolerance;
            tolerance << checksumTolerance;
            const std::string objects = objectDifferences(a, g, checksumTolerance);
            return prefix + "checksum: " + number(a["checksum"]) + " here, " +
                   number(g["checksum"]) + " in the golden report (relative tolerance " +
                   tolerance.str() + ")" +
                   (objects.empty() ? std::string() : "; lighting changed on " + objects);
        }
        if (a.contains("error_rms") && g.contains("error_rms") && a["error_rms"].is_number() &&
            g["error_rms"].is_number()) {
            const double ea = a["error_rms"].get<double>(), eg = g["error_rms"].get<double>();
            if (!(std::abs(ea - eg) <= 1e-6))
                return prefix + "error_rms: " + number(a["error_rms"]) + " here, " +
                       number(g["error_rms"]) + " in the golden report (tolerance 1e-6)";
        }
    }
    if (ours.size() != theirs.size()) {
        const bool extra = ours.size() > theirs.size();
        const nlohmann::json& first = extra ? ours[n] : theirs[n];
        return "check against " + goldenName + " failed: edit " + std::to_string(n + 1) + ", " +
               name(first) + ": " +
               (extra ? "not in the golden report" : "in the golden report but not replayed") +
               " (" + std::to_string(ours.size()) + " edits here, " +
               std::to_string(theirs.size()) + " in the golden report)";
    }
    return std::nullopt;
}

}  // namespace penumbra
