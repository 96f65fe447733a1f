#!/usr/bin/env python3
"""Peak RSS of a 100M-triangle bake whose grass comes from NumPy, against the built-in generator.

    PYTHONPATH=build/python python3 examples/python/bench_memory.py [--tmp DIR] [--width 1280]

Each bake runs in a child process of its own (peak RSS from getrusage). "builtin" is
examples/meadow-100m.json as it is (20M grass blades x 5 triangles, terrain, trees); "numpy"
replaces its grass entry by meadow.py's NumPy blades, 20M x 5 triangles streamed chunk by chunk
from a callable (the same count over the same square; the terrain and trees are unchanged).
"""
import argparse
import json
import pathlib
import resource
import subprocess
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent
EXAMPLES = HERE.parent


def child(mode, tmp, width, blades):
    import penumbra
    sys.path.insert(0, str(HERE))
    from meadow import blades as numpy_blades

    scene = json.loads((EXAMPLES / "meadow-100m.json").read_text())
    scene["receivers"]["width"], scene["receivers"]["height"] = width, width * 3 // 4
    if mode == "numpy":
        grass = next(g for g in scene["geometry"] if g["type"] == "grass")
        scene["geometry"].remove(grass)
        s = penumbra.Scene(scene, base_dir=str(EXAMPLES))
        s.add_source(numpy_blades(blades, extent=100.0), count=5 * blades)
    else:
        s = penumbra.Scene(scene, base_dir=str(EXAMPLES))
    started = time.monotonic()
    result = penumbra.bake(s, tmp_dir=tmp)
    print(json.dumps({"mode": mode, "triangles": result.stats["counters"]["triangles_read"],
                      "receivers": len(result), "seconds": round(time.monotonic() - started, 1),
                      "peak_rss_mib": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)}))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tmp", default="/tmp")
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--blades", type=int, default=20_000_000)
    parser.add_argument("--child", choices=["builtin", "numpy"])
    args = parser.parse_args()
    if args.child:
        return child(args.child, args.tmp, args.width, args.blades)
    print("| source | triangles | receivers | bake time | peak RSS |\n|---|---:|---:|---:|---:|")
    for mode in ("builtin", "numpy"):
        out = subprocess.run([sys.executable, __file__, "--child", mode, "--tmp", args.tmp, "--width", str(args.width),
                              "--blades", str(args.blades)], check=True, capture_output=True, text=True).stdout
        r = json.loads(out.strip().splitlines()[-1])
        print(f"| {mode} | {r['triangles']:,} | {r['receivers']:,} | {r['seconds']} s | {r['peak_rss_mib']} MiB |")


if __name__ == "__main__":
    main()
