#include "bake/shard/PartialFile.h"

#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/util/RegularFile.h"

#include <cstring>
#include <fstream>

namespace penumbra {
namespace {

constexpr char kMagic[8] = {'P', 'N', 'B', 'P', 'A', 'R', 'T', '\n'};

/// Little-endian on every machine penumbra builds for (x86-64, aarch64); the bytes are the values.
class Writer {
public:
    template <class T>
    void put(const T& v) { bytes(&v, sizeof v); }
    void bytes(const void* data, size_t n) {
        const auto* p = static_cast<const uint8_t*>(data);
        out.insert(out.end(), p, p + n);
    }
    std::vector<uint8_t> out;
};

class Reader {
public:
    Reader(const std::string& path, std::span<const uint8_t> data) : path_(path), data_(data) {}
    template <class T>
    T get() {
        T v;
        bytes(&v, sizeof v);
        return v;
    }
    void bytes(void* to, size_t n) {
        if (n == 0) return;  // `to` may be an empty vector's null data(), which memcpy must not get
        if (n > data_.size() - at_)
            fail(path_, "truncated partial file ({} bytes; the header or masks need more)", data_.size());
        std::memcpy(to, data_.data() + at_, n);
        at_ += n;
    }
    size_t at() const { return at_; }
    size_t remaining() const { return data_.size() - at_; }

private:
    const std::string& path_;
    std::span<const uint8_t> data_;
    size_t at_ = 0;
};

ReceiverState stateOf(const uint64_t* row, const LightSamples& samples) {
    bool any = false, full = true;
    for (int k = 0; k < samples.groupCount(); ++k) {
        any |= row[k] != 0;
        full &= row[k] == samples.groups[k].fullMask();
    }
    return full && samples.groupCount() > 0 ? ReceiverState::Full : any ? ReceiverState::Partial : ReceiverState::Clear;
}

void putHeader(Writer& w, const PartialHeader& h) {
    w.bytes(kMagic, sizeof kMagic);
    w.put(h.version), w.put(h.role), w.put(h.sceneHash), w.put(h.settingsHash), w.put(h.contentHash);
    w.put(h.cut), w.put(h.part), w.put(h.parts), w.put(h.partEnd ? h.partEnd : h.part + 1), w.put(h.replayed), w.put(h.replayHash);
    w.put(h.receivers), w.put(h.groups);
    w.put(uint32_t(h.lightFirstGroup.size()));
    for (uint32_t f : h.lightFirstGroup) w.put(f);
}

PartialHeader getHeader(Reader& r, const std::string& path) {
    char magic[8];
    r.bytes(magic, sizeof magic);
    if (std::memcmp(magic, kMagic, sizeof magic) != 0) fail(path, "not a penumbra partial file (shard or checkpoint)");
    PartialHeader h;
    h.version = r.get<uint32_t>();
    if (h.version != kPartialFormatVersion)
        fail(path, "partial file format version {}, this penumbra reads version {}", h.version, kPartialFormatVersion);
    h.role = r.get<uint32_t>(), h.sceneHash = r.get<uint64_t>(), h.settingsHash = r.get<uint64_t>();
    h.contentHash = r.get<uint64_t>(), h.cut = r.get<uint32_t>(), h.part = r.get<uint32_t>();
    h.parts = r.get<uint32_t>(), h.partEnd = r.get<uint32_t>(), h.replayed = r.get<uint64_t>(), h.replayHash = r.get<uint64_t>();
    h.receivers = r.get<uint64_t>(), h.groups = r.get<uint32_t>();
    const uint32_t lights = r.get<uint32_t>();
    if (lights > 1u << 20 || h.groups > 1u << 24 || h.receivers > (uint64_t(1) << 40) || h.part >= h.partEnd ||
        h.partEnd > h.parts)
        fail(path, "corrupt partial file header (parts {}..{} of {}, {} receivers, {} groups, {} lights)", h.part,
             h.partEnd, h.parts, h.receivers, h.groups, lights);
    if (size_t(lights) * sizeof(uint32_t) > r.remaining()) fail(path, "truncated partial file header ({} lights)", lights);
    h.lightFirstGroup.resize(lights);
    for (uint32_t& f : h.lightFirstGroup) f = r.get<uint32_t>();
    // Light i's groups are [f[i], f[i+1]): ascending, within the groups.
    for (size_t i = 0; i < lights; ++i)
        if (h.lightFirstGroup[i] > h.groups || (i > 0 && h.lightFirstGroup[i] < h.lightFirstGroup[i - 1]))
            fail(path, "corrupt partial file header (light {} starts at group {} of {})", i, h.lightFirstGroup[i], h.groups);
    return h;
}

/// The whole file; a FIFO or a device (which might never end) is refused, not read.
std::vector<uint8_t> readWhole(const std::string& path) {
    const RegularFile file(path);
    std::vector<uint8_t> data(size_t(file.size()));
    file.read(data.data(), data.size(), 0);
    return data;
}

}  // namespace

void Fnv64::add(const void* data, size_t bytes) {
    const auto* p = static_cast<const uint8_t*>(data);
    for (size_t i = 0; i < bytes; ++i) value = (value ^ p[i]) * 0x100000001b3ull;
}

void writePartialFile(const std::string& path, const PartialHeader& header, const LightSamples& samples,
                      const VisibilityMasks& masks, std::span<const uint8_t> present) {
    std::vector<uint8_t> states(present.size(), uint8_t(ReceiverState::Absent));
    for (size_t r = 0; r < present.size(); ++r)
        if (present[r]) states[r] = uint8_t(stateOf(masks.row(r), samples));
    writePartialStates(path, header, states, masks);
}

void writePartialStates(const std::string& path, const PartialHeader& header, std::span<const uint8_t> states,
                        const VisibilityMasks& masks) {
    Writer w;
    putHeader(w, header);
    const size_t n = states.size();
    std::vector<uint8_t> packed((n + 3) / 4, 0);
    for (size_t r = 0; r < n; ++r) packed[r / 4] |= uint8_t((states[r] & 3u) << (2 * (r % 4)));
    w.bytes(packed.data(), packed.size());
    for (size_t r = 0; r < n; ++r)
        if (ReceiverState(states[r]) == ReceiverState::Partial) w.bytes(masks.row(r), sizeof(uint64_t) * size_t(masks.groups));
    Fnv64 sum;
    sum.add(w.out.data(), w.out.size());
    w.put(sum.value);
    // A checkpoint or shard file exists to outlive what stops the bake, the machine included.
    writeFileAtomically(path, w.out, FileSync::Durable);
}

PartialFile readPartialFile(const std::string& path) {
    const std::vector<uint8_t> data = readWhole(path);
    if (data.size() < sizeof(uint64_t)) fail(path, "truncated partial file ({} bytes)", data.size());
    const size_t body = data.size() - sizeof(uint64_t);
    Reader r(path, std::span<const uint8_t>(data.data(), body));
    PartialFile f{path, getHeader(r, path), {}, {}};
    const size_t n = size_t(f.header.receivers);
    // Sizes come from the file: check them against its length before allocating anything.
    if ((n + 3) / 4 > r.remaining())
        fail(path, "truncated partial file ({} bytes; {} receivers need {} bytes of states)", data.size(), n, (n + 3) / 4);
    std::vector<uint8_t> packed((n + 3) / 4);
    r.bytes(packed.data(), packed.size());
    f.state.resize(n);
    size_t partial = 0;
    for (size_t i = 0; i < n; ++i) {
        f.state[i] = uint8_t((packed[i / 4] >> (2 * (i % 4))) & 3u);
        partial += f.state[i] == uint8_t(ReceiverState::Partial);
    }
    size_t wordBytes = 0;
    if (__builtin_mul_overflow(partial, size_t(f.header.groups) * sizeof(uint64_t), &wordBytes) || r.remaining() < wordBytes)
        fail(path, "truncated partial file ({} bytes of masks; {} receivers of {} groups in partial shadow need more)",
             r.remaining(), partial, f.header.groups);
    if (r.remaining() > wordBytes)
        fail(path, "damaged partial file: {} bytes after the masks that {} receivers of {} groups in partial shadow need",
             r.remaining() - wordBytes, partial, f.header.groups);
    f.words.resize(partial * f.header.groups);
    r.bytes(f.words.data(), wordBytes);
    uint64_t stored;
    std::memcpy(&stored, data.data() + body, sizeof stored);
    Fnv64 sum;
    sum.add(data.data(), body);
    if (sum.value != stored) fail(path, "checksum mismatch: the partial file is damaged");
    return f;
}

PartialHeader readPartialHeader(const std::string& path) {
    const RegularFile file(path);  // a FIFO or a device is refused, not read
    std::ifstream in(path, std::ios::binary);
    if (!in) fail(path, "cannot open partial file: {}", std::strerror(errno));
    constexpr size_t kFixedBytes = 88;  // up to and with the light count
    std::vector<uint8_t> head(kFixedBytes);
    in.read(reinterpret_cast<char*>(head.data()), std::streamsize(head.size()));
    head.resize(size_t(in.gcount()));
    if (head.size() == kFixedBytes) {
        uint32_t lights = 0;
        std::memcpy(&lights, head.data() + kFixedBytes - sizeof lights, sizeof lights);
        head.resize(kFixedBytes + 4 * size_t(std::min(lights, 1u << 20)));
        in.read(reinterpret_cast<char*>(head.data() + kFixedBytes), std::streamsize(head.size() - kFixedBytes));
        head.resize(kFixedBytes + size_t(in.gcount()));
    }
    Reader r(path, head);
    return getHeader(r, path);
}

void addPartialMasks(const PartialFile& file, const LightSamples& samples, VisibilityMasks& masks,
                     std::vector<uint8_t>& covered) {
    const uint64_t* words = file.words.data();
    for (size_t r = 0; r < file.state.size(); ++r) {
        const auto s = ReceiverState(file.state[r]);
        if (s == ReceiverState::Absent) continue;
        covered[r] = uint8_t(std::min(255, covered[r] + 1));
        uint64_t* row = masks.row(r);
        if (s == ReceiverState::Full)
            for (int k = 0; k < masks.groups; ++k) row[k] |= samples.groups[k].fullMask();
        if (s == ReceiverState::Partial) {
            for (int k = 0; k < masks.groups; ++k) row[k] |= words[k];
            words += masks.groups;
        }
    }
}

}  // namespace penumbra
