#pragma once
/// @file FuzzSupport.h
/// @brief What every libFuzzer harness shares. The readers open files by name, so each input is
/// written to a file in a private scratch directory, which also holds the small side files that
/// scenes and glTF models name (mesh.obj, points.npy, buffer.bin, ...). An InputError is the
/// right answer to a bad input; any other exception (uncaught, so libFuzzer reports it), a crash,
/// a hang or a sanitizer report is a bug.
///
/// A harness is a few lines (fuzz/fuzz_obj.cpp):
///
///     #include "FuzzSupport.h"
///     PENUMBRA_FUZZ_FILE("mesh.obj") { penumbra::fuzz::drain(*penumbra::openGeometryFile(path)); }
///
/// CMake turns every fuzz/fuzz_NAME.cpp into a libFuzzer binary fuzz_NAME (PENUMBRA_FUZZ), or a
/// replay binary that runs the kept crash inputs in fuzz/regressions/NAME/ and the seeds in
/// fuzz/seeds/NAME/ once, as a test. fuzz/run.sh runs them; docs/reliability.md has the numbers.

#include "stream/Error.h"
#include "stream/TriangleSource.h"

#include <cstddef>
#include <cstdint>
#include <string>

namespace penumbra::fuzz {

/// The scratch directory (made once per process, with the side files; removed at exit).
const std::string& scratchDir();

/// @brief Writes @p size bytes to scratchDir()/@p name, replacing the previous input.
/// @return the file's path.
std::string writeInput(const uint8_t* data, size_t size, const char* name);

/// @brief Reads @p source to its end, or to @p limit triangles (generators may be huge).
uint64_t drain(TriangleSource& source, uint64_t limit = uint64_t(1) << 18);

/// Registers the geometry types and receiver kinds (once).
void initialize();

/// @brief Called with the error an input was rejected with; prints it when PENUMBRA_FUZZ_VERBOSE
/// is set (to check that seeds get past the first key).
void rejected(const InputError& error);

}  // namespace penumbra::fuzz

/// Defines the harness: the body gets `path`, the input written as scratchDir()/NAME.
#define PENUMBRA_FUZZ_FILE(NAME)                                                     \
    static void penumbraFuzzBody(const std::string& path);                           \
    extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {        \
        penumbra::fuzz::initialize();                                                \
        const std::string path = penumbra::fuzz::writeInput(data, size, NAME);      \
        try {                                                                        \
            penumbraFuzzBody(path);                                                  \
        } catch (const penumbra::InputError& error) {                                \
            penumbra::fuzz::rejected(error);                                         \
        }                                                                            \
        return 0;                                                                    \
    }                                                                                \
    static void penumbraFuzzBody(const std::string& path)
