// Tests for the .npy reader and writer: round trips, numpy-style headers written by hand,
// and hostile input (every truncation, corrupt header fields).

#include "stream/util/Error.h"
#include "stream/util/Npy.h"

#include "TestSupport.h"

#include <catch2/catch.hpp>

#include <stdlib.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <sstream>

using namespace penumbra::test;
namespace fs = std::filesystem;
using penumbra::InputError;
using penumbra::NpyArray;

namespace {

void spit(const std::string& path, const std::string& bytes) {
    std::ofstream(path, std::ios::binary | std::ios::trunc).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

/// A .npy file as numpy would lay it out, from a header dict given verbatim.
std::string makeNpy(int major, const std::string& dict, const std::string& data, bool pad = true) {
    const size_t prefix = major == 1 ? 10 : 12;
    std::string header = dict;
    if (pad) {
        size_t total = prefix + header.size() + 1;
        header.append((64 - total % 64) % 64, ' ');
    }
    header.push_back('\n');
    std::string out("\x93NUMPY", 6);
    out.push_back(static_cast<char>(major));
    out.push_back('\0');
    for (size_t i = 0; i < (major == 1 ? 2u : 4u); ++i)
        out.push_back(static_cast<char>((header.size() >> (8 * i)) & 0xFF));
    return out + header + data;
}

std::string floatBytes(std::initializer_list<float> values) {
    std::string s(values.size() * 4, '\0');
    std::memcpy(s.data(), values.begin(), s.size());
    return s;
}

}  // namespace

TEST_CASE("writeNpy/readNpy round-trip every supported dtype", "[io]") {
    ScratchDir dir;
    std::mt19937 rng(7);
    const std::vector<std::pair<std::string, size_t>> dtypes = {
        {"<f4", 4}, {"<f8", 8}, {"<f2", 2}, {"<i4", 4}, {"<u8", 8}, {"<i8", 8}, {"<u4", 4},
        {"<i2", 2}, {"<u2", 2}, {"|u1", 1}, {"|i1", 1}, {"|b1", 1}};
    const std::vector<std::vector<uint64_t>> shapes = {{5}, {2, 3}, {}, {0}, {2, 0, 4}, {1, 1, 1, 3}};
    for (const auto& [dtype, size] : dtypes) {
        for (const auto& shape : shapes) {
            size_t count = 1;
            for (auto d : shape) count *= d;
            std::vector<uint8_t> data(count * size);
            for (auto& b : data) b = static_cast<uint8_t>(rng());
            if (dtype == "|b1") for (auto& b : data) b &= 1;
            const std::string path = dir.file("a.npy");
            penumbra::writeNpy(path, dtype, shape, data.data(), data.size());

            std::string raw = slurp(path);
            const size_t headerLen = static_cast<uint8_t>(raw[8]) | (static_cast<uint8_t>(raw[9]) << 8);
            INFO(dtype << " " << raw.substr(10, headerLen));
            CHECK(raw.substr(0, 8) == std::string("\x93NUMPY\x01\x00", 8));
            CHECK((10 + headerLen) % 64 == 0);
            CHECK(raw[10 + headerLen - 1] == '\n');
            CHECK(raw.size() == 10 + headerLen + data.size());

            NpyArray a = penumbra::readNpy(path);
            CHECK(a.dtype == dtype);
            CHECK(a.shape == shape);
            CHECK(a.elementCount() == count);
            CHECK(a.itemSize() == size);
            CHECK(a.data == data);
        }
    }
}

TEST_CASE("writeNpy emits exactly numpy's header text", "[io]") {
    ScratchDir dir;
    const std::string path = dir.file("n.npy");
    float v[3] = {1, 2, 3};
    const uint64_t shape1[] = {3};
    penumbra::writeNpy(path, "<f4", shape1, v, sizeof v);
    // np.save("n.npy", np.array([1, 2, 3], dtype="<f4")) writes this 128-byte prefix.
    const std::string numpyHeader =
        "{'descr': '<f4', 'fortran_order': False, 'shape': (3,), }" + std::string(60, ' ') + "\n";
    CHECK(slurp(path) == std::string("\x93NUMPY\x01\x00\x76\x00", 10) + numpyHeader +
                             std::string(reinterpret_cast<const char*>(v), sizeof v));

    const uint64_t shape2[] = {1, 3};
    penumbra::writeNpy(path, "<f4", shape2, v, sizeof v);
    CHECK(slurp(path).substr(10, 60) ==
          "{'descr': '<f4', 'fortran_order': False, 'shape': (1, 3), } ");
    penumbra::writeNpy(path, "<f4", {}, v, 4);
    CHECK(slurp(path).substr(10, 56) == "{'descr': '<f4', 'fortran_order': False, 'shape': (), } ");
}

TEST_CASE("readNpy accepts numpy-style headers written by hand", "[io]") {
    ScratchDir dir;
    const std::string path = dir.file("h.npy");
    const std::string data = floatBytes({1, 2, 3, 4, 5, 6});
    struct Case {
        int major;
        std::string dict;
        std::vector<uint64_t> shape;
        bool pad = true;
    };
    const std::vector<Case> cases = {
        {1, "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }", {2, 3}},
        {1, "{'descr': '<f4', 'fortran_order': False, 'shape': (6,)}", {6}, false},
        {1, "{\"shape\": (3, 2), \"fortran_order\": False, \"descr\": \"<f4\"}", {3, 2}},
        {1, "{ 'descr' : '=f4' , 'fortran_order' : False , 'shape' : ( 6 , ) , }", {6}},
        {1, "{'descr': '<f4', 'fortran_order': False, 'shape': (2L, 3L), }", {2, 3}},
        {1, "{'descr': '<f4', 'fortran_order': False, 'shape': (1, 1, 6), }", {1, 1, 6}},
        {2, "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }", {2, 3}},
        {3, "{'descr': '<f4', 'fortran_order': False, 'shape': (6,), }", {6}},
    };
    for (const Case& c : cases) {
        INFO(c.dict);
        spit(path, makeNpy(c.major, c.dict, data, c.pad));
        NpyArray a = penumbra::readNpy(path);
        CHECK(a.dtype == "<f4");
        CHECK(a.shape == c.shape);
        CHECK(penumbra::npyAsFloat32(a, path) == std::vector<float>{1, 2, 3, 4, 5, 6});
    }

    spit(path, makeNpy(1, "{'descr': '<u1', 'fortran_order': False, 'shape': (), }", "\x2a"));
    NpyArray scalar = penumbra::readNpy(path);
    CHECK(scalar.dtype == "|u1");
    CHECK(scalar.shape.empty());
    CHECK(scalar.elementCount() == 1);
    CHECK(scalar.data == std::vector<uint8_t>{42});
}

TEST_CASE("readNpy rejects every truncated prefix of a valid file", "[io]") {
    ScratchDir dir;
    const std::string good = dir.file("good.npy"), cut = dir.file("cut.npy");
    const double values[4] = {1.5, -2, 1e300, 0};
    const uint64_t shape[] = {2, 2};
    penumbra::writeNpy(good, "<f8", shape, values, sizeof values);
    const std::string bytes = slurp(good);
    REQUIRE(penumbra::readNpy(good).data.size() == sizeof values);
    for (size_t n = 0; n < bytes.size(); ++n) {
        spit(cut, bytes.substr(0, n));
        std::string msg = errorOf([&] { penumbra::readNpy(cut); });
        INFO("prefix of " << n << " bytes: " << msg);
        CHECK(msg.rfind(cut + ": ", 0) == 0);
        CHECK(msg.find('\n') == std::string::npos);
    }
}

TEST_CASE("readNpy names what is wrong with a corrupt file", "[io]") {
    ScratchDir dir;
    const std::string path = dir.file("pts.npy");
    const std::string six = floatBytes({1, 2, 3, 4, 5, 6});
    auto header = [](const std::string& descr, const std::string& order, const std::string& shape) {
        return "{'descr': " + descr + ", 'fortran_order': " + order + ", 'shape': " + shape + ", }";
    };
    struct Case {
        std::string bytes;
        std::string expect;
    };
    std::string v9 = makeNpy(1, header("'<f4'", "False", "(6,)"), six);
    v9[6] = 9;
    std::string v11 = makeNpy(1, header("'<f4'", "False", "(6,)"), six);
    v11[7] = 1;
    std::string longHeader = makeNpy(1, header("'<f4'", "False", "(6,)"), "");
    longHeader[8] = '\xff';
    longHeader[9] = '\x7f';
    const std::vector<Case> cases = {
        {"PK\x03\x04 this is a zip file, not an array", "not a .npy file"},
        {v9, "unsupported .npy format version 9.0"},
        {v11, "unsupported .npy format version 1.1"},
        {longHeader, "header length 32767 runs past the end of the file"},
        {makeNpy(1, header("'>f4'", "False", "(6,)"), six), "big-endian dtype '>f4' is not supported"},
        {makeNpy(1, header("'<f4'", "True", "(6,)"), six), "Fortran order"},
        {makeNpy(1, header("[('x', '<f4'), ('y', '<f4')]", "False", "(3,)"), six), "structured dtypes"},
        {makeNpy(1, header("'<c8'", "False", "(3,)"), six), "unsupported dtype '<c8'"},
        {makeNpy(1, header("'|O'", "False", "(6,)"), six), "unsupported dtype '|O'"},
        {makeNpy(1, header("'<U4'", "False", "(6,)"), six), "unsupported dtype '<U4'"},
        {makeNpy(1, header("'<f4'", "maybe", "(6,)"), six), "fortran_order must be True or False"},
        {makeNpy(1, header("'<f4'", "False", "(6)"), six), "shape (6) is not a tuple"},
        {makeNpy(1, header("'<f4'", "False", "(-6,)"), six), "non-negative integers"},
        {makeNpy(1, header("'<f4'", "False", "[6]"), six), "shape must be a tuple"},
        {makeNpy(1, header("'<f4'", "False", "(6, 'a')"), six), "non-negative integers"},
        {makeNpy(1, header("'<f4'", "False", "(99999999999999999999,)"), six), "shape entry is too large"},
        {makeNpy(1, header("'<f4'", "False", "(4294967296, 4294967296)"), six), "is too large"},
        {makeNpy(1, "{'descr': '<f4', 'shape': (6,), }", six), "missing key 'fortran_order'"},
        {makeNpy(1, "{'fortran_order': False, 'shape': (6,), }", six), "missing key 'descr'"},
        {makeNpy(1, "{'descr': '<f4', 'fortran_order': False}", six), "missing key 'shape'"},
        {makeNpy(1, header("'<f4'", "False", "(6,)") + " extra", six), "unexpected text after"},
        {makeNpy(1, "{'descr': '<f4', 'fortran_order': False, 'shape': (6,), 'x': 1}", six),
         "unexpected key 'x'"},
        {makeNpy(1, "{'descr': '<f4', 'descr': '<f4', 'fortran_order': False, 'shape': (6,)}", six),
         "key 'descr' appears twice"},
        {makeNpy(1, "{'descr: '<f4', 'fortran_order': False, 'shape': (6,)}", six), "bad .npy header"},
        {makeNpy(1, "('descr', '<f4')", six), "must be a Python dict"},
        {makeNpy(1, "", six), "must be a Python dict"},
        {makeNpy(1, header("'<f4'", "False", "(6,)"), six + "xx"), "but file has 26 bytes of data"},
    };
    for (const Case& c : cases) {
        spit(path, c.bytes);
        std::string msg = errorOf([&] { penumbra::readNpy(path); });
        INFO(msg);
        CHECK(msg.rfind(path + ": ", 0) == 0);
        CHECK(msg.find(c.expect) != std::string::npos);
        CHECK(msg.find('\n') == std::string::npos);
    }

    // The message users see for a half-copied point list.
    spit(path, makeNpy(1, header("'<f4'", "False", "(1000, 6)"), std::string(12000, '\0')));
    CHECK(errorOf([&] { penumbra::readNpy(path); }) ==
          path + ": header says 1000x6 float32 (24000 bytes) but file has 12000 bytes of data");

    CHECK(errorOf([&] { penumbra::readNpy(dir.file("absent.npy")); }) ==
          dir.file("absent.npy") + ": cannot open: No such file or directory");
    CHECK(errorOf([&] { penumbra::readNpy(dir.path.string()); }).find("is a directory") != std::string::npos);
}

TEST_CASE("npyAsFloat32 converts float arrays and rejects the rest", "[io]") {
    NpyArray f8;
    f8.dtype = "<f8";
    f8.shape = {3};
    const double d[3] = {0.5, -1e-3, 1e10};
    f8.data.assign(reinterpret_cast<const uint8_t*>(d), reinterpret_cast<const uint8_t*>(d) + sizeof d);
    CHECK(penumbra::npyAsFloat32(f8, "x.npy") == std::vector<float>{0.5f, -1e-3f, 1e10f});

    NpyArray i4;
    i4.dtype = "<i4";
    i4.shape = {1};
    i4.data.assign(4, 0);
    CHECK(errorOf([&] { penumbra::npyAsFloat32(i4, "x.npy"); }) ==
          "x.npy: expected a float32 or float64 array but got int32 ('<i4')");
}

TEST_CASE("writeNpy validates its arguments", "[io]") {
    ScratchDir dir;
    const std::string path = dir.file("w.npy");
    float v[4] = {};
    const uint64_t shape[] = {5};
    CHECK(errorOf([&] { penumbra::writeNpy(path, "<f4", shape, v, sizeof v); }).find("needs 20 bytes but 16") !=
          std::string::npos);
    const uint64_t four[] = {4};
    CHECK(errorOf([&] { penumbra::writeNpy(path, ">f4", four, v, sizeof v); }).find("big-endian") !=
          std::string::npos);
    CHECK_FALSE(fs::exists(path));
    CHECK(errorOf([&] { penumbra::writeNpy(dir.file("no/such/dir.npy"), "<f4", four, v, sizeof v); })
              .find("cannot create file") != std::string::npos);
    CHECK(fs::is_empty(dir.path));
}
