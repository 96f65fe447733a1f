// Bake dumps (`--dump DIR`, read by `penumbra compare`): bake/output/BakeDump.h's reader over the
// four files of a dump. One input holds them all, in the order receivers.npy, samples.npy,
// masks.npy, rule.json, separated by the line "#PNDUMP#" (fuzz/seeds/dump are real dumps so cut);
// a missing part is a missing file. Every row is read, and every sample its receiver's set names,
// as compare reads them.
#include "FuzzSupport.h"

#include "bake/output/BakeDump.h"

#include <filesystem>
#include <fstream>
#include <iterator>

namespace {

constexpr const char* kParts[] = {"receivers.npy", "samples.npy", "masks.npy", "rule.json"};
constexpr std::string_view kSeparator = "\n#PNDUMP#\n";

/// Writes the parts of @p input as the files of a dump in @p dir (made empty first).
void writeDump(const std::string& input, const std::string& dir) {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
    std::filesystem::create_directories(dir);
    size_t at = 0;
    for (const char* name : kParts) {
        if (at > input.size()) break;
        size_t end = input.find(kSeparator, at);
        if (end == std::string::npos) end = input.size();
        std::ofstream(dir + "/" + name, std::ios::binary).write(input.data() + at, std::streamsize(end - at));
        at = end + kSeparator.size();
    }
}

}  // namespace

PENUMBRA_FUZZ_FILE("dump.parts") {
    using namespace penumbra;
    std::ifstream in(path, std::ios::binary);
    const std::string input((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string dir = fuzz::scratchDir() + "/dump";
    writeDump(input, dir);
    BakeDumpReader dump(dir);
    std::vector<DumpReceiver> receivers;
    std::vector<uint64_t> masks;
    double sum = 0;  // kept, so that the reads are not optimised away
    for (uint64_t done = 0; done < dump.receivers(); done += 64) {
        const uint64_t rows = std::min<uint64_t>(64, dump.receivers() - done);
        dump.next(rows, receivers, masks);
        for (const DumpReceiver& r : receivers)
            for (uint64_t k = 0; k < dump.samples(); ++k) sum += dump.sample(r.sampleSet, k).w;
    }
    if (sum < 0) std::abort();
}
