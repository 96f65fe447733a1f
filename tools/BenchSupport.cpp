#include "BenchSupport.h"

#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/util/JsonParams.h"
#include "stream/util/PathText.h"
#include "stream/util/StopRequest.h"
#include "stream/util/TempRegistry.h"

#include <fmt/format.h>
#include <tbb/info.h>

#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/utsname.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <span>
#include <sstream>

extern char** environ;

namespace penumbra {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr int kForwardedSignals[] = {SIGINT, SIGTERM, SIGHUP, SIGQUIT};
std::atomic<pid_t> g_child{0};                ///< the running child bake, 0 between children
volatile std::sig_atomic_t g_interrupted = 0;  ///< the first forwarded signal, 0 if none
struct sigaction g_before[std::size(kForwardedSignals)];
bool g_forwarding = false;

extern "C" void forwardToChild(int sig) {
    if (!g_interrupted) g_interrupted = sig;
    if (const pid_t child = g_child.load(); child > 0) ::kill(child, sig);
}

/// Throws after a forwarded signal: the benchmark unwinds to TempDir, which ends the process.
void throwIfInterrupted() {
    if (g_interrupted) throw StopRequested(fmt::format("bench: interrupted by signal {}", int(g_interrupted)));
}

/// Output of a shell command's first line ("" on failure); for `git rev-parse` and the like.
std::string commandOutput(const std::string& command) {
    std::FILE* pipe = ::popen((command + " 2>/dev/null").c_str(), "r");
    if (!pipe) return "";
    char buffer[512];
    std::string out;
    if (std::fgets(buffer, sizeof buffer, pipe)) out = buffer;
    ::pclose(pipe);
    while (!out.empty() && (out.back() == '\n' || out.back() == '\r')) out.pop_back();
    return out;
}

/// The first "KEY: value" line's value of a /proc-style file, or "".
std::string procField(const std::string& path, const std::string& key) {
    std::ifstream in(path);
    for (std::string line; std::getline(in, line);)
        if (line.rfind(key, 0) == 0) {
            auto colon = line.find(':');
            if (colon == std::string::npos) continue;
            std::string v = line.substr(colon + 1);
            v.erase(0, v.find_first_not_of(" \t"));
            return v;
        }
    return "";
}

}  // namespace

std::string slurpFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

void writeText(const std::string& path, const std::string& text) {
    ensureParentDirectory(path);
    writeFileAtomically(path, std::span(reinterpret_cast<const uint8_t*>(text.data()), text.size()));
}

void checkDistinctFiles(const std::vector<std::pair<std::string, std::string>>& files) {
    for (size_t i = 0; i < files.size(); ++i)
        for (size_t j = 0; j < i; ++j) {
            if (files[i].second.empty() || files[j].second.empty()) continue;
            std::error_code ec;
            const bool same = comparablePath(files[i].second) == comparablePath(files[j].second) ||
                              fs::equivalent(files[i].second, files[j].second, ec);  // links to one existing file
            if (same) fail(files[i].first, "names the same file as {} ({}); give each its own file", files[j].first, files[i].second);
        }
}

void checkMarkdownFile(const std::string& path) {
    if (path.empty() || fs::path(path).extension() == ".md") return;
    // The section is spliced into the file, or appended to one that has none: into a script or a
    // README.txt given by mistake, it went without a word.
    fail("--markdown", "{}: not a Markdown file (.md); the bench splices its generated section into a BENCHMARKS.md", path);
}

json machineInfo() {
    std::string os;
    std::ifstream osRelease("/etc/os-release");
    for (std::string line; std::getline(osRelease, line);)
        if (line.rfind("PRETTY_NAME=", 0) == 0) {
            os = line.substr(12);
            os.erase(std::remove(os.begin(), os.end(), '"'), os.end());
        }
    struct utsname u {};
    if (::uname(&u) == 0) os += std::string(os.empty() ? "" : ", ") + u.sysname + " " + u.release;
    uint64_t ramKiB = 0;
    std::sscanf(procField("/proc/meminfo", "MemTotal").c_str(), "%llu", reinterpret_cast<unsigned long long*>(&ramKiB));
    std::string commit = commandOutput("git rev-parse --short HEAD");
    if (commit.empty()) commit = "unknown";
    else if (!commandOutput("git status --porcelain --untracked-files=no").empty()) commit += " (uncommitted changes)";
#if defined(__clang__)
    const std::string compiler = std::string("clang ") + __clang_version__;
#elif defined(__GNUC__)
    const std::string compiler = std::string("gcc ") + __VERSION__;
#else
    const std::string compiler = "unknown";
#endif
#ifdef NDEBUG
    const bool optimized = true;
#else
    const bool optimized = false;
#endif
    return {{"cpu", procField("/proc/cpuinfo", "model name")},
            {"cores", tbb::info::default_concurrency()},
            {"ram_bytes", ramKiB * 1024},
            {"os", os},
            {"compiler", compiler},
            {"assertions_off", optimized},
            {"commit", commit}};
}

/// The 1-minute load average: on a shared machine it says how many cores the bench really had.
double loadAverage() {
    double load = -1;
    if (std::FILE* f = std::fopen("/proc/loadavg", "r")) {
        if (std::fscanf(f, "%lf", &load) != 1) load = -1;
        std::fclose(f);
    }
    return load;
}

std::string utcNow() {
    std::time_t t = std::time(nullptr);
    char buffer[32];
    std::strftime(buffer, sizeof buffer, "%Y-%m-%d %H:%M UTC", std::gmtime(&t));
    return buffer;
}

/// Runs this executable with @p args in a child process, stdout and stderr to files in @p dir.
ChildResult runSelf(const std::vector<std::string>& args, const fs::path& dir) {
    static const std::string self = fs::read_symlink("/proc/self/exe").string();
    const std::string outPath = (dir / "child.out").string(), errPath = (dir / "child.err").string();
    std::vector<std::string> argvText{self};
    argvText.insert(argvText.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (std::string& a : argvText) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    throwIfInterrupted();  // before the actions exist, so that nothing leaks
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, outPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&actions, 2, errPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const auto start = std::chrono::steady_clock::now();
    pid_t pid = 0;
    int rc = posix_spawn(&pid, self.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (rc != 0) fail(self, "cannot start a child process: {}", std::strerror(rc));
    g_child.store(pid);
    if (const int sig = g_interrupted) ::kill(pid, sig);  // arrived before the pid was known
    int status = 0;
    struct rusage usage {};
    while (::wait4(pid, &status, 0, &usage) < 0)
        if (errno != EINTR) g_child.store(0), fail(self, "wait4 failed: {}", std::strerror(errno));
    g_child.store(0);
    throwIfInterrupted();
    ChildResult r;
    r.wallSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    r.peakRssBytes = uint64_t(usage.ru_maxrss) * 1024;
    r.cpuSeconds = double(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) + 1e-6 * double(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
    r.out = slurpFile(outPath);
    r.err = slurpFile(errPath);
    return r;
}

/// Last non-empty line of a child's stderr, for error records.
std::string lastLine(const std::string& text) {
    std::string t = text;
    while (!t.empty() && (t.back() == '\n' || t.back() == '\r')) t.pop_back();
    auto nl = t.rfind('\n');
    return nl == std::string::npos ? t : t.substr(nl + 1);
}

TempDir::TempDir(const std::string& parent) {
    fs::path base = parent.empty() ? fs::temp_directory_path() : fs::path(parent);
    std::string pattern = (base / "penumbra-bench-XXXXXX").string();
    if (!::mkdtemp(pattern.data())) fail(base.string(), "cannot create a temporary directory: {}", std::strerror(errno));
    path = pattern;
    struct sigaction action {};
    action.sa_handler = forwardToChild;
    sigemptyset(&action.sa_mask);
    for (size_t i = 0; i < std::size(kForwardedSignals); ++i) {
        ::sigaction(kForwardedSignals[i], nullptr, &g_before[i]);
        if (g_before[i].sa_handler != SIG_IGN) ::sigaction(kForwardedSignals[i], &action, nullptr);  // nohup stays nohup
    }
    g_forwarding = true;
}

TempDir::~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
    if (!g_forwarding) return;
    for (size_t i = 0; i < std::size(kForwardedSignals); ++i) ::sigaction(kForwardedSignals[i], &g_before[i], nullptr);
    g_forwarding = false;
    if (const int sig = g_interrupted) {  // end as the signal would have, now that nothing is left behind
        removeRegisteredTempFiles();
        ::signal(sig, SIG_DFL);
        ::raise(sig);
    }
}

json bakeChild(const fs::path& scene, const std::string& method, int threads, const fs::path& work,
               const std::vector<std::string>& extra) {
    const std::string stats = (work / "stats.json").string();
    std::error_code ec;
    fs::remove(stats, ec);
    // The bench writes its scenes into its own directory, with their inputs' paths anchored where
    // the original scene lives (benchScene()): those lie outside the copy's directory.
    std::vector<std::string> args{"bake", scene.string(), "--method", method, "-q", "--stats", stats,
                                  "--tmp", work.string(), "--allow-outside-uris"};
    if (threads > 0) args.insert(args.end(), {"--threads", std::to_string(threads)});
    args.insert(args.end(), extra.begin(), extra.end());
    ChildResult child = runSelf(args, work);
    if (child.exitCode != 0)
        return {{"error", fmt::format("bake --method {} exited with {}: {}", method, child.exitCode, lastLine(child.err))}};
    json s = json::parse(slurpFile(stats));
    s["child_peak_rss_bytes"] = child.peakRssBytes;
    s["child_wall_s"] = child.wallSeconds;
    s["child_cpu_s"] = child.cpuSeconds;
    return s;
}

std::map<std::string, uint64_t> parseCompare(const std::string& text) {
    // "key value" lines; the listed mismatches ("mismatch receiver 12 sample 3 ...") are skipped.
    std::map<std::string, uint64_t> values;
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);) {
        std::istringstream fields(line);
        std::string key, rest;
        unsigned long long v = 0;
        if (fields >> key >> v && !(fields >> rest)) values[key] = v;
    }
    return values;
}

fs::path benchSceneFile(const std::string& examplesDir, const std::string& name) {
    fs::path p = name.size() > 5 && name.substr(name.size() - 5) == ".json" ? fs::path(name) : fs::path(examplesDir) / (name + ".json");
    if (!fs::is_regular_file(p))
        fail("--scenes", "no scene file {} (scene names are looked up in --examples, default ./examples)", p.string());
    return p;
}

std::string sceneName(const std::string& name) { return fs::path(name).stem().string(); }


json resizedScene(json scene, int width, int height, int samples, double lightScale, const fs::path& output) {
    scene["receivers"]["width"] = width;
    scene["receivers"]["height"] = height;
    for (json& light : scene["lights"]) {
        light["samples"] = samples;
        if (lightScale != 1.0)
            for (const char* axis : {"u", "v"})
                for (json& c : light[axis]) c = c.get<double>() * lightScale;
    }
    scene["output"] = output.string();
    return scene;
}

namespace {
void anchorPaths(json& j, const fs::path& sourceDir) {
    if (j.is_array()) {
        for (json& e : j) anchorPaths(e, sourceDir);
        return;
    }
    if (!j.is_object()) return;
    for (auto it = j.begin(); it != j.end(); ++it) {
        const bool input = it.key() == "path" || it.key() == "leaf_texture" || it.key() == "petal_texture";
        if (input && it->is_string() && fs::path(it->get<std::string>()).is_relative())
            *it = fs::absolute(sourceDir / it->get<std::string>()).lexically_normal().string();
        else
            anchorPaths(*it, sourceDir);
    }
}
}  // namespace

json benchSceneOf(const std::string& examplesDir, const std::string& name, const std::string& kind, const char* option,
                  const char* why) {
    json scene = benchScene(examplesDir, name);
    const json* receivers = scene.contains("receivers") ? &scene["receivers"] : nullptr;
    const std::string type = receivers && receivers->is_object() && receivers->contains("type") && (*receivers)["type"].is_string()
                                 ? (*receivers)["type"].get<std::string>()
                                 : "?";
    // Any other kind's bake would fail in every row, after the rows before it had run.
    if (type != kind)
        fail(option, "{}: {}, and this scene's receivers are \"{}\"", benchSceneFile(examplesDir, name).string(), why, type);
    return scene;
}

json benchCameraScene(const std::string& examplesDir, const std::string& name) {
    return benchSceneOf(examplesDir, name, "camera", "--scenes", "the bench sets a camera's image size");
}

json benchScene(const std::string& examplesDir, const std::string& name) {
    const fs::path file = benchSceneFile(examplesDir, name);
    json scene = readJsonFile(file.string());
    for (const char* section : {"geometry", "receivers"})
        if (scene.contains(section)) anchorPaths(scene[section], file.parent_path());
    return scene;
}

ChildResult compareDumps(const fs::path& a, const fs::path& b, const fs::path& scene, const fs::path& dir) {
    return runSelf({"compare", a.string(), b.string(), "--scene", scene.string(), "--allow-outside-uris"}, dir);
}

std::string replaceGeneratedSection(const std::string& document, const std::string& begin, const std::string& end,
                                    const std::string& heading, const std::string& generated) {
    const std::string block = begin + "\n\n" + generated + "\n" + end + "\n";
    const size_t b = document.find(begin), e = document.find(end);
    if (b != std::string::npos && e != std::string::npos && e > b) {
        size_t after = e + end.size();
        if (after < document.size() && document[after] == '\n') ++after;
        return document.substr(0, b) + block + document.substr(after);
    }
    std::string doc = document;
    if (!doc.empty() && doc.back() != '\n') doc += '\n';
    return doc + "\n" + heading + "\n\n" + block;
}

double hpcBuildWallSeconds(const nlohmann::json& stats) {
    const nlohmann::json& t = stats.at("table2");
    return (t.contains("hierarchy_build_wall_s") ? t["hierarchy_build_wall_s"] : t.at("hierarchy_build_time_s")).get<double>();
}

double hpcPaperSeconds(const nlohmann::json& stats) {
    const nlohmann::json& t = stats.at("table2");
    return t.at("sort_time_s").get<double>() + hpcBuildWallSeconds(stats) + t.at("penumbra_cast_time_s").get<double>();
}

}  // namespace penumbra
