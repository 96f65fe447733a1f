#pragma once
/// @file Memory.h
/// @brief Process memory figures for --stats and budget checks, and parsing of byte sizes.

#include <cstdint>
#include <string>

namespace penumbra {

/// @brief Highest resident set size of this process so far, in bytes (getrusage ru_maxrss).
uint64_t peakRssBytes();

/// @brief Current resident set size in bytes (/proc/self/statm); 0 when unavailable.
uint64_t currentRssBytes();

/// @brief The address-space limit of this process (RLIMIT_AS: `prlimit --as`, `ulimit -v`), or 0
/// when there is none.
uint64_t addressSpaceLimit();

/// @brief Address space mapped now but not resident (/proc/self/statm size minus resident):
/// libraries' code and data, reserved stacks and arenas. Under an address-space limit it is
/// spent before any bake data; 0 when unavailable.
uint64_t mappedNotResidentBytes();

/// @brief Address space mapped now (/proc/self/statm size), 0 when unavailable.
uint64_t mappedBytes();

/// @brief Whether @p bytes more of address space can be mapped now: a reservation is made and
/// released at once (nothing is touched), so that a plan can be checked against what a limit
/// really leaves before the work allocates it.
bool addressSpaceAvailable(uint64_t bytes);

/// @brief Makes glibc's malloc use one arena. Each further arena reserves 64 MiB of address space
/// per thread that allocates, which an address-space limit cannot afford.
void useOneMallocArena();

/// @brief Returns freed heap memory to the operating system (glibc keeps it per thread arena
/// otherwise), so that a phase's peak does not carry into the next. Cheap; call between phases.
void returnFreedMemory();

/// @brief Parses a byte size such as "1000", "512k", "256M", "1G", "1.5GiB" or "2 GB".
///
/// Units are case-insensitive and all binary: k/K/KB/KiB = 1024, M/MB/MiB = 1024^2,
/// G/GB/GiB = 1024^3, T/TB/TiB = 1024^4 (a memory budget is naturally a power of two, and
/// treating "GB" as 10^9 would make "1G" and "1GB" silently differ). A trailing "B" alone means
/// bytes. Fractions are allowed with a unit and rounded down to whole bytes; a plain byte count
/// must be an integer.
///
/// Why not CLI11's `AsSizeValue`: it takes integers only ("1.5GiB" fails), accepts "Gi" and
/// "P"/"E", gives CLI11's own messages, and serves only the command line, while the same
/// budget text comes from Python (`memory_budget`) and shard plans too. One parser here keeps one
/// rule and one message for every way in.
///
/// @param text the user's text.
/// @param what names the setting in error messages, e.g. "--memory" or "scene.json: memory".
/// @throw InputError "WHAT: 'TEXT' is not a byte size ..." on empty, negative, malformed,
///        unknown-unit or overflowing input.
uint64_t parseByteSize(const std::string& text, const std::string& what);

/// @brief Formats a byte count for messages: "512 B", "1.50 KiB", "25.0 MiB", "256 MiB".
std::string formatBytes(uint64_t bytes);

/// @brief Empties @p c and gives its storage back. `v = {}` on a std::vector picks the
/// initializer_list assignment, which keeps the capacity: `convert` held every OBJ group's
/// vertices and indices until the end that way (3 MB a group, stop 58).
template <typename Container>
void releaseStorage(Container& c) {
    Container().swap(c);
}

}  // namespace penumbra
