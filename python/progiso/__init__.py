"""progiso: time-critical progressive isosurfaces, from Python.

- ``marching_cubes(volume, level, ...)``: scikit-image's call and return values, the surface
  made by progiso (marching tetrahedra on the finest cut of a longest-edge-bisection
  hierarchy), on all cores, with a deadline, an error or a triangle budget if asked.
- ``Engine(volume, level)``: the progressive engine. A valid surface at once, refined in the
  background; ``snapshot()`` any time, from any thread; ``set_isovalue()`` while it runs;
  ``for snap in eng.snapshots(): ...`` to follow it.
- ``read_volume(path)``: NRRD, NIfTI, MetaImage, VTK, DICOM, TIFF, MRC as numpy arrays.
- ``to_vtk(mesh)``, ``to_trimesh(mesh)``: a surface for VTK or trimesh.

Arrays are indexed in numpy's order: a volume ``v[i, j, k]``, and every position and normal
``(i, j, k)`` times the spacing given per axis, as scikit-image does.
"""

from ._progiso import _default_threads
from ._marching import marching_cubes
from ._engine import Engine, Snapshot, Change
from ._io import read_volume, VolumeFile
from ._interop import to_vtk, to_trimesh

__all__ = ["marching_cubes", "Engine", "Snapshot", "Change", "read_volume", "VolumeFile",
           "to_vtk", "to_trimesh", "default_threads"]
__version__ = "0.1.0"


def default_threads():
    """The worker threads a call uses when ``threads`` is not given: every core this process
    may run on."""
    return _default_threads()
