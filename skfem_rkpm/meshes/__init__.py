"""Background meshes with named boundaries.

The meshes returned here are ordinary scikit-fem meshes
(:class:`skfem.MeshTri1`, :class:`skfem.MeshQuad1`; in 3D
:class:`skfem.MeshHex1`, :class:`skfem.MeshTet1`).  Their vertices serve
as the particles of the reproducing kernel approximation and their cells as
integration cells.  Every mesh carries named boundaries in
``mesh.boundaries`` (a dict of facet index arrays), so that boundary
conditions can be written as ``mesh.boundaries["left"]``.

The functions live in

* :mod:`.structured`: rectangles (uniform, perturbed, graded, piecewise)
  and boxes;
* :mod:`.rings`: rings and ring sectors in polar cells;
* :mod:`.cylinders`: a quarter cylinder in mapped hexahedra;
* :mod:`.gmsh`: unstructured meshes from gmsh, ``.msh`` and ``.geo`` files
  (a ``.geo`` script is first checked by :mod:`.geo_check`);
* :mod:`.queries`: the particles, the spacing at each vertex and the normal
  of a flat boundary, for any mesh;

and are all importable from here.  Nothing in this folder imports another
folder of the package.
"""

from .cylinders import quarter_cylinder, quarter_disk
from .gmsh import from_gmsh, gmsh_plate_with_hole, gmsh_rectangle, load
from .queries import local_spacing, mesh_vertices, plane_normal
from .rings import annulus, ring_sector
from .structured import box, graded_rectangle, piecewise_rectangle, rectangle

__all__ = [
    "rectangle",
    "graded_rectangle",
    "piecewise_rectangle",
    "box",
    "annulus",
    "ring_sector",
    "quarter_disk",
    "quarter_cylinder",
    "gmsh_rectangle",
    "gmsh_plate_with_hole",
    "from_gmsh",
    "load",
    "local_spacing",
    "mesh_vertices",
    "plane_normal",
]
