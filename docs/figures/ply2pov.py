#!/usr/bin/env python3
"""Writes a binary little-endian PLY triangle mesh (as progiso writes it) as a POV-Ray mesh2.

usage: ply2pov.py IN.ply NAME > OUT.inc   (declares NAME, and NAME_min / NAME_max: its box)
"""
import struct
import sys


def read_ply(path):
    with open(path, "rb") as f:
        header = []
        while True:
            line = f.readline().decode("ascii").strip()
            header.append(line)
            if line == "end_header":
                break
        if "format binary_little_endian 1.0" not in header:
            sys.exit(f"{path}: expected a binary little-endian PLY, found {header[1:2]}")
        nv = nf = 0
        for line in header:
            if line.startswith("element vertex"):
                nv = int(line.split()[2])
            elif line.startswith("element face"):
                nf = int(line.split()[2])
        verts = list(struct.iter_unpack("<3f", f.read(12 * nv)))
        data = f.read(13 * nf)
        faces = []
        for k in range(nf):
            n, a, b, c = struct.unpack_from("<B3i", data, 13 * k)
            if n != 3:
                sys.exit(f"{path}: face {k} has {n} vertices, expected 3")
            faces.append((a, b, c))
        return verts, faces


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    verts, faces = read_ply(sys.argv[1])
    name = sys.argv[2]
    out = sys.stdout
    lo = [min(v[q] for v in verts) for q in range(3)]
    hi = [max(v[q] for v in verts) for q in range(3)]
    out.write(f"#declare {name}_min = <{lo[0]:.4f},{lo[1]:.4f},{lo[2]:.4f}>;\n")
    out.write(f"#declare {name}_max = <{hi[0]:.4f},{hi[1]:.4f},{hi[2]:.4f}>;\n")
    out.write(f"#declare {name} = mesh2 {{\n vertex_vectors {{ {len(verts)},\n")
    out.write(",\n".join(f"<{x:.4f},{y:.4f},{z:.4f}>" for x, y, z in verts))
    out.write(f"\n }}\n face_indices {{ {len(faces)},\n")
    out.write(",\n".join(f"<{a},{b},{c}>" for a, b, c in faces))
    out.write("\n }\n}\n")


main()
