#include "receivers/PointReceivers.h"
#include "stream/util/PathText.h"

#include "stream/util/Csv.h"
#include "stream/util/Error.h"
#include "stream/util/Npy.h"

#include <glm/geometric.hpp>

#include <cmath>
#include <filesystem>
#include <span>

namespace penumbra {
namespace {

/// Position and normal per row.
bool isPointArray(std::span<const uint64_t> shape) { return shape.size() == 2 && shape[1] == 6; }

}  // namespace

ReceiverSet loadPointReceivers(const std::string& path) {
    std::vector<float> values;
    std::string ext = lowercaseExtension(path);
    if (ext == ".csv") {
        for (const auto& row : readCsvNumbers(path, 6))
            for (double v : row) values.push_back(float(v));
    } else {
        NpyArray array = readNpy(path);
        if (!isPointArray(array.shape))
            fail(path, "expected an N x 6 array (position, normal), got shape of {} dimensions{}", array.shape.size(),
                 array.shape.size() == 2 ? fmt::format(" ({} x {})", array.shape[0], array.shape[1]) : "");
        values = npyAsFloat32(array, path);
    }
    ReceiverSet set;
    const size_t n = values.size() / 6;
    set.position.resize(n), set.normal.resize(n);
    for (size_t i = 0; i < n; ++i) {
        const float* v = &values[i * 6];
        for (int c = 0; c < 6; ++c)
            if (!std::isfinite(v[c])) fail(path, "receiver {} has a non-finite value in column {}", i, c);
        set.position[i] = {v[0], v[1], v[2]};
        glm::vec3 normal(v[3], v[4], v[5]);
        float len = glm::length(normal);
        set.normal[i] = len > 0 ? normal / len : normal;
    }
    return set;
}

std::optional<uint64_t> pointReceiverBound(const std::string& path) {
    if (lowercaseExtension(path) != ".npy") return std::nullopt;
    try {
        const NpyRowReader rows(path);
        if (!isPointArray(rows.header().shape)) return std::nullopt;
        return rows.header().shape[0];
    } catch (const InputError&) {
        return std::nullopt;
    }
}

}  // namespace penumbra
