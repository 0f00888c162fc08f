"""Writes the bumpy sphere the MPI and out-of-core figures use (bench/README.md): an N³ uint8
raw volume, x fastest, whose isovalue 120 is a sphere of radius 0.39 N with bumps of 0.012 N.

usage: make_bumpy_sphere.py OUT.raw [N]   (N = 1024 by default: 1 GiB)
"""
import sys

import numpy as np


def main():
    out = sys.argv[1]
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 1024
    s = n / 1024.0  # the figures' shape at any size
    c = (n - 1) / 2.0
    x = np.arange(n, dtype=np.float64)
    dx2 = ((x - c) ** 2)[None, :]
    dy2 = ((x - c) ** 2)[:, None]
    sx = np.sin(x * 0.05 / s)[None, :]
    sy = np.sin(x * 0.043 / s)[:, None]
    with open(out, "wb") as f:
        for z in range(n):
            r = np.sqrt(dx2 + dy2 + (z - c) ** 2)
            bump = 12.0 * s * sx * sy * np.sin(z * 0.061 / s)
            v = 120.0 + (400.0 * s + bump - r) * 0.8 / s
            f.write(np.clip(v, 0.0, 255.0).astype(np.uint8).tobytes())


if __name__ == "__main__":
    main()
