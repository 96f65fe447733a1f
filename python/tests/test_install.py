"""`cmake --install` puts a package that Debian's /usr/bin/python3 imports."""
import subprocess
import sys

from conftest import BUILD


def test_cmake_install_gives_an_importable_package(tmp_path):
    subprocess.run(["cmake", "--install", str(BUILD), "--prefix", str(tmp_path)], check=True, capture_output=True)
    site = tmp_path / f"lib/python3.{sys.version_info.minor}/dist-packages"
    assert (site / "penumbra" / "__init__.pyi").exists() and (site / "penumbra" / "py.typed").exists()
    code = ("import penumbra, numpy as np; "
            "s = penumbra.Scene({'lights': [{'type': 'rect', 'center': [0, 2, 0], 'u': [1, 0, 0], 'v': [0, 0, 1]}]}, "
            "points=(np.zeros((3, 3)), np.tile([0, 1, 0], (3, 1)))); "
            "print(penumbra.__file__, penumbra.bake(s).visibility.tolist())")
    out = subprocess.run(["/usr/bin/python3", "-I", "-c", f"import sys; sys.path.insert(0, {str(site)!r}); {code}"],
                         check=True, capture_output=True, text=True, cwd=tmp_path).stdout
    assert out.startswith(str(site)) and "[1.0, 1.0, 1.0]" in out
