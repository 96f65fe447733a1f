#include "MethodsBench.h"

#include "BenchSupport.h"

#include "bake/cast/Caster.h"
#include "stream/util/Error.h"
#include "stream/util/InputFile.h"
#include "stream/util/JsonParams.h"
#include "stream/util/Memory.h"
#include "stream/util/Npy.h"

#include <fmt/format.h>
#include <tbb/info.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>

namespace penumbra {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

/// A method's own time: hpc's is the paper's (sort + hierarchy build + cast), Embree's its build
/// and trace; every other method's is its cast phase after the scan pass (reading the scene into
/// memory or streaming it, building, casting) up to shading its receivers, which hpc's leaves
/// out too.
double methodSeconds(const json& s, const std::string& method) {
    const json& t = s["table2"];
    if (method == "hpc") return hpcPaperSeconds(s);
    if (method == "embree") return s["embree"]["build_time_s"].get<double>() + s["embree"]["trace_time_s"].get<double>();
    return t["penumbra_cast_time_s"].get<double>();
}

/// Receivers of the bake's first pass: all of them unless the kind refined (camera antialiasing
/// adds receivers where the first pass's V changes, so their count and places depend on the method).
uint64_t firstPassReceivers(const json& s) {
    const uint64_t all = s["receivers"].get<uint64_t>();
    if (!s.contains("antialias") || !s["antialias"].contains("added_receivers")) return all;
    return all - std::min(all, s["antialias"]["added_receivers"].get<uint64_t>());
}

/// A --methods entry: a caster's name, or "penumbra-map:LOOKUP" for the preview with one of its
/// lookups (the bake's --penumbra-map-lookup), so both can be measured in one run.
struct MethodSpec {
    std::string caster;
    std::vector<std::string> args;  ///< extra bake flags
};

MethodSpec methodSpec(const std::string& name) {
    const size_t colon = name.find(':');
    if (colon == std::string::npos) return {name, {}};
    if (name.substr(0, colon) != "penumbra-map")
        fail("--methods", "\"{}\": only penumbra-map takes a variant (penumbra-map:backprojection or penumbra-map:wyman-hansen)", name);
    const std::string lookup = name.substr(colon + 1);
    if (lookup != "backprojection" && lookup != "wyman-hansen")
        fail("--methods", "\"{}\": the penumbra-map lookup must be backprojection or wyman-hansen", name);
    return {"penumbra-map", {"--penumbra-map-lookup", lookup}};
}

/// What the JSON keeps of one timed bake.
json columns(const json& s, const std::string& method) {
    json c = {{"time_s", methodSeconds(s, method)},
              {"bake_total_s", s["table2"]["total_time_s"]},
              {"scan_s", s["stream"]["scan_time_s"]},
              {"process_wall_s", s["child_wall_s"]},
              {"process_cpu_s", s["child_cpu_s"]},
              {"peak_rss_bytes", s["child_peak_rss_bytes"]},
              {"receivers", s["receivers"]},
              {"first_pass_receivers", firstPassReceivers(s)},
              {"light_samples", s["light_samples"]},
              {"triangles", s["counters"]["triangles_read"]}};
    for (const char* section : {"ssv", "penumbra-map", "hh", "embree"})
        if (s.contains(section)) c[section] = s[section];
    return c;
}

/// Mean and largest |V_a - V_b| over the first @p count receivers of two --visibility files, and
/// the share above 0.1. The bakes share their first pass (every receiver unless the scene refines:
/// a refinement appends receivers chosen from each method's own V), so that is what is compared.
json visibilityError(const std::string& a, const std::string& b, uint64_t count) {
    const std::vector<float> va = npyAsFloat32(readNpy(a), a), vb = npyAsFloat32(readNpy(b), b);
    if (count > std::min(va.size(), vb.size())) return {{"error", fmt::format("{} or {} holds fewer than {} receivers", a, b, count)}};
    double sum = 0, largest = 0, meanA = 0, meanB = 0;
    uint64_t off = 0;
    for (size_t i = 0; i < count; ++i) {
        const double d = std::abs(double(va[i]) - double(vb[i]));
        sum += d, largest = std::max(largest, d), off += d > 0.1, meanA += va[i], meanB += vb[i];
    }
    const double n = double(std::max<size_t>(1, count));
    return {{"mean_abs_dv", sum / n}, {"max_abs_dv", largest}, {"fraction_above_0_1", double(off) / n},
            {"mean_v", meanA / n}, {"mean_v_hpc", meanB / n}, {"compared_receivers", count}};
}

/// Relations decided differently from hpc's dump, with ties classified against the scene.
json mismatches(const fs::path& scene, const fs::path& hpcDump, const std::string& method, int threads, const fs::path& work,
                const std::vector<std::string>& extra) {
    const fs::path dump = work / ("dump-" + method);
    std::vector<std::string> args = extra;
    args.insert(args.end(), {"--dump", dump.string()});
    json b = bakeChild(scene, method, threads, work, args);
    if (b.contains("error")) return b;
    ChildResult c = compareDumps(hpcDump, dump, scene, work);
    std::error_code ec;
    fs::remove_all(dump, ec);
    if (c.exitCode != 0 && c.exitCode != 3) return {{"error", fmt::format("compare exited with {}: {}", c.exitCode, lastLine(c.err))}};
    auto v = parseCompare(c.out);
    const uint64_t differing = v["only_a"] + v["only_b"];
    return {{"relations", v["relations"]}, {"only_hpc", v["only_a"]}, {"only_method", v["only_b"]}, {"mismatches", differing},
            {"ties", v["ties"]}, {"non_ties", differing - v["ties"]}, {"compare_s", c.wallSeconds}};
}

/// Runs @p method on @p file, timed (best of repeat), with its error against hpc's visibility
/// and, for exact methods, its mismatches against hpc's dump.
json runMethod(const BenchMethodsOptions& o, const std::string& method, const fs::path& file, const fs::path& work,
               const fs::path& hpcVisibility, const fs::path& hpcDump, uint64_t hpcFirstPass) {
    const MethodSpec spec = methodSpec(method);
    std::vector<std::string> extra = spec.args;
    if (casterEntry(spec.caster).traits.holdsScene) extra.insert(extra.end(), {"--disable", "sort"});  // reads the scene once: no use for buckets
    std::string fileName = method;
    std::replace(fileName.begin(), fileName.end(), ':', '-');
    const fs::path visibility = work / ("v-" + fileName + ".npy");
    std::vector<std::string> timed = extra;
    timed.insert(timed.end(), {"--visibility", visibility.string()});
    json s = bestOf(o.repeat, [&](const json& x) { return methodSeconds(x, method); },
                    [&] { return bakeChild(file, spec.caster, o.threads, work, timed); });
    if (s.contains("error")) return s;
    json c = columns(s, method);
    if (method == "hpc") return c;
    const uint64_t firstPass = c["first_pass_receivers"].get<uint64_t>();
    c["error_vs_hpc"] = firstPass == hpcFirstPass
                            ? visibilityError(visibility.string(), hpcVisibility.string(), firstPass)
                            : json{{"error", fmt::format("first passes of {} and {} receivers differ", firstPass, hpcFirstPass)}};
    if (casterEntry(spec.caster).traits.masks && !o.noCompare)
        c["mismatches_vs_hpc"] = mismatches(file, hpcDump, spec.caster, o.threads, work, extra);
    return c;
}

/// hpc's timed run, visibility and (unless --no-compare) dump of @p file; then every method.
json runRow(const BenchMethodsOptions& o, const fs::path& file, const fs::path& work, const std::vector<std::string>& methods,
            const std::function<void(const std::string&)>& progress) {
    json row = {{"methods", json::object()}};
    const fs::path hpcVisibility = work / "v-hpc.npy", hpcDump = work / "dump-hpc";
    json hpc = runMethod(o, "hpc", file, work, hpcVisibility, hpcDump, 0);
    row["methods"]["hpc"] = hpc;
    if (hpc.contains("error")) return row;
    if (!o.noCompare) {
        json d = bakeChild(file, "hpc", o.threads, work, {"--dump", hpcDump.string()});
        if (d.contains("error")) row["hpc_dump_error"] = d["error"];
    }
    progress(fmt::format("hpc {:.2f} s", hpc["time_s"].get<double>()));
    const double hpcSeconds = hpc["time_s"].get<double>();
    for (const std::string& m : methods) {
        if (m == "reference") {
            const double tests = hpc["receivers"].get<double>() * hpc["light_samples"].get<double>() * hpc["triangles"].get<double>();
            if (tests > o.referenceLimit) {
                row["methods"][m] = {{"skipped", fmt::format("infeasible: {:.2g} relation-triangle tests (limit --reference-limit {:.2g})",
                                                              tests, o.referenceLimit)}};
                continue;
            }
        }
        json c = runMethod(o, m, file, work, hpcVisibility, hpcDump, hpc["first_pass_receivers"].get<uint64_t>());
        if (!c.contains("error")) c["speedup_vs_hpc"] = hpcSeconds / std::max(1e-9, c["time_s"].get<double>());
        std::string line = c.contains("error") ? c["error"].get<std::string>() : fmt::format("{:.2f} s", c["time_s"].get<double>());
        if (c.contains("error_vs_hpc") && c["error_vs_hpc"].contains("mean_abs_dv"))
            line += fmt::format(", mean |dV| {:.4f}", c["error_vs_hpc"]["mean_abs_dv"].get<double>());
        if (c.contains("mismatches_vs_hpc") && c["mismatches_vs_hpc"].contains("mismatches"))
            line += fmt::format(", mismatches {} ({} ties)", c["mismatches_vs_hpc"]["mismatches"].get<uint64_t>(),
                                c["mismatches_vs_hpc"]["ties"].get<uint64_t>());
        progress(m + " " + line);
        row["methods"][m] = c;
    }
    std::error_code ec;
    fs::remove_all(hpcDump, ec);
    return row;
}

/// Removes @p work except the visible fractions this process read: an input stays recorded until
/// the command ends (InputFile.h), and a later output given the inode of a deleted one would be
/// refused as that input. TempDir removes them at the end.
void removeAllButRead(const fs::path& work) {
    std::error_code ec;
    for (const fs::directory_entry& e : fs::directory_iterator(work, ec))
        if (e.path().filename().string().rfind("v-", 0) != 0) fs::remove_all(e.path(), ec);
}

std::pair<int, int> parseSize(const std::string& text) {
    int w = 0, h = 0;
    char x = 0;
    if (std::sscanf(text.c_str(), "%d%c%d", &w, &x, &h) != 3 || x != 'x' || w < 1 || h < 1 || w > 16384 || h > 16384)
        fail("--sizes", "expected WIDTHxHEIGHT such as 640x480, got \"{}\"", text);
    return {w, h};
}

}  // namespace

CLI::App* addBenchMethodsCommand(CLI::App& bench, BenchMethodsOptions& o) {
    CLI::App* cmd = bench.add_subcommand("methods", "every method on the Table 2 scenes: time, peak RSS, mismatches and errors against hpc");
    cmd->add_option("--scenes", o.scenes, "scene names in --examples or .json paths (default grids,flowers,sponza-like)")->delimiter(',');
    cmd->add_option("--sizes", o.sizes, "camera sizes (default 640x480,1280x960)")->delimiter(',');
    cmd->add_option("--methods", o.methods,
                    "methods besides hpc, which every row runs (default embree,ssv,penumbra-map,reference,hh); penumbra-map:wyman-hansen or "
                    "penumbra-map:backprojection bakes the preview with that lookup")
        ->delimiter(',');
    cmd->add_option("--lightmap", o.lightmap, "the scene hh runs on (default lightmap)");
    cmd->add_option("--hh-samples", o.hhSamples, "light samples for the hh rows (default 64,256,1024)")->delimiter(',');
    cmd->add_option("--scale", o.scale, "resolution factor for a quick run (default 1)");
    cmd->add_option("--threads", o.threads, "threads for every bake (default: all cores)");
    cmd->add_option("--repeat", o.repeat, "timed runs per method; the fastest is kept (default 1)");
    cmd->add_option("--reference-limit", o.referenceLimit, "skip the reference beyond this many relation-triangle tests (default 2e10)");
    cmd->add_option("--json", o.jsonPath, "write the result as JSON (rewritten after every row)");
    cmd->add_option("--markdown", o.markdownPath, "regenerate the Methods section of this BENCHMARKS.md");
    cmd->add_option("--examples", o.examplesDir, "directory of the scene files (default ./examples)");
    cmd->add_option("--tmp", o.tmpDir, "directory for scenes, dumps and bucket files (default: the system temp dir)");
    cmd->add_flag("--no-compare", o.noCompare, "skip the --dump runs that count mismatches against hpc");
    cmd->add_flag("-q,--quiet", o.quiet, "no progress lines on stderr");
    cmd->add_option("--render", o.renderPath,
                    "bake nothing: print (and with --markdown splice) the Markdown of a JSON result written by an earlier run");
    return cmd;
}

void runBenchMethods(const BenchMethodsOptions& given, const std::string& commandLine) {
    BenchMethodsOptions o = given;  // "hpc" in --methods is no error: every row runs it as the baseline
    o.methods.erase(std::remove(o.methods.begin(), o.methods.end(), "hpc"), o.methods.end());
    checkDistinctFiles({{"--render", o.renderPath}, {"--json", o.jsonPath}, {"--markdown", o.markdownPath}});
    checkMarkdownFile(o.markdownPath);
    if (!o.renderPath.empty()) {
        json result;
        checkInputFile(o.renderPath);  // "cannot open", not a parse error of nothing
        try {
            result = json::parse(slurpFile(o.renderPath));
            writeMethodsMarkdown(result, o.markdownPath);
        } catch (const json::exception& e) {
            fail("--render", "{}: not a result of bench methods ({})", o.renderPath, e.what());
        }
        return;
    }
    if (!(o.scale > 0.0 && o.scale <= 4.0)) fail("--scale", "must be in (0, 4], got {}", o.scale);
    if (o.repeat < 1 || o.repeat > 100) fail("--repeat", "must be in 1..100, got {}", o.repeat);
    if (o.threads < 0 || o.threads > 1024) fail("--threads", "must be in 0..1024, got {}", o.threads);
    std::vector<std::string> known = casterNames();
    known.erase(std::remove(known.begin(), known.end(), "hpc"), known.end());
    for (const std::string& m : o.methods)
        if (std::find(known.begin(), known.end(), methodSpec(m).caster) == known.end())
            fail("--methods", "unknown method \"{}\" (known: {}; and penumbra-map:LOOKUP)", m, fmt::join(known, ", "));
    for (int k : o.hhSamples)
        if (k < 1 || k > 65536) fail("--hh-samples", "each count must be in 1..65536, got {}", k);
    std::vector<std::pair<int, int>> sizes;
    for (const std::string& s : o.sizes) sizes.push_back(parseSize(s));
    std::vector<std::pair<std::string, json>> scenes;
    for (const std::string& name : o.scenes) scenes.emplace_back(sceneName(name), benchCameraScene(o.examplesDir, name));
    const bool hh = std::find(o.methods.begin(), o.methods.end(), "hh") != o.methods.end();
    // Before any row: a --lightmap that hh cannot bake failed its rows after every camera row.
    const json lightmapScene = hh ? benchSceneOf(o.examplesDir, o.lightmap, "lightmap", "--lightmap", "hh bakes lightmap receivers")
                                  : json();
    std::vector<std::string> cameraMethods;
    for (const std::string& m : o.methods)
        if (m != "hh") cameraMethods.push_back(m);

    TempDir tmp(o.tmpDir);
    json result = {{"command", commandLine}, {"date", utcNow()}, {"machine", machineInfo()}, {"scale", o.scale},
                   {"repeat", o.repeat}, {"threads", o.threads > 0 ? o.threads : int(tbb::info::default_concurrency())},
                   {"load_average_start", loadAverage()}, {"rows", json::array()}, {"hh", json::array()}};
    const auto start = std::chrono::steady_clock::now();
    auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
    auto save = [&] {
        result["elapsed_s"] = elapsed();
        if (!o.jsonPath.empty()) writeText(o.jsonPath, result.dump(2) + "\n");
    };
    for (const auto& [name, base] : scenes)
        for (const auto& [width, height] : sizes) {
            const int w = std::max(8, int(std::lround(width * o.scale))), h = std::max(6, int(std::lround(height * o.scale)));
            const fs::path work = tmp.path / fmt::format("{}-{}x{}", name, width, height);
            fs::create_directories(work);
            const fs::path file = work / "scene.json";
            writeText(file.string(), resizedScene(base, w, h, 256, 1.0, work / "out.exr").dump(2));
            auto progress = [&, n = name, ww = w, hh2 = h](const std::string& line) {
                if (!o.quiet) fmt::print(stderr, "[methods] {} {}x{}: {} [{:.0f} s]\n", n, ww, hh2, line, elapsed());
            };
            json row = runRow(o, file, work, cameraMethods, progress);
            row["scene"] = name, row["width"] = w, row["height"] = h, row["nominal"] = fmt::format("{}x{}", width, height);
            result["rows"].push_back(row);
            removeAllButRead(work);
            save();
        }
    if (hh) {
        for (int samples : o.hhSamples) {
            const fs::path work = tmp.path / fmt::format("hh-{}", samples);
            fs::create_directories(work);
            json scene = lightmapScene;
            for (json& light : scene["lights"]) light["samples"] = samples;
            scene["output"] = (work / "out.exr").string();
            const fs::path file = work / "scene.json";
            writeText(file.string(), scene.dump(2));
            auto progress = [&](const std::string& line) {
                if (!o.quiet) fmt::print(stderr, "[methods] hh at {} samples: {} [{:.0f} s]\n", samples, line, elapsed());
            };
            json row = runRow(o, file, work, {"hh"}, progress);
            row["scene"] = sceneName(o.lightmap), row["samples"] = samples;
            result["hh"].push_back(row);
            removeAllButRead(work);
            save();
        }
    }
    result["load_average_end"] = loadAverage();
    result["bench_process_peak_rss_bytes"] = peakRssBytes();
    save();
    writeMethodsMarkdown(result, o.markdownPath);
}

void writeMethodsMarkdown(const json& result, const std::string& markdownPath) {
    const std::string md = methodsMarkdown(result);
    if (!markdownPath.empty()) writeText(markdownPath, replaceMethodsSection(fs::exists(markdownPath) ? slurpFile(markdownPath) : "", md));
    fmt::print("{}", md);
}

}  // namespace penumbra
