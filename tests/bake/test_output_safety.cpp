// What an output may replace, and how: device nodes and FIFOs are written into, never renamed
// over; directories, block devices and inputs are refused; a symbolic link is followed; outputs
// of an OutputSet appear together or not at all; two writers of one path leave one complete
// file; SIGKILL while writing leaves no temporary. Device nodes are made with mknod in the test's
// own directory (root only; the cases skip otherwise), never on a system path.

#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/util/InputFile.h"
#include "stream/util/TempRegistry.h"

#include "TestSupport.h"

#include <catch2/catch.hpp>

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <thread>

using namespace penumbra;
using namespace penumbra::test;
namespace fs = std::filesystem;

namespace {

/// A character device node like /dev/null (1, 3) or /dev/full (1, 7) in @p dir; false when this
/// process may not make one (not root, or a container without CAP_MKNOD).
bool makeDevice(const std::string& path, unsigned minor) {
    return ::mknod(path.c_str(), S_IFCHR | 0666, makedev(1, minor)) == 0;
}

std::string write(const std::string& path, const std::string& text) {
    return errorOf([&] { writeFileAtomically(path, std::span(reinterpret_cast<const uint8_t*>(text.data()), text.size())); });
}

bool isCharDevice(const std::string& path) {
    struct stat st {};
    return ::lstat(path.c_str(), &st) == 0 && S_ISCHR(st.st_mode);
}

}  // namespace

TEST_CASE("outputs: a device node is written into and stays a device", "[io][output-safety]") {
    ScratchDir dir;
    const std::string null = dir / "null", full = dir / "full";
    if (!makeDevice(null, 3) || !makeDevice(full, 7)) {
        WARN("skipped: cannot mknod here (needs root / CAP_MKNOD)");
        return;
    }
    CHECK(write(null, "discarded") == "(no InputError thrown)");
    CHECK(isCharDevice(null));
    checkOutputPath(null);  // a fine output location
    // /dev/full refuses every byte: the error names the path, and the node is still a device.
    CHECK_THAT(write(full, "x"), Catch::StartsWith(full + ": write failed: No space left on device"));
    CHECK(isCharDevice(full));
    CHECK(dir.entries() == std::vector<std::string>{"full", "null"});
}

TEST_CASE("outputs: a FIFO is written into, and one without a reader is an error", "[io][output-safety]") {
    ScratchDir dir;
    const std::string fifo = dir / "pipe";
    REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
    CHECK(write(fifo, "x") == fifo + ": is a FIFO that no process reads");
    std::string received;
    std::thread reader([&] { received = slurp(fifo); });
    // The reader may not have opened its end yet: retry until it has.
    std::string error;
    for (int i = 0; i < 200 && (error = write(fifo, "through the pipe")) != "(no InputError thrown)"; ++i)
        ::usleep(10000);
    reader.join();
    CHECK(error == "(no InputError thrown)");
    CHECK(received == "through the pipe");
    struct stat st {};
    REQUIRE(::lstat(fifo.c_str(), &st) == 0);
    CHECK(S_ISFIFO(st.st_mode));
}

TEST_CASE("outputs: directories, block devices and inputs are refused", "[io][output-safety]") {
    ScratchDir dir;
    fs::create_directory(dir.path / "sub");
    CHECK(write(dir / "sub", "x") == dir / "sub" + ": is a directory; outputs are regular files, character devices or FIFOs");
    CHECK_THROWS_WITH(checkOutputPath(dir / "sub"), Catch::Contains("is a directory"));
    if (::mknod((dir / "disk").c_str(), S_IFBLK | 0600, makedev(7, 200)) == 0) {
        CHECK_THAT(write(dir / "disk", "x"), Catch::Contains("is a block device"));
        CHECK_THROWS_WITH(checkOutputPath(dir / "disk"), Catch::Contains("is a block device"));
    }

    // An input of the current job, under any of its names, is never replaced.
    { std::ofstream(dir / "mesh.obj") << "v 0 0 0\n"; }
    REQUIRE(::link((dir / "mesh.obj").c_str(), (dir / "alias.obj").c_str()) == 0);
    {
        InputScope job;
        checkInputFile(dir / "mesh.obj");
        CHECK_THAT(write(dir / "alias.obj", "x"), Catch::Contains("is also an input of this run"));
        CHECK_THROWS_WITH(checkOutputPath(dir / "alias.obj"), Catch::Contains("is also an input of this run"));
        CHECK(slurp(dir / "mesh.obj") == "v 0 0 0\n");
    }
    CHECK(write(dir / "alias.obj", "x") == "(no InputError thrown)");  // the job is over
}

TEST_CASE("outputs: a symbolic link is followed, and its target replaced", "[io][output-safety]") {
    ScratchDir dir;
    { std::ofstream(dir / "real.exr") << "old"; }
    fs::create_symlink(dir / "real.exr", dir / "link.exr");
    CHECK(write(dir / "link.exr", "new") == "(no InputError thrown)");
    CHECK(fs::is_symlink(dir / "link.exr"));
    CHECK(slurp(dir / "real.exr") == "new");
    fs::create_symlink(dir / "missing.exr", dir / "dangling.exr");
    CHECK(write(dir / "dangling.exr", "x") == dir / "dangling.exr" + ": is a symbolic link to a missing file");
}

TEST_CASE("outputs: an OutputSet commits every file or none", "[io][output-safety]") {
    ScratchDir dir;
    const bool named = GENERATE(false, true);
    if (named) ::setenv("PENUMBRA_NO_TMPFILE", "1", 1);
    { std::ofstream(dir / "a.exr") << "old a"; }
    {
        OutputSet set;
        CHECK(write(dir / "a.exr", "new a") == "(no InputError thrown)");
        CHECK(write(dir / "b.png", "new b") == "(no InputError thrown)");
        CHECK(set.size() == 2);
        CHECK(slurp(dir / "a.exr") == "old a");  // finished, not yet in place
        CHECK_FALSE(fs::exists(dir / "b.png"));
        // Destroyed without commit(): a later output of the job failed.
    }
    CHECK(dir.entries() == std::vector<std::string>{"a.exr"});
    CHECK(slurp(dir / "a.exr") == "old a");
    {
        OutputSet set;
        write(dir / "a.exr", "new a");
        write(dir / "b.png", "new b");
        set.commit();
    }
    CHECK(dir.entries() == (std::vector<std::string>{"a.exr", "b.png"}));
    CHECK(slurp(dir / "a.exr") == "new a");

    // A device that refuses its bytes fails the set before any regular file is put in place.
    if (makeDevice(dir / "full", 7)) {
        OutputSet set;
        write(dir / "a.exr", "newer a");
        write(dir / "full", "stats");
        CHECK_THAT(errorOf([&] { set.commit(); }), Catch::StartsWith(dir / "full" + ": write failed"));
        CHECK(slurp(dir / "a.exr") == "new a");
        CHECK(dir.entries() == (std::vector<std::string>{"a.exr", "b.png", "full"}));
        fs::remove(dir / "full");
    }
    // A folder made at a later file's name while the set was open (a dump folder at the
    // camera's preview) fails the set before the earlier file is put in place.
    {
        OutputSet set;
        write(dir / "a.exr", "newest a");
        write(dir / "c.png", "c");
        fs::create_directory(dir / "c.png");
        CHECK_THAT(errorOf([&] { set.commit(); }), Catch::StartsWith(dir / "c.png" + ": is a directory now"));
        CHECK(slurp(dir / "a.exr") == "new a");
        CHECK(dir.entries() == (std::vector<std::string>{"a.exr", "b.png", "c.png"}));
    }
    ::unsetenv("PENUMBRA_NO_TMPFILE");
}

TEST_CASE("outputs: folders made for a set that is never put in place are removed", "[io][output-safety]") {
    // A merge killed or failing before its outputs were in place left the --dump folder it made.
    ScratchDir dir;
    fs::create_directory(dir / "kept");
    {
        OutputSet set;
        ensureParentDirectory(dir / "made/deeper/a.npy");
        ensureParentDirectory(dir / "kept/b.npy");
        write(dir / "made/deeper/a.npy", "a");
        write(dir / "kept/b.npy", "b");
    }  // not committed
    CHECK(dir.entries() == std::vector<std::string>{"kept"});
    CHECK(fs::is_empty(dir / "kept"));
    {
        OutputSet set;
        ensureParentDirectory(dir / "made/deeper/a.npy");
        write(dir / "made/deeper/a.npy", "a");
        set.commit();
    }
    CHECK(slurp(dir / "made/deeper/a.npy") == "a");
    // What a signal handler removes: a registered folder only while it is empty.
    fs::create_directory(dir / "empty");
    registerTempFile(dir / "empty");
    registerTempFile(dir / "made");
    removeRegisteredTempFiles();
    CHECK_FALSE(fs::exists(dir / "empty"));
    CHECK(slurp(dir / "made/deeper/a.npy") == "a");
}

TEST_CASE("outputs: two writers of one path leave one complete file", "[io][output-safety]") {
    ScratchDir dir;
    const std::string target = dir / "shared.bin";
    const std::string a(1 << 20, 'a'), b(1 << 20, 'b');
    for (int round = 0; round < 20; ++round) {
        std::thread first([&] { write(target, a); }), second([&] { write(target, b); });
        first.join(), second.join();
        const std::string got = slurp(target);
        CHECK((got == a || got == b));
    }
    CHECK(dir.entries() == std::vector<std::string>{"shared.bin"});
}

TEST_CASE("outputs helper: killed while writing", "[.][io-kill-helper]") {
    const char* where = std::getenv("PENUMBRA_KILL_HELPER_DIR");
    if (!where) return;
    installCleanupSignalHandlers();
    AtomicFile f(std::string(where) + "/interrupted.exr");
    std::string bytes(1 << 20, 'x');
    f.write(bytes.data(), bytes.size());
    const int sig = std::atoi(std::getenv("PENUMBRA_KILL_SIGNAL"));
    ::kill(::getpid(), sig);
    ::pause();
}

TEST_CASE("outputs: no signal, SIGKILL included, leaves a temporary behind", "[io][output-safety]") {
    for (int sig : {SIGKILL, SIGHUP, SIGQUIT, SIGTERM, SIGINT}) {
        for (bool named : {false, true}) {
            // SIGKILL cannot be handled: only the nameless temporary survives it.
            if (sig == SIGKILL && named) continue;
            ScratchDir dir;
            ::setenv("PENUMBRA_KILL_SIGNAL", std::to_string(sig).c_str(), 1);
            if (named) ::setenv("PENUMBRA_NO_TMPFILE", "1", 1);
            std::string output;
            int status = runSelfAsChild("[io-kill-helper]", "PENUMBRA_KILL_HELPER_DIR", dir.path.string(), 0, output);
            ::unsetenv("PENUMBRA_NO_TMPFILE");
            INFO("signal " << sig << (named ? " (named temporaries)" : "") << ": " << output);
            REQUIRE(WIFSIGNALED(status));
            CHECK(WTERMSIG(status) == sig);
            CHECK(dir.entries().empty());
        }
    }
    ::unsetenv("PENUMBRA_KILL_SIGNAL");
}
