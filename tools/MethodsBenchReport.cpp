// The Markdown of `penumbra bench methods` (MethodsBench.h): the tables, the targets with their
// verdicts, and the splice into docs/BENCHMARKS.md between the generated-section markers.

#include "BenchSupport.h"
#include "MethodsBench.h"
#include "TableBenchReport.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace penumbra {
namespace {

using nlohmann::json;

constexpr const char* kBeginMarker = "<!-- penumbra bench methods: begin (generated, do not edit) -->";
constexpr const char* kEndMarker = "<!-- penumbra bench methods: end -->";

std::string number(const json& v, const char* format = "{:.2f}") { return v.is_number() ? fmt::format(fmt::runtime(format), v.get<double>()) : "–"; }

const json& at(const json& j, const char* key) {
    static const json none;
    return j.is_object() && j.contains(key) ? j[key] : none;
}

std::string mismatchCell(const json& c) {
    const json& m = at(c, "mismatches_vs_hpc");
    if (m.is_null()) return "–";
    if (m.contains("error")) return "error";
    return fmt::format("{} ({})", at(m, "mismatches").get<uint64_t>(), at(m, "ties").get<uint64_t>());
}

/// hpc's value of @p key over @p c's (> 1: faster), or null.
json ratioToHpc(const json& hpc, const json& c, const char* key) {
    const json &a = at(hpc, key), &b = at(c, key);
    if (!a.is_number() || !b.is_number() || !(b.get<double>() > 0)) return nullptr;
    return a.get<double>() / b.get<double>();
}

std::string methodLine(const std::string& scene, const std::string& size, const std::string& method, const json& c, const json& hpc) {
    if (c.contains("skipped")) return fmt::format("| {} | {} | {} | {} | | | | | | | | | | |\n", scene, size, method, at(c, "skipped").get<std::string>());
    if (c.contains("error")) return fmt::format("| {} | {} | {} | error: {} | | | | | | | | | | |\n", scene, size, method, at(c, "error").get<std::string>());
    const json& e = at(c, "error_vs_hpc");
    const bool isHpc = method == "hpc";
    auto ratio = [&](const char* key) { return isHpc ? std::string("1") : number(ratioToHpc(hpc, c, key), "{:.2f}×"); };
    return fmt::format("| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n", scene, size, method, number(at(c, "time_s")),
                       isHpc ? "1" : number(at(c, "speedup_vs_hpc"), "{:.2f}×"), number(at(c, "bake_total_s")), ratio("bake_total_s"),
                       number(at(c, "process_cpu_s")), ratio("process_cpu_s"), formatMiB(at(c, "peak_rss_bytes")), mismatchCell(c),
                       number(at(e, "mean_abs_dv"), "{:.4f}"), number(at(e, "max_abs_dv"), "{:.3f}"), number(at(e, "fraction_above_0_1"), "{:.4f}"));
}

std::string ssvTable(const json& result) {
    std::string md = "| scene | size | kd-tree MiB | nodes | leaves | depth | references | scene MiB | potential silhouette edges | "
                     "edges per frustum | silhouette edges per frustum | straddlers per frustum | reference retries | fallbacks | "
                     "time per receiver µs | build s |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for (const json& row : at(result, "rows")) {
        const json& s = at(at(at(row, "methods"), "ssv"), "ssv");
        if (s.is_null()) continue;
        md += fmt::format("| {} | {}×{} | {} | {} | {} | {} | {} | {} | {} | {:.1f} | {:.1f} | {:.1f} | {} | {} | {:.1f} | {:.2f} |\n",
                          at(row, "scene").get<std::string>(), at(row, "width").get<int>(), at(row, "height").get<int>(),
                          formatMiB(at(at(s, "kd_tree"), "bytes")), at(at(s, "kd_tree"), "nodes").get<uint64_t>(), at(at(s, "kd_tree"), "leaves").get<uint64_t>(),
                          at(at(s, "kd_tree"), "depth").get<int>(), at(at(s, "kd_tree"), "references").get<uint64_t>(), formatMiB(at(s, "scene_bytes")),
                          at(s, "potential_silhouette_edges").get<uint64_t>(), at(s, "edges_per_frustum").get<double>(),
                          at(s, "silhouette_edges_per_frustum").get<double>(), at(s, "straddlers_per_frustum").get<double>(),
                          at(s, "reference_retries").get<uint64_t>(), at(s, "fallback_frustums").get<uint64_t>(),
                          at(s, "time_per_receiver_us").get<double>(), at(s, "build_time_s").get<double>());
    }
    return md;
}

std::string hhTable(const json& result) {
    std::string md = "| samples | hpc s | hh s | hh vs hpc | hh peak RSS MiB | mismatches vs hpc (ties) | mean abs dV | max abs dV | > 0.1 |\n"
                     "|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for (const json& row : at(result, "hh")) {
        const json &hpc = at(at(row, "methods"), "hpc"), &hh = at(at(row, "methods"), "hh");
        if (hpc.contains("error") || hh.is_null() || hh.contains("error")) {
            md += fmt::format("| {} | error | | | | | | | |\n", at(row, "samples").get<int>());
            continue;
        }
        const json& e = at(hh, "error_vs_hpc");
        md += fmt::format("| {} | {} | {} | {} | {} | {} | {} | {} | {} |\n", at(row, "samples").get<int>(), number(at(hpc, "time_s")),
                          number(at(hh, "time_s")), number(at(hh, "speedup_vs_hpc"), "{:.2f}×"), formatMiB(at(hh, "peak_rss_bytes")),
                          mismatchCell(hh), number(at(e, "mean_abs_dv"), "{:.4f}"), number(at(e, "max_abs_dv"), "{:.3f}"),
                          number(at(e, "fraction_above_0_1"), "{:.4f}"));
    }
    return md;
}

std::string targets(const json& result) {
    std::string md = "| target | measured | verdict |\n|---|---|---|\n";
    auto verdict = [](bool met) { return met ? "met" : "**not met**"; };
    // The preview, and each of its lookups run as a variant (penumbra-map:LOOKUP).
    std::vector<std::string> previews;
    for (const json& row : at(result, "rows"))
        for (const auto& [method, c] : at(row, "methods").items())
            if (method.rfind("penumbra-map", 0) == 0 && std::find(previews.begin(), previews.end(), method) == previews.end())
                previews.push_back(method);
    for (const std::string& preview : previews)
    for (const json& row : at(result, "rows")) {
        const json& pm = at(at(row, "methods"), preview.c_str());
        if (pm.is_null() || pm.contains("error") || at(row, "nominal") != "1280x960") continue;
        const json& hpc = at(at(row, "methods"), "hpc");
        const double cast = at(pm, "speedup_vs_hpc").get<double>();
        const json bake = ratioToHpc(hpc, pm, "bake_total_s"), cpu = ratioToHpc(hpc, pm, "process_cpu_s");
        // Judged both ways: the paper's count (the method's own phase against hpc's sort + build +
        // cast) and the whole bake, whose wall time on a loaded machine can flatter either side,
        // so its CPU time must agree.
        const bool whole = bake.is_number() && bake.get<double>() >= 10 && cpu.is_number() && cpu.get<double>() >= 10;
        const std::string judged = cast >= 10 ? (whole ? "met" : "met in the paper's count; **not met** for the whole bake")
                                              : std::string(verdict(false));
        md += fmt::format("| {} ≥ 10× faster than hpc, {} 1280×960 (cast / whole bake / process CPU) | {:.1f}× / {} / {} | {} |\n",
                          preview, at(row, "scene").get<std::string>(), cast, number(bake, "{:.1f}×"), number(cpu, "{:.1f}×"), judged);
    }
    for (const std::string& preview : previews)
    for (const json& row : at(result, "rows")) {
        const json& e = at(at(at(row, "methods"), preview.c_str()), "error_vs_hpc");
        if (at(row, "scene") != "grids" || !e.contains("mean_abs_dv")) continue;
        const double dv = at(e, "mean_abs_dv").get<double>();
        md += fmt::format("| {} mean abs dV < 0.05 on grids {} | {:.4f} | {} |\n", preview, at(row, "nominal").get<std::string>(), dv,
                          verdict(dv < 0.05));
    }
    for (const char* method : {"ssv", "embree", "reference"}) {
        uint64_t total = 0, nonTies = 0;
        bool any = false;
        for (const json& row : at(result, "rows")) {
            const json& m = at(at(at(row, "methods"), method), "mismatches_vs_hpc");
            if (!m.contains("mismatches")) continue;
            any = true, total += at(m, "mismatches").get<uint64_t>(), nonTies += at(m, "non_ties").get<uint64_t>();
        }
        if (any)
            md += fmt::format("| {}: every mismatch against hpc a tie of the rule | {} mismatches, {} not ties | {} |\n", method, total,
                              nonTies, verdict(nonTies == 0));
    }
    return md;
}

}  // namespace

std::string replaceMethodsSection(const std::string& document, const std::string& generated) {
    return replaceGeneratedSection(document, kBeginMarker, kEndMarker,
                                   "## Methods: every method against hpc\n\nGenerated by `penumbra bench methods`.", generated);
}

std::string methodsMarkdown(const json& result) {
    const json& m = at(result, "machine");
    std::string md;
    if (at(result, "scale").get<double>() != 1.0)
        md += fmt::format("**Reduced-scale run (`--scale {}`): every size below is {:.0f}% of the nominal one in each direction.**\n\n",
                          at(result, "scale").get<double>(), 100 * at(result, "scale").get<double>());
    md += fmt::format("Run {} with `{}`.\n\n", at(result, "date").get<std::string>(), at(result, "command").get<std::string>());
    md += fmt::format("Machine: {}, {} cores, {:.1f} GiB RAM, {}; {}; commit {}. Every bake on {} thread(s), best of {}. "
                      "Load average (1 min) {:.1f} at the start and {:.1f} at the end, over {:.0f} s.\n\n",
                      at(m, "cpu").get<std::string>(), at(m, "cores").get<int>(), at(m, "ram_bytes").get<double>() / double(1ull << 30),
                      at(m, "os").get<std::string>(), at(m, "compiler").get<std::string>(), at(m, "commit").get<std::string>(),
                      at(result, "threads").get<int>(), at(result, "repeat").get<int>(), at(result, "load_average_start").get<double>(),
                      result.value("load_average_end", -1.0), result.value("elapsed_s", 0.0));
    md += "| scene | size | method | time s | vs hpc | bake s | bake vs hpc | CPU s | CPU vs hpc | peak RSS MiB | mismatches vs hpc (ties) | "
          "mean abs dV | max abs dV | > 0.1 |\n|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for (const json& row : at(result, "rows")) {
        const std::string size = fmt::format("{}×{}", at(row, "width").get<int>(), at(row, "height").get<int>());
        const json& hpc = at(at(row, "methods"), "hpc");
        if (!hpc.is_null()) md += methodLine(at(row, "scene"), size, "hpc", hpc, hpc);
        for (const auto& [method, c] : at(row, "methods").items())
            if (method != "hpc") md += methodLine(at(row, "scene"), size, method, c, hpc);
    }
    // Sections only for the methods the run had (an empty ssv table was printed without ssv).
    const json& rows = at(result, "rows");
    if (std::any_of(rows.begin(), rows.end(), [](const json& row) { return !at(at(at(row, "methods"), "ssv"), "ssv").is_null(); }))
        md += "\n### ssv: the numbers of Harter, Osswald & Assarsson\n\n" + ssvTable(result);
    if (const json& hh = at(result, "hh"); !hh.empty()) {
        const std::string scene = at(hh[0], "scene").is_string() ? at(hh[0], "scene").get<std::string>() : std::string("lightmap");
        md += fmt::format("\n### hh against hpc on the {} example, as the samples grow\n\n", scene) + hhTable(result);
    }
    md += "\n### Targets\n\n" + targets(result);
    return md;
}

}  // namespace penumbra
