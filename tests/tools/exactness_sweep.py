#!/usr/bin/env python3
"""Random held-out variants of the examples, checked end to end through the CLI.

Each case takes an example scene, replaces its lights with one or two random ones (rect, 4x rect,
disk, sphere, polygon, narrow or wide sun; 16, 64 or 256 samples; 1, 3 or 8 sets), bakes it at a
small size with an exact method (hpc, or ssv) and with `--method embree`, each with `--dump`, and
runs `penumbra compare --scene` on the two dumps: exit 0 means every mismatch is a tie that the
blocking rule classifies. Every other case also bakes with one and two threads and in three
receiver shards (merged), and requires the outputs to be the same bytes.

The scenes are not the tests' own, so this finds what fixed scenes miss. CTest runs a few cases
with a fixed seed; for a longer run:

    python3 tests/tools/exactness_sweep.py build/penumbra examples --seed 7 --cases 100

Exit 0 when every case passes; 1 with one line per failing case (its scene is kept in --keep).
"""

import argparse
import filecmp
import json
import math
import os
import random
import shutil
import subprocess
import sys
import tempfile

EXAMPLES = ["grids.json", "flowers.json", "sponza-like.json", "antialias.json", "glass.json", "gltf-tree.json",
            "lightmap.json", "vertices.json"]


def random_light(rng):
    kind = rng.choice(["rect", "rect4", "disk", "sphere", "polygon", "sun", "wide sun"])
    common = {"samples": rng.choice([16, 64, 256]), "sample_sets": rng.choice([1, 3, 8])}
    c = [rng.uniform(-2, 2), rng.uniform(3, 8), rng.uniform(-2, 2)]
    if kind.startswith("rect"):
        a, t = rng.uniform(0.2, 2) * (4 if kind == "rect4" else 1), rng.uniform(0, math.pi)
        return {"type": "rect", "center": c, "u": [a * math.cos(t), 0, a * math.sin(t)],
                "v": [-a * math.sin(t), rng.uniform(-0.3, 0.3), a * math.cos(t)], **common}
    if kind == "disk":
        return {"type": "disk", "center": c, "normal": [rng.uniform(-.5, .5), -1, rng.uniform(-.5, .5)],
                "radius": rng.uniform(0.1, 3), **common}
    if kind == "sphere":
        return {"type": "sphere", "center": c, "radius": rng.uniform(0.1, 1.5), **common}
    if kind == "polygon":
        r, (x, y, z) = rng.uniform(0.3, 2), c
        return {"type": "polygon", "vertices": [[x + r, y, z], [x, y, z + r], [x - r, y, z], [x - r / 2, y, z - r]], **common}
    return {"type": "sun", "direction": [rng.uniform(-1, 1), -1, rng.uniform(-1, 1)],
            "angular_diameter_deg": rng.uniform(0.2, 20 if kind == "wide sun" else 3), **common}


def variant(rng, examples, size):
    name = rng.choice(EXAMPLES)
    with open(os.path.join(examples, name)) as f:
        scene = json.load(f)
    scene["lights"] = [random_light(rng) for _ in range(rng.choice([1, 1, 2]))]
    receivers = scene.get("receivers", {})
    if receivers.get("type") == "camera":
        receivers["width"], receivers["height"] = size, size * 3 // 4
    elif receivers.get("type") == "lightmap":
        receivers["resolution"] = max(64, size)  # room for the charts and their padding
    scene.pop("output", None)
    return name, scene


def bake(penumbra, scene_path, args, what):
    """Runs `penumbra bake` on the scene; None when it succeeds, else what failed."""
    r = subprocess.run([penumbra, "bake", scene_path, "-q", *args], capture_output=True, text=True, timeout=1800)
    return None if r.returncode == 0 else f"{what} exited {r.returncode}: {r.stderr.strip()[-200:]}"


def same_outputs(a, b):
    names = sorted(os.listdir(a))
    if names != sorted(os.listdir(b)):
        return False
    match, mismatch, errors = filecmp.cmpfiles(a, b, names, shallow=False)
    return not mismatch and not errors


def check_case(penumbra, scene_path, scene, rng, work, determinism):
    """Returns None when the case passes, else what failed."""
    out = "out.glb" if scene.get("receivers", {}).get("type") == "vertices" else "out.exr"
    method = rng.choice(["hpc", "hpc", "ssv"])
    extra = rng.choice([[], ["--disable", "footprints"], ["--disable", "front-plane"], ["--simd", "scalar"]])
    for tag, m in {"exact": [method] + extra, "embree": ["embree"]}.items():
        os.makedirs(os.path.join(work, tag))
        dump = ["--dump", os.path.join(work, tag, "dump"), "-o", os.path.join(work, tag, out)]
        if failure := bake(penumbra, scene_path, ["--threads", "2", "--method", *m, *dump], f"{tag} bake ({' '.join(m)})"):
            return failure
    r = subprocess.run([penumbra, "compare", os.path.join(work, "embree", "dump"), os.path.join(work, "exact", "dump"),
                        "--scene", scene_path], capture_output=True, text=True, timeout=1800)
    if r.returncode:
        return f"{method} {' '.join(extra)} against embree: {r.stdout.strip().splitlines()[-1:]}"
    if not determinism:
        return None
    dirs = {threads: os.path.join(work, f"threads{threads}") for threads in (1, 2)}
    for threads, d in dirs.items():
        os.makedirs(d)
        if failure := bake(penumbra, scene_path, ["--threads", str(threads), "-o", os.path.join(d, out)], f"bake on {threads} thread(s)"):
            return failure
    if not same_outputs(dirs[1], dirs[2]):
        return "outputs differ between 1 and 2 threads"
    if any("translucent" in g for g in scene.get("geometry", [])):  # such scenes cannot be sharded (documented)
        return None
    shards, merged = os.path.join(work, "shards"), os.path.join(work, "merged")
    os.makedirs(merged)
    for i in range(3):
        if failure := bake(penumbra, scene_path, ["--threads", "1", "--shard", f"{i}/3", "--shard-dir", shards], f"shard {i}/3"):
            return failure
    if failure := bake(penumbra, scene_path, ["--merge", "--shard-dir", shards, "-o", os.path.join(merged, out)], "merge"):
        return failure
    if not same_outputs(dirs[2], merged):
        return "merged shards differ from the single bake"
    return None


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("penumbra")
    p.add_argument("examples")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--cases", type=int, default=4)
    p.add_argument("--size", type=int, default=64, help="camera width (and lightmap texels per side, at least 64)")
    p.add_argument("--keep", default=None, help="directory for the scenes of failing cases")
    a = p.parse_args()
    rng = random.Random(a.seed)
    failures = 0
    for i in range(a.cases):
        name, scene = variant(rng, a.examples, a.size)
        # The scene sits beside the examples so that their relative file names resolve.
        fd, scene_path = tempfile.mkstemp(prefix=".sweep-", suffix=".json", dir=a.examples)
        work = tempfile.mkdtemp(prefix="penumbra-sweep-")
        try:
            with os.fdopen(fd, "w") as f:
                json.dump(scene, f)
            failure = check_case(a.penumbra, scene_path, scene, rng, work, determinism=i % 2 == 0)
            if failure and a.keep:
                os.makedirs(a.keep, exist_ok=True)
                shutil.copy(scene_path, os.path.join(a.keep, f"case{i}-{name}"))
        finally:
            os.remove(scene_path)
            shutil.rmtree(work, ignore_errors=True)
        lights = "+".join(l["type"] for l in scene["lights"])
        print(f"case {i}: {name}, {lights}: {failure or 'ok'}", flush=True)
        failures += failure is not None
    print(f"{a.cases - failures} of {a.cases} cases passed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
