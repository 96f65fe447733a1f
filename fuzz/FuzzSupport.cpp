#include "FuzzSupport.h"

#include "bake/kinds/ReceiverKind.h"
#include "bake/Scene.h"
#include "procedural/Generators.h"
#include "stream/GeometryFile.h"
#include "stream/Npy.h"
#include "stream/PtriFormat.h"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <vector>

namespace penumbra::fuzz {
namespace {

std::string g_dir;

void removeScratch() {
    std::error_code ec;
    std::filesystem::remove_all(g_dir, ec);
}

void writeText(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

/// The side files a scene or model may name: a quad as OBJ (also with UVs), glTF, GLB and .ptri, point lists as
/// .npy and CSV, and a raw 36-byte buffer (one triangle of floats).
void writeSideFiles(const std::string& dir) {
    writeText(dir + "/mesh.obj", "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nf 1 2 3 4\n");
    writeText(dir + "/uv.obj", "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n");
    const std::vector<Triangle> quad = {{{glm::vec3(-1, 0, -1), glm::vec3(1, 0, -1), glm::vec3(1, 0, 1)}, 0},
                                        {{glm::vec3(-1, 0, -1), glm::vec3(1, 0, 1), glm::vec3(-1, 0, 1)}, 0}};
    for (const char* name : {"/mesh.glb", "/mesh.gltf", "/mesh.ptri"}) {
        VectorSource source(quad);
        convertGeometry(source, dir + name);
    }
    const float points[12] = {0, 0.5f, 0, 0, 1, 0, 0.2f, 0.5f, 0.1f, 0, 1, 0};
    const uint64_t shape[2] = {2, 6};
    writeNpy(dir + "/points.npy", "<f4", shape, points, sizeof points);
    writeText(dir + "/points.csv", "x,y,z,nx,ny,nz\n0,0.5,0,0,1,0\n0.2,0.5,0.1,0,1,0\n");
    const float triangle[9] = {0, 0, 0, 1, 0, 0, 0, 0, 1};
    std::ofstream(dir + "/buffer.bin", std::ios::binary).write(reinterpret_cast<const char*>(triangle), sizeof triangle);
}

}  // namespace

void initialize() {
    static std::once_flag once;
    std::call_once(once, [] {
        registerFileSourceTypes();
        registerProceduralGenerators();
        scratchDir();
    });
}

const std::string& scratchDir() {
    static std::once_flag once;
    std::call_once(once, [] {
        // Memory-backed where there is /dev/shm: every execution writes its input again.
        const char* base = std::filesystem::is_directory("/dev/shm") ? "/dev/shm" : "/tmp";
        std::string pattern = std::string(base) + "/penumbra-fuzz-XXXXXX";
        if (!::mkdtemp(pattern.data())) std::abort();
        g_dir = pattern;
        std::atexit(removeScratch);
        writeSideFiles(g_dir);
    });
    return g_dir;
}

std::string writeInput(const uint8_t* data, size_t size, const char* name) {
    const std::string path = scratchDir() + "/" + name;
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (!f || (size && std::fwrite(data, 1, size, f) != size) || std::fclose(f) != 0) std::abort();
    return path;
}

void rejected(const InputError& error) {
    static const bool verbose = std::getenv("PENUMBRA_FUZZ_VERBOSE") != nullptr;
    if (verbose) std::fprintf(stderr, "rejected: %s\n", error.what());
}

uint64_t drain(TriangleSource& source, uint64_t limit) {
    std::vector<Triangle> chunk(4096);
    uint64_t total = 0;
    while (total < limit)
        if (size_t n = source.read(chunk)) total += n;
        else break;
    return total;
}

}  // namespace penumbra::fuzz
