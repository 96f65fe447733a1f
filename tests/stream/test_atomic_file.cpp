// Tests for AtomicFile, writeFileAtomically, ensureParentDirectory and the temp-file registry.
//
// Two scenarios cannot be staged inside the test process itself: a full disk (emulated with
// RLIMIT_FSIZE, which would also limit Catch's own output files) and death by SIGTERM. For
// those the test binary re-executes itself, running a hidden helper test case in a fresh
// process with the limit or the signal applied there.

#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"

#include "TestSupport.h"

#include <catch2/catch.hpp>

#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>


using namespace penumbra::test;
namespace fs = std::filesystem;
using penumbra::AtomicFile;
using penumbra::InputError;

namespace {

/// A fresh directory under the system temp dir, removed with everything in it.
/// Runs this test binary again on the hidden test case tagged @p tag, with
/// PENUMBRA_IO_HELPER_DIR=@p dir in its environment and, if @p fileSizeLimit > 0, that
/// RLIMIT_FSIZE and SIGXFSZ ignored (so an oversize write fails with EFBIG instead of killing).
/// Returns the wait status; the child's stdout+stderr go to @p output.
int runHelper(const std::string& tag, const std::string& dir, rlim_t fileSizeLimit, std::string& output) {
    return runSelfAsChild(tag, "PENUMBRA_IO_HELPER_DIR", dir, fileSizeLimit, output);
}

const char* helperDir() { return std::getenv("PENUMBRA_IO_HELPER_DIR"); }

/// Forces the named-temporary fallback (PENUMBRA_NO_TMPFILE) while alive, when @p on.
struct NamedTemporaries {
    explicit NamedTemporaries(bool on) : on_(on) {
        if (on_) ::setenv("PENUMBRA_NO_TMPFILE", "1", 1);
    }
    ~NamedTemporaries() {
        if (on_) ::unsetenv("PENUMBRA_NO_TMPFILE");
    }
    bool on_;
};

}  // namespace

TEST_CASE("AtomicFile commit puts the file into place", "[io]") {
    ScratchDir dir;
    const std::string target = dir.file("a.bin");
    const bool named = GENERATE(false, true);  // O_TMPFILE, and the fallback without it
    NamedTemporaries fallback(named);
    std::string expected;
    {
        AtomicFile f(target);
        CHECK(f.finalPath() == target);
        if (named) {
            CHECK(f.tempPath().rfind(target + ".tmp-" + std::to_string(::getpid()) + "-", 0) == 0);
            CHECK(fs::path(f.tempPath()).parent_path() == dir.path);
        } else {
            CHECK(f.tempPath().rfind("/proc/self/fd/", 0) == 0);
            CHECK(dir.entries().empty());  // nothing has a name before commit()
        }
        CHECK(fs::exists(f.tempPath()));
        CHECK_FALSE(fs::exists(target));

        // Small writes, then one much larger than the internal buffer, then small again.
        f.write("hello ", 6);
        std::string big(3 * 1024 * 1024 + 17, 'x');
        for (size_t i = 0; i < big.size(); ++i) big[i] = static_cast<char>('a' + i % 26);
        f.write(big.data(), big.size());
        f.write("", 0);
        f.write(" end", 4);
        expected = "hello " + big + " end";
        f.commit();
        CHECK(f.committed());
        f.commit();  // idempotent
    }
    CHECK(dir.entries() == std::vector<std::string>{"a.bin"});
    CHECK(slurp(target) == expected);
}

TEST_CASE("AtomicFile replaces an existing file only on commit", "[io]") {
    ScratchDir dir;
    const std::string target = dir.file("out.txt");
    { std::ofstream(target) << "old"; }
    {
        AtomicFile f(target);
        f.write("new", 3);
        CHECK(slurp(target) == "old");
        f.commit();
    }
    CHECK(slurp(target) == "new");
}

TEST_CASE("AtomicFile removes the temporaries a killed process left beside its file", "[io]") {
    // SIGKILL between linking the staged name and renaming it over the old file (or while a named
    // temporary is written) leaves "NAME.tmp-PID-N"; nothing can run then, so the next write of
    // the same file clears those of processes that are gone, and only those.
    ScratchDir dir;
    const std::string target = dir.file("out.exr");
    { std::ofstream(target) << "old"; }
    const pid_t child = ::fork();
    if (child == 0) ::_exit(0);
    ::waitpid(child, nullptr, 0);  // a pid that no process has now
    const std::string dead = target + ".tmp-" + std::to_string(child) + "-3";
    const std::vector<std::string> kept = {target + ".tmp-1-3", target + ".tmp-" + std::to_string(::getpid()) + "-999",
                                           target + ".tmp-x", dir.file("other.exr.tmp-" + std::to_string(child) + "-1")};
    for (const std::string& f : kept) std::ofstream(f) << "keep";
    std::ofstream(dead) << "stale";
    const bool named = GENERATE(false, true);
    NamedTemporaries fallback(named);
    AtomicFile f(target);
    f.write("new", 3);
    f.commit();
    CHECK(slurp(target) == "new");
    CHECK_FALSE(fs::exists(dead));
    for (const std::string& k : kept) CHECK(fs::exists(k));
}

TEST_CASE("AtomicFile destroyed without commit leaves nothing behind", "[io]") {
    ScratchDir dir;
    {
        AtomicFile f(dir.file("never.bin"));
        f.write("partial", 7);
    }
    CHECK(dir.entries().empty());

    { std::ofstream(dir.file("keep.bin")) << "previous"; }
    {
        AtomicFile f(dir.file("keep.bin"));
        f.write("half", 4);
    }
    CHECK(dir.entries() == std::vector<std::string>{"keep.bin"});
    CHECK(slurp(dir.file("keep.bin")) == "previous");
}

TEST_CASE("AtomicFile works with libraries that write by file name", "[io]") {
    ScratchDir dir;
    const bool named = GENERATE(false, true);
    NamedTemporaries fallback(named);
    const std::string target = dir.file("lib.dat");
    { std::ofstream(target) << "an older, longer file"; }
    {
        AtomicFile f(target);
        { std::ofstream(f.tempPath(), std::ios::binary | std::ios::trunc) << "written by name"; }
        f.commit();
    }
    CHECK(slurp(target) == "written by name");
    CHECK(dir.entries() == std::vector<std::string>{"lib.dat"});

    // A library that failed and deleted its output must not produce a final file (only a named
    // temporary can be deleted).
    if (named) {
        AtomicFile g(dir.file("gone.dat"));
        fs::remove(g.tempPath());
        std::string msg = errorOf([&] { g.commit(); });
        CHECK(msg.rfind(dir.file("gone.dat") + ": output was not written", 0) == 0);
        CHECK_FALSE(fs::exists(dir.file("gone.dat")));
    }
}

TEST_CASE("AtomicFile reports an uncreatable file in one line naming the final path", "[io]") {
    ScratchDir dir;
    SECTION("missing directory") {
        const std::string target = dir.file("missing/x.exr");
        std::string msg = errorOf([&] { AtomicFile f(target); });
        CHECK(msg == target + ": cannot create file: No such file or directory");
    }
    SECTION("parent is a regular file") {
        { std::ofstream(dir.file("plain")) << "x"; }
        const std::string target = dir.file("plain/x.exr");
        std::string msg = errorOf([&] { AtomicFile f(target); });
        CHECK(msg == target + ": cannot create file: Not a directory");
    }
    SECTION("read-only directory") {
        if (::geteuid() == 0) return;  // root ignores directory permissions
        fs::create_directory(dir.path / "ro");
        fs::permissions(dir.path / "ro", fs::perms::owner_read | fs::perms::owner_exec);
        const std::string target = dir.file("ro/x.exr");
        std::string msg = errorOf([&] { AtomicFile f(target); });
        CHECK(msg == target + ": cannot create file: Permission denied");
    }
    CHECK(std::count_if(fs::recursive_directory_iterator(dir.path), {}, [](const auto& e) {
              return e.path().filename().string().find(".tmp-") != std::string::npos;
          }) == 0);
}

TEST_CASE("writeFileAtomically and ensureParentDirectory", "[io]") {
    ScratchDir dir;
    const std::string nested = dir.file("a/b/c/out.bin");
    penumbra::ensureParentDirectory(nested);
    CHECK(fs::is_directory(dir.path / "a/b/c"));
    penumbra::ensureParentDirectory(nested);  // already there: fine
    penumbra::ensureParentDirectory("relative-file-without-dir.bin");  // nothing to create

    std::vector<uint8_t> bytes = {0, 1, 2, 255};
    penumbra::writeFileAtomically(nested, bytes);
    CHECK(slurp(nested) == std::string("\0\1\2\xff", 4));
    penumbra::writeFileAtomically(dir.file("empty.bin"), {});
    CHECK(fs::file_size(dir.file("empty.bin")) == 0);

    { std::ofstream(dir.file("file")) << "x"; }
    std::string msg = errorOf([&] { penumbra::ensureParentDirectory(dir.file("file/sub/out.bin")); });
    CHECK(msg.rfind(dir.file("file/sub/out.bin") + ": cannot create directory ", 0) == 0);
    CHECK(msg.find('\n') == std::string::npos);
}

TEST_CASE("Temp-file registry removes registered files", "[io]") {
    ScratchDir dir;
    const std::string a = dir.file("a.tmp"), b = dir.file("b.tmp");
    { std::ofstream(a) << "a"; }
    { std::ofstream(b) << "b"; }
    penumbra::registerTempFile(a);
    penumbra::registerTempFile(b);
    penumbra::unregisterTempFile(b);
    penumbra::removeRegisteredTempFiles();
    CHECK_FALSE(fs::exists(a));
    CHECK(fs::exists(b));

    // AtomicFile registers a named temporary, and unregisters it once committed.
    NamedTemporaries fallback(true);
    AtomicFile pending(dir.file("pending.bin"));
    AtomicFile done(dir.file("done.bin"));
    done.write("ok", 2);
    done.commit();
    penumbra::removeRegisteredTempFiles();
    CHECK_FALSE(fs::exists(pending.tempPath()));
    CHECK(slurp(dir.file("done.bin")) == "ok");
}

TEST_CASE("AtomicFile helper: file size limit", "[.][io-fsize-helper]") {
    if (!helperDir()) return;
    const std::string target = std::string(helperDir()) + "/big.bin";
    std::vector<uint8_t> chunk(1 << 20, 0xAB);
    std::string msg = errorOf([&] {
        AtomicFile f(target);
        for (int i = 0; i < 8; ++i) f.write(chunk.data(), chunk.size());
        f.commit();
    });
    INFO(msg);
    CHECK(msg.rfind(target + ": write failed: File too large (needed ", 0) == 0);
    CHECK(msg.find(" more bytes)") != std::string::npos);
    CHECK(msg.find('\n') == std::string::npos);
    CHECK(fs::is_empty(helperDir()));
}

TEST_CASE("AtomicFile turns a full disk into an InputError and leaves no temporary", "[io]") {
    ScratchDir dir;
    std::string output;
    int status = runHelper("[io-fsize-helper]", dir.path.string(), 256 * 1024, output);
    INFO(output);
    REQUIRE(WIFEXITED(status));
    CHECK(WEXITSTATUS(status) == 0);
    CHECK(output.find("All tests passed") != std::string::npos);
    CHECK(dir.entries().empty());
}

TEST_CASE("AtomicFile helper: killed by SIGTERM", "[.][io-signal-helper]") {
    if (!helperDir()) return;
    penumbra::installCleanupSignalHandlers();
    AtomicFile f(std::string(helperDir()) + "/interrupted.bin");
    f.write("some bytes", 10);
    ::raise(SIGTERM);
    FAIL("still alive after SIGTERM");
}

TEST_CASE("AtomicFile helper: a library caller killed by SIGTERM", "[.][io-scoped-signal-helper]") {
    if (!helperDir()) return;
    ::signal(SIGTERM, SIG_DFL);
    const penumbra::ScopedSignalCleanup cleanup;  // what the Python module holds during bake() and write()
    NamedTemporaries fallback(true);
    AtomicFile f(std::string(helperDir()) + "/interrupted.bin");
    f.write("some bytes", 10);
    ::raise(SIGTERM);
    FAIL("still alive after SIGTERM");
}

TEST_CASE("a library caller's SIGTERM removes named temporaries, and its own handlers are left alone", "[io]") {
    // Python's Result.write() with named temporaries left .tmp-PID-N files on SIGTERM.
    ScratchDir dir;
    std::string output;
    int status = runHelper("[io-scoped-signal-helper]", dir.path.string(), 0, output);
    INFO(output);
    REQUIRE(WIFSIGNALED(status));
    CHECK(WTERMSIG(status) == SIGTERM);
    CHECK(dir.entries().empty());

    struct sigaction mine {}, seen {}, saved {};
    mine.sa_handler = [](int) {};
    sigemptyset(&mine.sa_mask);
    REQUIRE(::sigaction(SIGHUP, &mine, &saved) == 0);
    {
        const penumbra::ScopedSignalCleanup cleanup;
        ::sigaction(SIGHUP, nullptr, &seen);
        CHECK(seen.sa_handler == mine.sa_handler);  // the caller's handler stays
    }
    ::sigaction(SIGHUP, nullptr, &seen);
    CHECK(seen.sa_handler == mine.sa_handler);
    ::sigaction(SIGHUP, &saved, nullptr);
    struct sigaction before {};
    ::sigaction(SIGQUIT, nullptr, &before);
    if (before.sa_handler == SIG_DFL) {
        {
            const penumbra::ScopedSignalCleanup cleanup;
            ::sigaction(SIGQUIT, nullptr, &seen);
            CHECK(seen.sa_handler != SIG_DFL);  // the cleanup, while it lives
        }
        ::sigaction(SIGQUIT, nullptr, &seen);
        CHECK(seen.sa_handler == SIG_DFL);  // and the default after
    }
}

TEST_CASE("SIGTERM removes registered temporaries and still kills the process", "[io]") {
    ScratchDir dir;
    std::string output;
    int status = runHelper("[io-signal-helper]", dir.path.string(), 0, output);
    INFO(output);
    REQUIRE(WIFSIGNALED(status));
    CHECK(WTERMSIG(status) == SIGTERM);
    CHECK(dir.entries().empty());
}
