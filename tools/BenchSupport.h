#pragma once
/// @file BenchSupport.h
/// @brief What the benchmarks share: bakes in child processes (so peak RSS is each bake's own),
/// the machine and load they ran on, scene files resized for a row, and the generated sections
/// they splice into docs/BENCHMARKS.md.

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace penumbra {

std::string slurpFile(const std::string& path);
/// Writes @p text to @p path atomically, creating its folder.
void writeText(const std::string& path, const std::string& text);
/// @brief Refuses two of a bench's files naming one file (`--json X --markdown X` wrote the JSON
/// and spliced the Markdown section into it, losing the document): pairs of option and path,
/// empty paths ignored.
/// @throw InputError naming the second option.
void checkDistinctFiles(const std::vector<std::pair<std::string, std::string>>& files);
/// @brief Refuses a bench's `--markdown` file that is not a `.md` file, before any work.
/// @throw InputError naming the file.
void checkMarkdownFile(const std::string& path);
/// CPU, cores, RAM, OS, compiler and commit, for the record.
nlohmann::json machineInfo();
/// The 1-minute load average: on a shared machine it says how many cores the bench really had.
double loadAverage();
std::string utcNow();

/// A finished child process: exit status, wall time, peak RSS and what it printed.
struct ChildResult {
    int exitCode = -1;
    double wallSeconds = 0;
    uint64_t peakRssBytes = 0;  ///< wait4() ru_maxrss: this child's own peak
    double cpuSeconds = 0;      ///< user + system time of the child, all its threads
    std::string out, err;
};

/// @brief Runs this executable with @p args in a child process, stdout and stderr to files in @p dir.
ChildResult runSelf(const std::vector<std::string>& args, const std::filesystem::path& dir);
/// Last non-empty line of a child's stderr, for error records.
std::string lastLine(const std::string& text);

/// @brief A benchmark's temporary directory, removed with its contents when the benchmark ends,
/// throws or is interrupted.
///
/// While it lives, SIGINT, SIGTERM, SIGHUP and SIGQUIT are forwarded to the running child bake
/// (runSelf()), which removes its own temporaries and dies; the benchmark then unwinds, and this
/// destructor removes the directory and ends the process by the same signal (exit 128 + N), so
/// `kill` leaves no child running and no `penumbra-bench-*` folder behind. Not nestable.
struct TempDir {
    std::filesystem::path path;
    explicit TempDir(const std::string& parent);
    ~TempDir();
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;
};

/// @brief Runs one bake in a child and returns its stats with the child's wall time, CPU time and
/// peak RSS added (or {"error": ...}).
nlohmann::json bakeChild(const std::filesystem::path& scene, const std::string& method, int threads,
                         const std::filesystem::path& work, const std::vector<std::string>& extra = {});

/// The fastest of @p repeat bakes by @p seconds (errors win only if every run failed).
template <class Seconds>
nlohmann::json bestOf(int repeat, Seconds seconds, const std::function<nlohmann::json()>& run) {
    nlohmann::json best;
    for (int i = 0; i < repeat; ++i) {
        nlohmann::json s = run();
        if (s.contains("error")) {
            if (best.is_null()) best = s;
            continue;
        }
        if (best.is_null() || best.contains("error") || seconds(s) < seconds(best)) best = s;
    }
    return best;
}

/// Parses `penumbra compare` output: its "key value" lines (the listed mismatches are skipped).
std::map<std::string, uint64_t> parseCompare(const std::string& text);

/// @brief hpc's time in the paper's Table 2 sense from a bake's stats: sort + hierarchy build +
/// penumbra cast, all wall-clock. The build is the first builds' wall time
/// (`table2.hierarchy_build_wall_s`; rebuilds run during the cast and are in its wall time);
/// stats of older binaries without it give their thread-seconds of all builds.
double hpcPaperSeconds(const nlohmann::json& stats);
/// @brief The hierarchy build column of hpcPaperSeconds().
double hpcBuildWallSeconds(const nlohmann::json& stats);

/// @brief A scene name in @p examplesDir ("grids") or a .json path. @throw InputError when missing.
std::filesystem::path benchSceneFile(const std::string& examplesDir, const std::string& name);
std::string sceneName(const std::string& name);

/// @brief @p scene with its camera at @p width x @p height, every light at @p samples samples
/// with u and v scaled by @p lightScale, writing its output to @p output.
nlohmann::json resizedScene(nlohmann::json scene, int width, int height, int samples, double lightScale,
                            const std::filesystem::path& output);

/// @brief Scene @p name of @p examplesDir (as benchSceneFile() finds it), with every relative
/// input path (geometry and receiver `path`, `leaf_texture`, `petal_texture`) made absolute from
/// the scene's folder, so that the copies the benches write elsewhere read the same files. Their
/// children bake and compare those copies with --allow-outside-uris (bakeChild(), compareDumps()).
nlohmann::json benchScene(const std::string& examplesDir, const std::string& name);

/// @brief benchScene(), refused unless its receivers are of @p kind ("camera", "lightmap").
/// @param option and @p why name the option that gave the scene and what needs that kind
/// @throw InputError "OPTION: FILE: WHY, and this scene's receivers are \"TYPE\""
nlohmann::json benchSceneOf(const std::string& examplesDir, const std::string& name, const std::string& kind, const char* option,
                            const char* why);

/// @brief benchScene() for the benches that resize a camera (table2, methods).
/// @throw InputError naming the scene file when its receivers are not a camera.
nlohmann::json benchCameraScene(const std::string& examplesDir, const std::string& name);

/// @brief `penumbra compare @p a @p b --scene @p scene` in a child process, run in @p dir.
ChildResult compareDumps(const std::filesystem::path& a, const std::filesystem::path& b, const std::filesystem::path& scene,
                         const std::filesystem::path& dir);

/// @brief Replaces the part of @p document between @p begin and @p end (marker lines) with
/// @p generated; without markers, appends @p heading and the markers. Other sections are kept.
std::string replaceGeneratedSection(const std::string& document, const std::string& begin, const std::string& end,
                                    const std::string& heading, const std::string& generated);

}  // namespace penumbra
