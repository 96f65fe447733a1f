"""examples/python run, and the baked penumbra profile follows the analytic one."""
import os
import re
import subprocess
import sys

from conftest import BUILD, SOURCE


def run(script, *args, cwd):
    env = dict(os.environ, PYTHONPATH=str(BUILD / "python"))
    return subprocess.run([sys.executable, str(SOURCE / "examples/python" / script), *args], check=True, env=env,
                          capture_output=True, text=True, cwd=cwd).stdout


def test_penumbra_profile_matches_the_analytic_ramp(tmp_path):
    out = run("penumbra_profile.py", "-o", str(tmp_path / "p.png"), "--samples", "256", cwd=tmp_path)
    error = float(re.search(r"max \|baked - analytic\| = ([0-9.]+)", out).group(1))
    # 256 samples stratify the light in 16 columns across the edge: at most one column off.
    assert error < 1 / 16 and (tmp_path / "p.png").stat().st_size > 0


def test_meadow_and_lightmap_examples_write_their_outputs(tmp_path):
    run("meadow.py", "--blades", "3000", "-o", str(tmp_path / "m.exr"), "--threads", "2", cwd=tmp_path)
    assert (tmp_path / "m.exr").exists() and (tmp_path / "m.png").exists()
    run("lightmap.py", "--resolution", "32", "-o", str(tmp_path / "l.exr"), cwd=tmp_path)
    assert (tmp_path / "l-atlas.exr").exists()
