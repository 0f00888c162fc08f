"""Reads a .pvtp with VTK's own reader (what ParaView uses) and a .vtp of the same surface, and
checks that they hold the same triangles: each as its three corners' positions (and normals, when
the files have them), starting at its smallest corner so that orientation counts. Exit 0 when
they match, 1 otherwise.

usage: pvtp_check.py PIECES.pvtp WHOLE.vtp NUMBER_OF_PIECES
"""
import sys

import vtk


def triangles(reader, path):
    reader.SetFileName(path)
    reader.Update()
    data = reader.GetOutput()
    points = data.GetPoints()
    normals = data.GetPointData().GetNormals()
    ids = vtk.vtkIdList()
    out = []

    def corner(i):
        p = tuple(points.GetPoint(i))
        return p + tuple(normals.GetTuple3(i)) if normals is not None else p

    for cell in range(data.GetNumberOfCells()):
        data.GetCellPoints(cell, ids)
        corners = [corner(ids.GetId(k)) for k in range(ids.GetNumberOfIds())]
        first = corners.index(min(corners))
        out.append(tuple(corners[first:] + corners[:first]))
    return reader, sorted(out)


def main():
    pieces, whole, count = sys.argv[1], sys.argv[2], int(sys.argv[3])
    reader, a = triangles(vtk.vtkXMLPPolyDataReader(), pieces)
    _, b = triangles(vtk.vtkXMLPolyDataReader(), whole)
    if reader.GetNumberOfPieces() != count:
        print(f"{pieces}: {reader.GetNumberOfPieces()} pieces, expected {count}")
        return 1
    if not a or a != b:
        print(f"{pieces}: {len(a)} triangles, {whole}: {len(b)}; they differ")
        return 1
    print(f"{pieces}: {count} pieces, {len(a)} triangles, the same as {whole}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
