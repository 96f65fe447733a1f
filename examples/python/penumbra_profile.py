#!/usr/bin/env python3
"""The penumbra behind a straight edge, baked and plotted against the analytic profile.

    python3 examples/python/penumbra_profile.py -o docs/images/penumbra-profile.png

A rect light 2a wide at height H, a half-plane blocker (x < 0) at height h, receivers along the
floor. A receiver at x sees the light point x_l past the edge when x_l >= x (1 - H/h), so its
visible fraction is clamp((a - x (1 - H/h)) / 2a, 0, 1): a linear ramp across the penumbra.
"""
import argparse
import pathlib

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import penumbra  # noqa: E402

A, H, EDGE = 1.0, 4.0, 2.0  # light half-width, light height, blocker height


def analytic(x):
    return np.clip((A - x * (1 - H / EDGE)) / (2 * A), 0, 1)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default="docs/images/penumbra-profile.png")
    parser.add_argument("--samples", type=int, default=1024)
    args = parser.parse_args()
    x = np.linspace(-2, 2, 801, dtype=np.float32)
    positions = np.stack([x, np.zeros_like(x), np.zeros_like(x)], 1)
    normals = np.tile(np.float32([0, 1, 0]), (len(x), 1))
    scene = penumbra.Scene({
        "lights": [{"type": "rect", "center": [0, H, 0], "u": [2 * A, 0, 0], "v": [0, 0, 2 * A],
                    "samples": args.samples}],
    }, points=(positions, normals))
    half_plane = np.float32([[[-50, EDGE, -50], [0, EDGE, -50], [0, EDGE, 50]],
                             [[-50, EDGE, -50], [0, EDGE, 50], [-50, EDGE, 50]]])
    scene.add_source([half_plane])
    result = penumbra.bake(scene)
    error = np.abs(result.visibility - analytic(x)).max()
    fig, ax = plt.subplots(figsize=(7, 3.6), dpi=120)
    ax.plot(x, analytic(x), color="black", lw=2.5, alpha=0.35, label="analytic")
    ax.plot(x, result.visibility, color="tab:blue", lw=1, label=f"penumbra, {result.samples} samples")
    ax.set_xlabel("receiver x (m); edge above x = 0")
    ax.set_ylabel("visible fraction of the light")
    ax.set_title(f"Penumbra behind an edge: max |baked - analytic| = {error:.4f}")
    ax.legend(loc="upper left")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    pathlib.Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.output)
    print(f"max |baked - analytic| = {error:.4f} over {len(x)} receivers -> {args.output}")


if __name__ == "__main__":
    main()
