#include "stream/util/Memory.h"

#include <malloc.h>
#include <sys/mman.h>

#include "stream/util/Error.h"

#include <sys/resource.h>
#include <unistd.h>

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <string_view>

namespace penumbra {

uint64_t peakRssBytes() {
    struct rusage usage {};
    if (::getrusage(RUSAGE_SELF, &usage) != 0) return 0;
    return static_cast<uint64_t>(usage.ru_maxrss) * 1024;  // Linux reports KiB
}

namespace {

/// Pages mapped and resident now (/proc/self/statm "size resident ..."); false when unavailable.
/// One read of a tiny file is cheaper and simpler than parsing /proc/self/status.
bool statmPages(unsigned long long& size, unsigned long long& resident) {
    std::FILE* f = std::fopen("/proc/self/statm", "r");
    if (!f) return false;
    int got = std::fscanf(f, "%llu %llu", &size, &resident);
    std::fclose(f);
    return got == 2;
}

uint64_t pageBytes() {
    long page = ::sysconf(_SC_PAGESIZE);
    return static_cast<uint64_t>(page > 0 ? page : 4096);
}

}  // namespace

uint64_t currentRssBytes() {
    unsigned long long sizePages = 0, residentPages = 0;
    return statmPages(sizePages, residentPages) ? residentPages * pageBytes() : 0;
}

uint64_t addressSpaceLimit() {
    struct rlimit limit {};
    if (::getrlimit(RLIMIT_AS, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) return 0;
    return uint64_t(limit.rlim_cur);
}

uint64_t mappedNotResidentBytes() {
    unsigned long long sizePages = 0, residentPages = 0;
    if (!statmPages(sizePages, residentPages) || residentPages > sizePages) return 0;
    return (sizePages - residentPages) * pageBytes();
}

uint64_t mappedBytes() {
    unsigned long long sizePages = 0, residentPages = 0;
    return statmPages(sizePages, residentPages) ? sizePages * pageBytes() : 0;
}

bool addressSpaceAvailable(uint64_t bytes) {
    if (bytes == 0) return true;
    void* probe = ::mmap(nullptr, size_t(bytes), PROT_NONE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
    if (probe == MAP_FAILED) return false;
    ::munmap(probe, size_t(bytes));
    return true;
}

void useOneMallocArena() { ::mallopt(M_ARENA_MAX, 1); }

uint64_t parseByteSize(const std::string& text, const std::string& what) {
    auto bad = [&](std::string_view why) -> uint64_t {
        fail(what, "'{}' is not a byte size ({}; expected e.g. 1000, 512k, 256M or 1.5GiB)", text, why);
    };

    std::string_view s = text;
    while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
    while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
    if (s.empty()) return bad("it is empty");
    if (s.front() == '-') return bad("it is negative");
    if (s.front() == '+') s.remove_prefix(1);

    // Split into the numeric part and the unit; from_chars would also accept "inf", "nan" and
    // exponents, which make no sense here, so the number is restricted to digits and one dot.
    size_t numEnd = 0;
    bool sawDot = false, sawDigit = false;
    while (numEnd < s.size()) {
        char c = s[numEnd];
        if (c >= '0' && c <= '9') sawDigit = true;
        else if (c == '.' && !sawDot) sawDot = true;
        else break;
        ++numEnd;
    }
    if (!sawDigit) return bad("it does not start with a number");
    std::string_view number = s.substr(0, numEnd);
    std::string_view unitText = s.substr(numEnd);
    while (!unitText.empty() && (unitText.front() == ' ' || unitText.front() == '\t'))
        unitText.remove_prefix(1);

    std::string unit;
    for (char c : unitText) unit.push_back(static_cast<char>(std::tolower(static_cast<unsigned char>(c))));
    int power = -1;
    if (unit.empty() || unit == "b") power = 0;
    else {
        static constexpr std::string_view kPrefixes = "kmgt";
        size_t p = kPrefixes.find(unit[0]);
        std::string_view rest = std::string_view(unit).substr(1);
        if (p != std::string_view::npos && (rest.empty() || rest == "b" || rest == "ib"))
            power = static_cast<int>(p) + 1;
    }
    if (power < 0) return bad(fmt::format("unknown unit '{}'", unitText));

    const uint64_t multiplier = uint64_t{1} << (10 * power);
    if (!sawDot) {
        uint64_t value = 0;
        auto [end, ec] = std::from_chars(number.data(), number.data() + number.size(), value);
        if (ec != std::errc() || end != number.data() + number.size()) return bad("it is too large");
        if (value > UINT64_MAX / multiplier) return bad("it is too large");
        return value * multiplier;
    }
    if (power == 0) return bad("a byte count must be a whole number");
    double value = 0;
    auto [end, ec] = std::from_chars(number.data(), number.data() + number.size(), value);
    if (ec != std::errc() || end != number.data() + number.size()) return bad("malformed number");
    long double bytes = static_cast<long double>(value) * static_cast<long double>(multiplier);
    if (!(bytes < 18446744073709551615.0L)) return bad("it is too large");
    return static_cast<uint64_t>(std::floor(bytes));
}

std::string formatBytes(uint64_t bytes) {
    if (bytes < 1024) return fmt::format("{} B", bytes);
    static constexpr const char* kUnits[] = {"KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
    double v = static_cast<double>(bytes);
    int u = -1;
    while (v >= 1024.0 && u < 5) {
        v /= 1024.0;
        ++u;
    }
    // Three significant digits is plenty for a report and keeps columns aligned.
    if (v < 10) return fmt::format("{:.2f} {}", v, kUnits[u]);
    if (v < 100) return fmt::format("{:.1f} {}", v, kUnits[u]);
    return fmt::format("{:.0f} {}", v, kUnits[u]);
}

void returnFreedMemory() { ::malloc_trim(0); }

}  // namespace penumbra
