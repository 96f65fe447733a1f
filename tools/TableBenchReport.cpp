#include "TableBenchReport.h"

#include "BenchSupport.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

namespace penumbra {
namespace {

using nlohmann::json;

constexpr const char* kBeginMarker = "<!-- penumbra bench table2: begin (generated, do not edit) -->";
constexpr const char* kEndMarker = "<!-- penumbra bench table2: end -->";

std::string secs(const json& v) { return fmt::format("{:.2f}", v.get<double>()); }

/// @p method's ("ours" or "embree") whole-process wall time in @p row, from start to the written
/// output; none where a result predates it or the bake failed.
std::optional<double> processWall(const json& row, const char* method) {
    if (!row.contains(method) || row[method].contains("error") || !row[method].contains("process_wall_s")) return std::nullopt;
    const json& w = row[method]["process_wall_s"];
    return w.is_number() ? std::optional<double>(w.get<double>()) : std::nullopt;
}

/// Embree's whole-process wall time over ours in @p row, where both are known.
std::optional<double> processWallRatio(const json& row) {
    const auto ours = processWall(row, "ours"), embree = processWall(row, "embree");
    if (!ours || !embree || !(*ours > 0)) return std::nullopt;
    return *embree / *ours;
}

/// The process wall columns of @p row: ours, Embree's and their ratio ("–" where unknown).
std::string processWallColumns(const json& row) {
    auto cell = [](std::optional<double> v) { return v ? fmt::format(" {:.2f} |", *v) : std::string(" – |"); };
    return cell(processWall(row, "ours")) + cell(processWall(row, "embree")) + cell(processWallRatio(row));
}

/// Finds the row of @p scene named @p row with no error, or nullptr.
const json* findRow(const json& result, const std::string& scene, const std::string& row) {
    for (const json& r : result["rows"])
        if (r["scene"] == scene && r["row"] == row && !r.contains("error")) return &r;
    return nullptr;
}

std::string verdict(bool met) { return met ? "met" : "**not met**"; }

std::string targetsMarkdown(const json& result) {
    std::string md = "| target | measured | verdict |\n|---|---|---|\n";
    std::vector<std::string> scenes;
    for (const json& r : result["rows"])
        if (std::find(scenes.begin(), scenes.end(), r["scene"].get<std::string>()) == scenes.end())
            scenes.push_back(r["scene"]);
    // Issue #16: Embree/ours at least 1 on every row at 1280x960 and above, at least 2 on flowers
    // and sponza-like, toward 3 everywhere; by the paper's count and by the processes' wall time.
    for (const std::string& scene : scenes) {
        double worst = INFINITY, worstWall = INFINITY;
        for (const json& r : result["rows"]) {
            if (r["scene"] != scene || r["nominal_width"].get<int>() < 1280) continue;
            if (r.contains("ratio")) worst = std::min(worst, r["ratio"].get<double>());
            if (const auto wall = processWallRatio(r)) worstWall = std::min(worstWall, *wall);
        }
        const double need = scene == "flowers" || scene == "sponza-like" ? 2.0 : 1.0;
        auto line = [&](const char* how, double value) {
            if (!std::isfinite(value)) return;
            md += fmt::format("| {}: Embree/ours ≥ {:g} (aim ≥ 3) at 1280×960 and above, {} | lowest ratio {:.2f} | {} |\n", scene, need,
                              how, value, value >= need ? (value < 3.0 ? "met (aim of 3 not met)" : "met") : "**not met**");
        };
        line("sort + build + cast", worst);
        line("whole process wall", worstWall);
    }
    for (const std::string& scene : scenes) {
        auto ratio = [&](const char* a, const char* b) -> std::optional<double> {
            const json *ra = findRow(result, scene, a), *rb = findRow(result, scene, b);
            if (!ra || !rb) return std::nullopt;
            return (*rb)["ours"]["time_s"].get<double>() / (*ra)["ours"]["time_s"].get<double>();
        };
        using Step = std::tuple<const char*, const char*, const char*>;
        for (auto [a, b, what] : std::vector<Step>{{"640x480@256", "1280x960@256", "4× receivers (640×480 → 1280×960)"},
                                                   {"1280x960@256", "2560x1920@256", "4× receivers (1280×960 → 2560×1920)"},
                                                   {"1280x960@256", "1280x960@1024", "4× samples (256 → 1024)"}})
            if (auto r = ratio(a, b)) md += fmt::format("| {}: {} costs ≤ 2.5× | {:.2f}× | {} |\n", scene, what, *r, verdict(*r <= 2.5));
    }
    uint64_t nonTies = 0, total = 0;
    bool compared = false;
    for (const json& r : result["rows"])
        if (r.contains("mismatches") && !r["mismatches"].contains("error")) {
            compared = true;
            nonTies += r["mismatches"]["non_ties"].get<uint64_t>();
            total += r["mismatches"]["mismatches"].get<uint64_t>();
        }
    if (compared)
        md += fmt::format("| zero mismatches against Embree apart from ties | {} mismatches, {} not ties | {} |\n", total,
                          nonTies, verdict(nonTies == 0));
    if (result.contains("thread_scaling"))
        for (const json& s : result["thread_scaling"])
            if (s.contains("speedup"))
                md += fmt::format("| {} {}: {} threads ≥ 1.8× of 1 | {:.2f}× | {} |\n", s["scene"].get<std::string>(),
                                  s["row"].get<std::string>(), s["threads"].back().get<int>(), s["speedup"].get<double>(),
                                  verdict(s["speedup"].get<double>() >= 1.8));
    if (result.contains("root_cull") && result["root_cull"].contains("cases"))
        for (const json& c : result["root_cull"]["cases"])
            if (c.contains("triangles_per_second_per_core"))
                md += fmt::format("| root cull ({}) ≥ 20M triangles/s/core | {:.1f}M | {} |\n", c["case"].get<std::string>(),
                                  c["triangles_per_second_per_core"].get<double>() / 1e6,
                                  verdict(c["triangles_per_second_per_core"].get<double>() >= 20e6));
    return md;
}

}  // namespace

std::string formatMiB(const json& bytes) { return fmt::format("{:.1f}", bytes.get<double>() / (1024.0 * 1024.0)); }

std::string replaceTable2Section(const std::string& document, const std::string& generated) {
    return replaceGeneratedSection(document, kBeginMarker, kEndMarker,
                                   "## Table 2: penumbra casting against Embree\n\nGenerated by `penumbra bench table2`; see the README for the command.",
                                   generated);
}

std::string table2Markdown(const json& result) {
    const json& m = result["machine"];
    std::string md;
    const double scale = result["scale"];
    if (scale != 1.0)
        md += fmt::format("**Reduced-scale validation run (`--scale {}`): every resolution is {:.0f}% of the paper's in each "
                          "direction; these numbers check the tool, they are not the benchmark.**\n\n",
                          scale, 100 * scale);
    md += fmt::format("Run {} with `{}`.\n\n", result["date"].get<std::string>(), result["command"].get<std::string>());
    md += fmt::format("Machine: {}, {} cores, {:.1f} GiB RAM, {}; {}; commit {}.\n\n", m["cpu"].get<std::string>(),
                      m["cores"].get<int>(), m["ram_bytes"].get<double>() / double(1ull << 30), m["os"].get<std::string>(),
                      m["compiler"].get<std::string>(), m["commit"].get<std::string>());
    md += fmt::format("Best of {} run(s) per row and method; ours on {} thread(s), Embree on {} thread(s).",
                      result["repeat"].get<int>(), result["threads_table"].get<int>(), result["threads_table"].get<int>());
    if (result.contains("load_average_end"))
        md += fmt::format(" Load average (1 min) {:.1f} at the start and {:.1f} at the end, over {:.0f} s: a load near or "
                          "above the core count means other work shared the cores, which shows first in thread scaling.",
                          result["load_average_start"].get<double>(), result["load_average_end"].get<double>(),
                          result["elapsed_s"].get<double>());
    md += "\n\n";
    if (result.contains("bench_process_peak_rss_bytes"))
        md += fmt::format("Peak RSS is each bake's own (a child process each, wait4() ru_maxrss). Linux counts the spawning "
                          "process's resident set in a child's ru_maxrss, so no figure can read below the benchmark "
                          "process's own peak, {} MiB.\n\n",
                          formatMiB(result["bench_process_peak_rss_bytes"]));
    md += "| scene | resolution | samples | light | sort s | hierarchy build s | penumbra cast s | ours s | samples MiB | "
          "hierarchy MiB | masks MiB | ours peak RSS MiB | Embree s (build + trace) | Embree peak RSS MiB | Embree/ours | "
          "ours process wall s | Embree process wall s | Embree/ours, process | mismatches (ties) |\n";
    md += "|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for (const json& r : result["rows"]) {
        md += fmt::format("| {} | {}×{} | {} | {} |", r["scene"].get<std::string>(), r["width"].get<int>(), r["height"].get<int>(),
                          r["samples"].get<int>(), r["light_scale"].get<double>() == 1.0 ? "1×" : "4× area");
        if (r.contains("error")) {
            md += " error: " + r["error"].get<std::string>() + " |||||||||||||||\n";
            continue;
        }
        const json& o = r["ours"];
        md += fmt::format(" {} | {} | {} | {} | {} | {} | {} | {} |", secs(o["sort_s"]), secs(o["hierarchy_build_s"]),
                          secs(o["penumbra_cast_s"]), secs(o["time_s"]), formatMiB(o["samples_memory_bytes"]),
                          formatMiB(o["hierarchy_memory_bytes"]), formatMiB(o["mask_memory_bytes"]), formatMiB(o["peak_rss_bytes"]));
        if (r.contains("embree") && !r["embree"].contains("error"))
            md += fmt::format(" {} ({} + {}) | {} | {:.2f} |", secs(r["embree"]["time_s"]), secs(r["embree"]["build_s"]),
                              secs(r["embree"]["trace_s"]), formatMiB(r["embree"]["peak_rss_bytes"]), r["ratio"].get<double>());
        else
            md += r.contains("embree") ? " error | | |" : " – | – | – |";
        md += processWallColumns(r);
        if (r.contains("mismatches") && !r["mismatches"].contains("error"))
            md += fmt::format(" {} ({}) |\n", r["mismatches"]["mismatches"].get<uint64_t>(), r["mismatches"]["ties"].get<uint64_t>());
        else
            md += r.contains("mismatches") ? " error |\n" : " – |\n";
    }
    if (result.contains("thread_scaling") && !result["thread_scaling"].empty()) {
        md += "\n### Thread scaling (ours: sort + hierarchy build + penumbra cast)\n\n| scene | row |";
        std::string rule = "|---|---|";
        for (const json& t : result["thread_scaling"][0]["threads"]) md += fmt::format(" {} thr s |", t.get<int>()), rule += "---:|";
        md += " speed-up | cast-only speed-up |\n" + rule + "---:|---:|\n";
        for (const json& s : result["thread_scaling"]) {
            md += fmt::format("| {} | {} |", s["scene"].get<std::string>(), s["row"].get<std::string>());
            for (const json& t : s["seconds"]) md += fmt::format(" {} |", t.is_null() ? std::string("error") : secs(t));
            md += s.contains("speedup") ? fmt::format(" {:.2f}× | {:.2f}× |\n", s["speedup"].get<double>(), s["cast_speedup"].get<double>())
                                        : " – | – |\n";
        }
    }
    if (result.contains("root_cull")) {
        const json& c = result["root_cull"];
        md += "\n### Root-cull throughput (1 thread)\n\n";
        if (c.contains("error")) {
            md += "error: " + c["error"].get<std::string>() + "\n";
        } else {
            md += "| case | triangles | culled at root | penumbra cast s | M triangles/s/core | stream + bucket pass M triangles/s |\n"
                  "|---|---:|---:|---:|---:|---:|\n";
            for (const json& k : c["cases"]) {
                if (k.contains("error")) {
                    md += "| " + k["case"].get<std::string>() + " | error: " + k["error"].get<std::string>() + " ||||\n";
                    continue;
                }
                md += fmt::format("| {} | {:.0f} | {:.0f} | {:.3f} | {:.1f} | {:.1f} |\n", k["case"].get<std::string>(),
                                  k["triangles"].get<double>(), k["culled_at_root"].get<double>(), k["cast_s"].get<double>(),
                                  k["triangles_per_second_per_core"].get<double>() / 1e6,
                                  k["sort_pass_triangles_per_second"].get<double>() / 1e6);
            }
        }
    }
    md += "\n### Targets\n\n" + targetsMarkdown(result);
    return md;
}

}  // namespace penumbra
