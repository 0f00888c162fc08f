"""The binding gives exactly what the C++ library gives: the progiso command's output, and the
engine's cuts against the one-shot call."""

import subprocess

import numpy as np
import pytest

import progiso
from conftest import load, progiso_exe, read_ply, triangle_set


def run_command(tmp_path, vol, iso, *extra):
    raw = tmp_path / "v.raw"
    vol.tofile(raw)
    dtype = {np.dtype("uint8"): "u8", np.dtype("<i2"): "i16", np.dtype("<f4"): "f32"}[vol.dtype]
    out = tmp_path / "out.ply"
    subprocess.run([progiso_exe(), "extract", str(raw), "--dims",
                    ",".join(str(s) for s in vol.shape[::-1]), "--type", dtype, "--iso",
                    str(iso), "-o", str(out), *extra], check=True, capture_output=True)
    verts, faces = read_ply(out)
    return verts[:, ::-1].copy(), faces  # to axis order


@pytest.mark.parametrize("name,iso", [("hipip", 128), ("headsq", 500)])
def test_full_surface_equals_the_commands_vertex_for_vertex(tmp_path, name, iso):
    vol, _, _ = load(name)
    verts, faces = run_command(tmp_path, vol, iso, "--full", "--threads", "2")
    v, fc, _, _ = progiso.marching_cubes(vol, iso)
    np.testing.assert_array_equal(v, verts)
    np.testing.assert_array_equal(fc, faces)


def test_error_goal_equals_the_commands(tmp_path):
    vol, _, _ = load("neghip")
    verts, faces = run_command(tmp_path, vol, 64, "--error", "0.5")
    v, fc, _, _ = progiso.marching_cubes(vol, 64, max_error=0.5)
    assert len(fc) < len(progiso.marching_cubes(vol, 64)[1])
    assert triangle_set(v, fc) == triangle_set(verts, faces)


def test_engine_cuts_equal_the_one_shot_surfaces():
    vol, spacing, _ = load("headsq")
    with progiso.Engine(vol, 500, spacing=spacing, threads=2) as eng:
        assert eng.refine()
        snap = eng.snapshot()
        assert snap.uniform_stride == 1
        v, fc, n, _ = progiso.marching_cubes(vol, 500, spacing=spacing)
        assert triangle_set(snap.vertices, snap.faces) == triangle_set(v, fc)
        eng.set_isovalue(1150)
        assert eng.refine(max_error=1.0)
        snap = eng.snapshot()
        v, fc, _, _ = progiso.marching_cubes(vol, 1150, spacing=spacing, max_error=1.0)
        assert triangle_set(snap.vertices, snap.faces) == triangle_set(v, fc)
