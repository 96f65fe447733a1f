#include "stream/GltfReader.h"

#include "stream/util/InputFile.h"

#include "stream/util/Error.h"
#include "stream/GltfBytes.h"
#include "stream/GltfDocument.h"
#include "stream/GltfInstancing.h"
#include "stream/GltfPrimitive.h"

#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>

namespace penumbra {
namespace {

/// Triangles decoded at once in local coordinates, then placed once per instance.
constexpr size_t kBlockTriangles = 1024;

/// One node drawing a primitive, with its EXT_mesh_gpu_instancing accessors (or one instance).
struct Placement {
    int node = 0;
    glm::dmat4 world{1.0};
    GltfInstancing instancing;
};

/// A primitive and every placement of it: its triangles are read once per pass, block by block,
/// and each block is placed instance by instance.
struct Draw {
    size_t layout = 0;
    std::vector<Placement> placements;
    uint64_t instances = 0;
};

/// A placement's transform of one instance, with the flags that keep identities bit-exact.
struct Instance {
    glm::dmat4 matrix{1.0};
    bool identity = true, mirrored = false;
    int node = 0;
};

class GltfSource final : public TriangleSource {
public:
    GltfSource(std::string path, std::shared_ptr<const GltfAlphaIds> alpha);

    size_t read(std::span<Triangle> out) override;
    void rewind() override;
    std::string name() const override { return doc_.path; }
    std::optional<uint64_t> sizeHint() const override { return triangleCount_; }
    uint64_t residentBytes() const override;
    std::string residentDetail() const override;
    /// What opening the file held at its peak for the JSON text and its parsed tree.
    uint64_t parsingBytes() const;

private:
    void placeScene();
    void loadBlock();
    Instance instance(const Placement& p, uint64_t i);
    void advance();

    GltfDocument doc_;
    std::shared_ptr<const GltfAlphaIds> alpha_;
    const GltfPrimitiveAlpha* blockAlpha_ = nullptr;  ///< the current draw's, or null: opaque
    std::unique_ptr<GltfBytes> bytes_;
    std::vector<std::pair<std::string, FileStamp>> stamps_;  ///< the buffer files, as first read
    bool passStarts_ = false;  ///< rewound: read() checks the stamps first
    std::vector<GltfPrimitiveLayout> layouts_;
    std::vector<Draw> draws_;
    uint64_t triangleCount_ = 0;
    uint64_t decodeBudget_ = 0;
    size_t largestDecode_ = SIZE_MAX;

    // Position in the stream: draw, block of its triangles, placement and instance, triangle.
    size_t draw_ = 0;
    uint64_t blockStart_ = 0;
    size_t placement_ = 0;
    uint64_t instance_ = 0;
    size_t next_ = 0;
    bool blockLoaded_ = false;
    std::vector<Triangle> block_;
    Instance current_;
    bool currentReady_ = false;
    std::unique_ptr<GltfPrimitiveReader> reader_;
};

namespace {
/// Bytes of memory that parsing one byte of a glTF's JSON holds at its peak (text and tree).
constexpr uint64_t kGltfJsonParseBytesPerByte = 13;
/// Bytes the opened source keeps per JSON object of its document, at most: measured 398 a node
/// (its description, its placement, the draw's list) on 300,000 nodes sharing one mesh; 10 % more
/// so that the budget a refusal names before the opening holds after it.
constexpr uint64_t kGltfHeldBytesPerObject = 440;
/// Added to that estimate: the plan after the opening counts the rest exactly (30,000 nodes named
/// 106M before the opening and 107M after it without it).
constexpr uint64_t kGltfHeldMarginBytes = 4ull << 20;
}  // namespace

GltfSource::GltfSource(std::string path, std::shared_ptr<const GltfAlphaIds> alpha)
    : doc_(loadGltfDocument(path)), alpha_(std::move(alpha)) {
    placeScene();
    bytes_ = std::make_unique<GltfBytes>(doc_, decodeBudget_);
    block_.reserve(kBlockTriangles);
    // The files every pass reads buffers from: the .glb itself, or the .gltf's .bin files.
    for (const GltfBuffer& b : doc_.buffers)
        if (b.source == GltfBuffer::Source::GlbChunk || b.source == GltfBuffer::Source::File)
            if (std::none_of(stamps_.begin(), stamps_.end(), [&](const auto& s) { return s.first == b.file; }))
                stamps_.emplace_back(b.file, FileStamp::of(b.file));
}

void GltfSource::placeScene() {
    GltfSkipped skipped;
    std::vector<std::vector<size_t>> meshLayouts(doc_.meshes.size());
    for (size_t m = 0; m < doc_.meshes.size(); ++m)
        for (size_t p = 0; p < doc_.meshes[m].primitives.size(); ++p)
            if (auto layout = gltfTrianglePrimitive(doc_, int(m), int(p), &skipped)) {
                meshLayouts[m].push_back(layouts_.size());
                layouts_.push_back(*layout);
            }
    skipped.warn(doc_.path);
    std::map<size_t, size_t> drawOf;  // layout -> draw: every node sharing a mesh joins one draw
    for (const GltfMeshNode& placed : walkGltfScene(doc_)) {
        Placement p;
        p.node = placed.node, p.world = placed.world;
        p.instancing = gltfInstancingOf(doc_, placed.node);
        for (size_t l : meshLayouts[size_t(placed.mesh)]) {
            if (layouts_[l].triangles == 0 || p.instancing.instances == 0) continue;
            auto [it, fresh] = drawOf.emplace(l, draws_.size());
            if (fresh) draws_.push_back(Draw{l, {}, 0});
            Draw& d = draws_[it->second];
            d.placements.push_back(p);
            d.instances += p.instancing.instances;
            triangleCount_ += layouts_[l].triangles * p.instancing.instances;
        }
    }
    for (const Draw& d : draws_)
        if (layouts_[d.layout].decodeBytes > decodeBudget_) decodeBudget_ = layouts_[d.layout].decodeBytes, largestDecode_ = d.layout;
}

uint64_t GltfSource::parsingBytes() const { return doc_.jsonBytes * kGltfJsonParseBytesPerByte; }

}  // namespace

GltfOpeningBytes gltfOpeningBytes(const std::string& path) {
    GltfOpeningBytes bytes;
    bytes.parse = gltfJsonTextBytes(path) * kGltfJsonParseBytesPerByte;
    // What the opened document keeps grows with its objects: a budget named from the parse alone
    // (279M for 300,000 nodes in 15.8 MiB) was refused again after the parse, naming 400M.
    if (bytes.parse >= TriangleSource::kNotableResidentBytes)
        bytes.held = gltfJsonObjectCount(path) * kGltfHeldBytesPerObject + kGltfHeldMarginBytes;
    return bytes;
}

namespace {

uint64_t GltfSource::residentBytes() const {
    uint64_t placements = 0;
    for (const Draw& d : draws_) placements += sizeof(Draw) + d.placements.size() * sizeof(Placement);
    // Opening the file held its JSON text and the parsed tree: about 13 bytes per byte of JSON
    // (measured: 150,000 nodes in 10.6 MB peaked at 141 MiB over an empty file's). It is freed
    // once the document is read, but the process's peak has seen it, so the plan counts it:
    // a budget named without it was exceeded by 40 % on a glTF of many nodes.
    return doc_.residentBytes() + layouts_.size() * sizeof(GltfPrimitiveLayout) + placements +
           kGltfCacheBlocks * kGltfBlockBytes + kBlockTriangles * sizeof(Triangle) + decodeBudget_ + parsingBytes();
}

std::string GltfSource::residentDetail() const {
    if (parsingBytes() > decodeBudget_ && doc_.jsonBytes > (1u << 20))
        return fmt::format("{}: its {:.1f} MiB of glTF JSON take about {:.0f} MiB to parse", doc_.path, double(doc_.jsonBytes) / (1 << 20),
                           double(parsingBytes()) / (1 << 20));
    if (largestDecode_ == SIZE_MAX) return {};
    const GltfPrimitiveLayout& l = layouts_[largestDecode_];
    return fmt::format("{} needs {:.1f} MiB to decode ({})", l.where(doc_), double(l.decodeBytes) / (1 << 20),
                       l.draco          ? "KHR_draco_mesh_compression"
                       : l.compressed() ? "EXT_meshopt_compression"
                                        : "the index lists of its sparse accessors");
}

void GltfSource::rewind() {
    // Checked as the next pass starts reading (a rewind never throws).
    passStarts_ = true;
    draw_ = 0, blockStart_ = 0, placement_ = 0, instance_ = 0, next_ = 0;
    blockLoaded_ = currentReady_ = false;
    reader_.reset();
}

void GltfSource::loadBlock() {
    const Draw& d = draws_[draw_];
    const GltfPrimitiveLayout& layout = layouts_[d.layout];
    if (!reader_) reader_ = std::make_unique<GltfPrimitiveReader>(doc_, *bytes_, layout);
    blockAlpha_ = nullptr;
    if (alpha_)
        if (auto it = alpha_->primitives.find({layout.mesh, layout.primitive}); it != alpha_->primitives.end()) blockAlpha_ = &it->second;
    const uint64_t end = std::min(layout.triangles, blockStart_ + kBlockTriangles);
    block_.resize(size_t(end - blockStart_));
    for (uint64_t t = blockStart_; t < end; ++t) {
        const std::array<uint32_t, 3> v = reader_->triangle(t);
        Triangle& tri = block_[size_t(t - blockStart_)];
        for (int c = 0; c < 3; ++c) tri.v[size_t(c)] = reader_->position(v[size_t(c)]);
        // A MASK material's cut-out ids (GltfAlpha.h), else the material's translucent id or 0.
        const uint32_t alpha = blockAlpha_ ? blockAlpha_->at(t) : doc_.alphaIdOf(layout.mesh, layout.primitive);
        tri.flags = alpha == kGltfAlphaNoCast ? uint32_t(kTriangleNoCast) : withAlphaId(0, alpha);
    }
    blockLoaded_ = true;
}

Instance GltfSource::instance(const Placement& p, uint64_t i) {
    Instance out;
    out.node = p.node;
    out.matrix = p.world;
    if (p.instancing.any()) out.matrix = p.world * gltfInstanceLocal(doc_, *bytes_, p.instancing, p.node, i);
    out.identity = out.matrix == glm::dmat4(1.0);
    out.mirrored = glm::determinant(glm::dmat3(out.matrix)) < 0.0;
    return out;
}

/// Moves to the next instance of the current block; after the last, to the next block; after the
/// last block, to the next draw.
void GltfSource::advance() {
    next_ = 0;
    currentReady_ = false;
    const Draw& d = draws_[draw_];
    if (++instance_ < d.placements[placement_].instancing.instances) return;
    instance_ = 0;
    if (++placement_ < d.placements.size()) return;
    placement_ = 0;
    blockLoaded_ = false;
    blockStart_ += kBlockTriangles;
    if (blockStart_ < layouts_[d.layout].triangles) return;
    blockStart_ = 0;
    reader_.reset();  // frees a decoded Draco primitive before the next one is decoded
    ++draw_;
}

size_t GltfSource::read(std::span<Triangle> out) {
    if (passStarts_) {
        // A buffer rewritten in place between passes (an exporter saving moved vertices at the
        // same size) gave receivers of one version and shadows of another, exit 0.
        for (const auto& [file, stamp] : stamps_) requireUnchangedFile(file, stamp);
        passStarts_ = false;
    }
    size_t written = 0;
    while (written < out.size() && draw_ < draws_.size()) {
        if (!blockLoaded_) loadBlock();
        if (!currentReady_) current_ = instance(draws_[draw_].placements[placement_], instance_), currentReady_ = true;
        const size_t n = std::min(out.size() - written, block_.size() - next_);
        for (size_t i = 0; i < n; ++i) {
            Triangle tri = block_[next_ + i];
            if (!current_.identity) {
                for (glm::vec3& v : tri.v) v = glm::vec3(current_.matrix * glm::dvec4(v, 1.0));
                if (current_.mirrored && !alphaIdOf(tri.flags)) std::swap(tri.v[1], tri.v[2]);
                if (!isFinite(tri)) {
                    const GltfPrimitiveLayout& l = layouts_[draws_[draw_].layout];
                    fail(doc_.path, "node {} transforms mesh {} primitive {} to a non-finite position", current_.node, l.mesh,
                         l.primitive);
                }
            }
            out[written + i] = tri;
        }
        written += n, next_ += n;
        if (next_ == block_.size()) advance();
    }
    return written;
}

}  // namespace

TriangleSourcePtr openGltf(const std::string& path, std::shared_ptr<const GltfAlphaIds> alpha) {
    return std::make_unique<GltfSource>(path, std::move(alpha));
}

}  // namespace penumbra
