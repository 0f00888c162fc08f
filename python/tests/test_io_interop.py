"""progiso.read_volume, and surfaces for VTK and trimesh."""

import gzip

import numpy as np
import pytest

import progiso
from conftest import VOLUMES, data_dir, load


def test_raw_files_read_as_numpy_reads_them():
    vol, spacing, _ = load("headsq")
    path = data_dir() / VOLUMES["headsq"][0]
    got = progiso.read_volume(path, raw={"shape": (93, 64, 64), "dtype": "int16"},
                              spacing=spacing)
    np.testing.assert_array_equal(got.array, vol)
    assert got.array.dtype == np.int16 and got.array.flags["C_CONTIGUOUS"]
    assert got.array.flags["OWNDATA"] is False and got.array.flags["WRITEABLE"]
    assert got.spacing == spacing and got.origin == (0.0, 0.0, 0.0)
    assert got.world is None


def test_nrrd_header_gives_spacing_origin_and_world_in_axis_order(tmp_path):
    a = (np.arange(5 * 6 * 7) % 251).astype(np.uint8).reshape(5, 6, 7)  # z, y, x
    header = ("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 7 6 5\nspace: left-posterior-superior\n"
              "space directions: (0.5,0,0) (0,0.75,0) (0,0,2)\nspace origin: (10,20,30)\n"
              "encoding: gzip\n\n")
    path = tmp_path / "v.nrrd"
    path.write_bytes(header.encode() + gzip.compress(a.tobytes()))
    got = progiso.read_volume(path)
    np.testing.assert_array_equal(got.array, a)
    assert got.spacing == (2.0, 0.75, 0.5)
    assert got.origin == (30.0, 20.0, 10.0)
    # world · (i, j, k, 1) for array index (i, j, k) = (z, y, x).
    w = got.world
    np.testing.assert_allclose(w @ [1, 2, 3, 1], [10 + 3 * 0.5, 20 + 2 * 0.75, 30 + 1 * 2, 1])


@pytest.mark.parametrize("kind", ["mha", "vtk"])
def test_metaimage_and_legacy_vtk_read_in_axis_order(tmp_path, kind):
    a = ((np.arange(5 * 6 * 7) * 3) % 65000).astype(np.uint16).reshape(5, 6, 7)
    if kind == "mha":
        header = ("ObjectType = Image\nNDims = 3\nDimSize = 7 6 5\nElementType = MET_USHORT\n"
                  "ElementSpacing = 0.5 0.75 2\nOffset = 10 20 30\nElementDataFile = LOCAL\n")
        data = a.astype("<u2").tobytes()
    else:
        header = ("# vtk DataFile Version 3.0\nprogiso test\nBINARY\nDATASET STRUCTURED_POINTS\n"
                  "DIMENSIONS 7 6 5\nSPACING 0.5 0.75 2\nORIGIN 10 20 30\nPOINT_DATA 210\n"
                  "SCALARS s unsigned_short 1\nLOOKUP_TABLE default\n")
        data = a.astype(">u2").tobytes()
    path = tmp_path / ("v." + kind)
    path.write_bytes(header.encode() + data)
    got = progiso.read_volume(path)
    np.testing.assert_array_equal(got.array, a)
    assert got.array.dtype == np.uint16
    assert got.spacing == (2.0, 0.75, 0.5)
    assert got.origin == (30.0, 20.0, 10.0)
    np.testing.assert_allclose(got.world @ [1, 2, 3, 1], [10 + 1.5, 20 + 1.5, 30 + 2, 1])
    # And the surface of what was read is the surface of the array.
    v, f, _, _ = progiso.marching_cubes(got.array, 300.5, spacing=got.spacing)
    v2, f2, _, _ = progiso.marching_cubes(a, 300.5, spacing=(2.0, 0.75, 0.5))
    np.testing.assert_array_equal(v, v2)


def test_ome_zarr_levels_and_time_points_read_as_zarr_reads_them(tmp_path):
    zarr = pytest.importorskip("zarr")
    numcodecs = pytest.importorskip("numcodecs")
    rng = np.random.default_rng(5)
    full = rng.integers(0, 60000, size=(2, 1, 12, 10, 9)).astype("<u2")
    root = zarr.open_group(str(tmp_path / "img.zarr"), mode="w")
    datasets = []
    for k in range(2):
        root.create_dataset(str(k), data=full[:, :, ::2 ** k, ::2 ** k, ::2 ** k],
                            chunks=(1, 1, 5, 5, 5), compressor=numcodecs.Zstd())
        datasets.append({"path": str(k), "coordinateTransformations": [
            {"type": "scale", "scale": [1, 1, 2.0 * 2 ** k, 1.5 * 2 ** k, 2 ** k]}]})
    root.attrs["multiscales"] = [{"version": "0.4", "datasets": datasets, "axes": [
        {"name": "t", "type": "time"}, {"name": "c", "type": "channel"},
        {"name": "z", "type": "space"}, {"name": "y", "type": "space"},
        {"name": "x", "type": "space"}]}]
    for k in range(2):
        for t in range(2):
            f = progiso.read_volume(tmp_path / "img.zarr", volume=t, level=k)
            want = zarr.open(str(tmp_path / "img.zarr" / str(k)))[t, 0]
            assert f.array.dtype == np.uint16
            np.testing.assert_array_equal(f.array, want)
            assert f.spacing == pytest.approx((2.0 * 2 ** k, 1.5 * 2 ** k, 2 ** k))
    with pytest.raises(OSError, match="img.zarr: level 2 was chosen"):
        progiso.read_volume(tmp_path / "img.zarr", volume=0, level=2)
    with pytest.raises(ValueError, match="level"):
        progiso.read_volume(tmp_path / "img.zarr", volume=0, level=-1)


def test_file_errors_are_os_errors_naming_the_file(tmp_path):
    missing = tmp_path / "nope.nrrd"
    with pytest.raises(OSError, match="nope.nrrd"):
        progiso.read_volume(missing)
    bad = tmp_path / "bad.nrrd"
    bad.write_bytes(b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 7 6\n\n")
    with pytest.raises(OSError, match="bad.nrrd"):
        progiso.read_volume(bad)
    short = tmp_path / "short.raw"
    short.write_bytes(b"\0" * 10)
    with pytest.raises(OSError, match="short.raw"):
        progiso.read_volume(short, raw={"shape": (2, 2, 4), "dtype": "u8"})
    with pytest.raises(ValueError, match="raw dtype"):
        progiso.read_volume(short, raw={"shape": (2, 2, 4), "dtype": "complex"})


def test_to_vtk_gives_a_polydata_in_xyz_facing_out_of_the_region_above():
    pytest.importorskip("vtkmodules")
    n = 24
    z, y, x = np.mgrid[0:n, 0:n, 0:n].astype(np.float32)
    f = -np.sqrt((x - 11.3) ** 2 + (y - 12.2) ** 2 + (z - 10.1) ** 2)
    out = progiso.marching_cubes(f, -7.0)
    poly = progiso.to_vtk(out)
    assert poly.GetNumberOfPoints() == len(out[0])
    assert poly.GetNumberOfCells() == len(out[1])
    from vtkmodules.util.numpy_support import vtk_to_numpy
    pts = vtk_to_numpy(poly.GetPoints().GetData())
    np.testing.assert_array_equal(pts, out[0][:, ::-1])
    cells = vtk_to_numpy(poly.GetPolys().GetConnectivityArray()).reshape(-1, 3)
    a, b, c = pts[cells[:, 0]], pts[cells[:, 1]], pts[cells[:, 2]]
    centre = np.array([11.3, 12.2, 10.1])
    out_facing = np.sum(np.cross(b - a, c - a) * ((a + b + c) / 3 - centre), axis=1) > 0
    assert out_facing.all()  # the ball is the region above: normals leave it
    normals = vtk_to_numpy(poly.GetPointData().GetNormals())
    np.testing.assert_array_equal(normals, out[2][:, ::-1])


def test_to_trimesh_where_trimesh_is_installed():
    trimesh = pytest.importorskip("trimesh")
    eng = progiso.Engine(np.linspace(0, 1, 8 ** 3).reshape(8, 8, 8), 0.5)
    m = progiso.to_trimesh(eng.snapshot())
    assert isinstance(m, trimesh.Trimesh)


def test_snapshots_are_trimesh_style_pairs():
    eng = progiso.Engine(np.linspace(0, 1, 8 ** 3).reshape(8, 8, 8), 0.5)
    eng.refine()
    s = eng.snapshot()
    assert s.vertices.shape[1] == 3 and s.faces.shape[1] == 3
    assert s.faces.dtype == np.int32 and s.vertices.dtype == np.float32
    assert s.faces.max() < len(s.vertices)


def test_vtp_written_by_the_command_opens_in_vtks_xml_reader(tmp_path):
    pytest.importorskip("vtkmodules")
    import subprocess
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from conftest import progiso_exe, read_ply
    vol, _, _ = load("hipip")
    raw = tmp_path / "v.raw"
    vol.tofile(raw)
    for extra in ([], ["--normals"]):
        common = [progiso_exe(), "extract", str(raw), "--dims", "68,68,68", "--type", "u8",
                  "--iso", "128", *extra]
        subprocess.run(common + ["-o", str(tmp_path / "m.vtp")], check=True, capture_output=True)
        subprocess.run(common + ["-o", str(tmp_path / "m.ply")], check=True, capture_output=True)
        reader = vtkXMLPolyDataReader()
        reader.SetFileName(str(tmp_path / "m.vtp"))
        reader.Update()
        poly = reader.GetOutput()
        verts, faces = read_ply(tmp_path / "m.ply")
        assert poly.GetNumberOfPoints() == len(verts)
        assert poly.GetNumberOfCells() == len(faces)
        np.testing.assert_array_equal(vtk_to_numpy(poly.GetPoints().GetData()), verts)
        cells = vtk_to_numpy(poly.GetPolys().GetConnectivityArray()).reshape(-1, 3)
        np.testing.assert_array_equal(cells, faces)
        normals = poly.GetPointData().GetNormals()
        assert (normals is not None) == bool(extra)
