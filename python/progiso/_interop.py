"""A surface for VTK or trimesh, where those packages are importable."""

import numpy as np


def _arrays(mesh):
    """(vertices, faces, normals) of a Snapshot or a (verts, faces[, normals, ...]) tuple."""
    if hasattr(mesh, "vertices") and hasattr(mesh, "faces"):
        return mesh.vertices, mesh.faces, getattr(mesh, "normals", None)
    if isinstance(mesh, (tuple, list)) and len(mesh) >= 2:
        return mesh[0], mesh[1], mesh[2] if len(mesh) > 2 else None
    raise ValueError("expected a Snapshot or a (vertices, faces, ...) tuple, found %s"
                     % type(mesh).__name__)


def to_vtk(mesh):
    """A ``vtkPolyData`` of a Snapshot or of marching_cubes' output.

    VTK's frame is x, y, z: the points are the axis-order positions reversed (x = axis 2).
    That mirror also turns each triangle's right-hand normal around, so with the corners in
    the order given it points out of the region above the isovalue (with the default
    gradient_direction), the side the vertex normals give. Normals, when present, become the
    point normals. Needs the ``vtk`` package (Debian: python3-vtk9).
    """
    try:
        from vtkmodules.vtkCommonCore import vtkPoints
        from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
        from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
    except ImportError as e:
        raise ImportError("to_vtk needs VTK's Python package (Debian: python3-vtk9): %s" % e)
    verts, faces, normals = _arrays(mesh)
    xyz = np.ascontiguousarray(np.asarray(verts, dtype=np.float32)[:, ::-1])
    points = vtkPoints()
    points.SetData(numpy_to_vtk(xyz, deep=True))
    tri = np.asarray(faces, dtype=np.int64)
    cells = np.empty((len(tri), 4), dtype=np.int64)
    cells[:, 0] = 3
    cells[:, 1:] = tri
    polys = vtkCellArray()
    polys.SetCells(len(tri), numpy_to_vtkIdTypeArray(cells.ravel(), deep=True))
    poly = vtkPolyData()
    poly.SetPoints(points)
    poly.SetPolys(polys)
    if normals is not None:
        n = numpy_to_vtk(np.ascontiguousarray(np.asarray(normals, np.float32)[:, ::-1]),
                         deep=True)
        n.SetName("Normals")
        poly.GetPointData().SetNormals(n)
    return poly


def to_trimesh(mesh, process=False):
    """A ``trimesh.Trimesh`` of a Snapshot or of marching_cubes' output (positions in axis
    order, as given; faces as given). Needs the ``trimesh`` package. Without it, a Snapshot's
    ``vertices`` and ``faces`` are already trimesh's (vertices, faces) pair."""
    try:
        import trimesh
    except ImportError as e:
        raise ImportError("to_trimesh needs the trimesh package: %s" % e)
    verts, faces, normals = _arrays(mesh)
    return trimesh.Trimesh(vertices=verts, faces=faces, vertex_normals=normals,
                           process=process)
