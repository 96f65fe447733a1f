#pragma once
// Small OBJ meshes the lightmap tests write into scratch directories.

#include <fstream>
#include <string>

namespace penumbra::test {

inline void writeText(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

/// Unit quad in the XZ plane facing +Y, UV = (x, 1 - z) after the OBJ flip, two triangles.
inline const char* kQuadObj = "v 0 0 0\nv 1 0 0\nv 1 0 -1\nv 0 0 -1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 1 0\n"
                              "f 1/1/1 2/2/1 3/3/1 4/4/1\n";

}  // namespace penumbra::test
