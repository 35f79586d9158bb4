"""Scene to library objects: :func:`build` maps a validated scene dict
one-to-one onto a mesh, a basis, a
:class:`~skfem_rkpm.mechanics.problem.SolidProblem`, the
:class:`~skfem_rkpm.solvers.newton.Prescribed` conditions (fixed or moved
boundaries), the :class:`~skfem_rkpm.mechanics.loads.BoundaryLoads`
(pressures, tractions) and rigid tools with their contact
(:class:`Simulation`).
"""

from dataclasses import dataclass, field

import numpy as np
from skfem import (Basis, ElementHex1, ElementHex2, ElementQuad1, ElementQuad2, ElementTetP1,
                   ElementTetP2, ElementTriP1, ElementTriP2, ElementVector)

from ..approximation.basis import RKBasis
from ..mechanics.force_control import ForceDrivenContact
from ..mechanics.loads import BoundaryLoads, FollowerPressure, History, Pressure, Traction
from ..mechanics.friction import DEFAULT_AUGMENTED_TOLERANCE, DEFAULT_PENALTY_FACTOR
from ..mechanics.problem import SolidProblem
from ..mechanics.rigid_contact import RigidContact, ToolSideError
from ..mechanics.surface_contact import SurfaceContact
from ..meshes import plane_normal
from ..solvers.newton import Prescribed
from ..solvers.partitioned import MPIReduction, PartitionedSolid, partition
from ..solvers.petsc import world
from .memory import check_rk_memory
from .scene_tools import tool_from
from .scene import (DEFAULT_STABILIZATION, SceneError, components, material_from,
                    prescribed_components, spacing_radius)
from .scene_geometry import check_mesh, mesh_from

__all__ = ["Simulation", "build", "resolve_locking", "tool_from_scene"]

ELEMENTS = {"quad1": ElementQuad1, "quad2": ElementQuad2, "tri1": ElementTriP1,
            "tri2": ElementTriP2, "hex1": ElementHex1, "hex2": ElementHex2,
            "tet1": ElementTetP1, "tet2": ElementTetP2}

#: the linear elements (F-bar by default) and the elements of each kind of cell
LINEAR_ELEMENTS = ("quad1", "tri1", "hex1", "tet1")
#: the element of a scene without ``discretization.element``: linear on its cells
LINEAR_OF = {"MeshQuad1": "quad1", "MeshTri1": "tri1", "MeshHex1": "hex1",
             "MeshTet1": "tet1"}
FITTING = {"MeshQuad1": "quad1 or quad2", "MeshTri1": "tri1 or tri2",
           "MeshHex1": "hex1 or hex2", "MeshTet1": "tet1 or tet2"}


@dataclass
class Simulation:
    """Everything a run needs; each field is a plain library object."""

    scene: dict
    mesh: object
    basis: object
    problem: SolidProblem
    prescribed: list
    load: object = None
    tools: list = field(default_factory=list)
    points: dict = field(default_factory=dict)
    follower_loads: list = field(default_factory=list)
    #: the cells and rows of each MPI rank when the problem is partitioned
    #: (:class:`~skfem_rkpm.solvers.partitioned.Partition`), else None
    partition: object = None
    #: the re-referencing of the run (:class:`~skfem_rkpm.runs.rereference.Rereferencing`,
    #: which rebuilds the discretization on later configurations), else None
    rereferenced: object = None

    @property
    def contributions(self):
        """The nonlinear forces Newton adds to the internal force: tool
        contact and follower pressures."""
        return [*self.tools, *self.follower_loads]

    @property
    def method(self):
        return "rkpm" if isinstance(self.basis, RKBasis) else "fem"


def resolve_locking(locking, method, element, scene):
    """The locking control ``"auto"`` stands for: F-bar for RKPM and linear
    elements, none for quadratic elements and for RKPM when a tool slides
    with Coulomb friction (0 < μ, not stick).

    Measured against exact and converged answers (docs/plasticity.md,
    "Which locking control", ``benchmarks/locking_study.py``): without
    F-bar, Q1 gives 1.23 times Prandtl's punch pressure and a third of
    Cook's deflection, RKPM 1.07 and 0.90; with it both stay within 3.5 %
    and 7 %.  F-bar over-relaxes quadratic elements (Prandtl 0.93, Cook
    1.27), which lock little without it (1.04, 0.96).  On the ring under
    sliding friction F-bar inverts RKPM's outer corner cell at 31 % height
    reduction (also with augmented contact), where RKPM without it
    completes at the converged answer.

    In 3D RKPM always takes F-bar: without it the 3D ring sector locks
    (coarse, 5 x 2 x 4 cells: inner-diameter change +13.8 % against
    -26.1 % of FEM and -26.7 % of RKPM with F-bar; at 15 x 6 x 10 cells
    -6.6 % at 30 % height reduction where the axisymmetric ring has -10.5 %).
    """
    if locking != "auto":
        return locking
    if method == "fem":
        return "fbar" if element in LINEAR_ELEMENTS else "none"
    if scene["model"]["type"] == "3d":
        return "fbar"
    slides = False
    for name, section in scene.items():
        if name.startswith("tools.") and section.get("friction") not in (None, "stick"):
            slides = slides or float(section["friction"]) > 0.0
    return "none" if slides else "fbar"


def build(scene, method=None, trust_geo=False, mesh=None, radius=None):
    """Turn a validated scene (see :func:`skfem_rkpm.runs.scene.load_scene`) into a
    :class:`Simulation`; ``method`` overrides ``model.method``; ``trust_geo``
    lets a gmsh ``.geo`` geometry file run programs or read other files
    (refused otherwise, see :func:`skfem_rkpm.meshes.geo_check.check_geo`).
    ``mesh`` and ``radius`` (RKPM support radii) replace the scene's (a
    rebuild on a later configuration, :mod:`skfem_rkpm.runs.rereference`)."""
    model = scene["model"]["type"]
    method = method or scene["model"]["method"]
    if mesh is None:
        mesh = mesh_from(scene["geometry"], scene.get("_base"), trust_geo)
    check_mesh(scene, mesh)
    boundaries = set((mesh.boundaries or {}).keys())
    disc = scene["discretization"]
    part = _partition(scene, method, mesh)
    cells = None if part is None else part.cells_of(world()[0])
    reduction = None if part is None else MPIReduction()
    if method == "rkpm":
        check_rk_memory(mesh, spacing_radius(mesh, disc), disc["order"],
                        disc["support_shape"], disc["quadrature"])
        stabilization = disc.get("stabilization")
        if stabilization is not None and disc["integration"] != "scni":
            raise SceneError(f"discretization.stabilization: only for integration = "
                             f"\"scni\" (this scene has {disc['integration']!r})")
        if disc["smoothing"] != "median_dual" and disc["integration"] not in ("scni", "dni"):
            raise SceneError(f"discretization.smoothing: only for integration = \"scni\" or "
                             f"\"dni\" (this scene has {disc['integration']!r})")
        if disc["integration"] == "scni" and stabilization is None:
            stabilization = DEFAULT_STABILIZATION
        if disc.get("stabilization_moduli") is not None and not stabilization:
            raise SceneError("discretization.stabilization_moduli: only for integration = "
                             "\"scni\" with stabilization > 0 (this scene has integration = "
                             f"{disc['integration']!r}, stabilization = {stabilization or 0.0})")
        basis = RKBasis(mesh, vector=True, order=disc["order"], kernel=disc["kernel"],
                        support_shape=disc["support_shape"], intorder=disc["quadrature"],
                        integration=disc["integration"], axisymmetric=model == "axisymmetric",
                        radius=(radius if radius is not None else
                                spacing_radius(mesh, disc)
                                if disc["support"] is not None else None),
                        support=disc["dilation"], stabilization=stabilization or 0.0,
                        interpolating=disc["interpolating"], smoothing=disc["smoothing"],
                        elements=cells, reduction=reduction)
    else:
        element = ELEMENTS[disc["element"] or LINEAR_OF.get(type(mesh).__name__, "quad1")]()
        if element.refdom != mesh.refdom:
            name = type(mesh).__name__
            raise SceneError(f"discretization.element: {disc['element']!r} does not fit "
                             f"the {name} cells; use {FITTING.get(name, 'another')}")
        basis = Basis(mesh, ElementVector(element), intorder=disc["quadrature"],
                      elements=cells)
    locking = resolve_locking(disc["locking"], method,
                              disc["element"] or LINEAR_OF.get(type(mesh).__name__, "quad1"), scene)
    locking = None if locking == "none" else locking
    if method == "rkpm" and disc["integration"] in ("scni", "dni"):
        locking = None  # F-bar averages over a cell: one point per particle, nothing to do
    problem = SolidProblem(basis, material_from(scene["material"]), model, locking=locking,
                           stabilization_moduli=disc.get("stabilization_moduli") or "elastic")
    if part is not None:
        problem = PartitionedSolid(problem, reduction, world()[0])

    prescribed, loads, followers = [], [], []
    for name, section in scene.items():
        if not name.startswith("boundary."):
            continue
        boundary = name.split(".", 1)[1]
        if boundary not in boundaries:
            raise SceneError(f"[{name}]: the mesh has no boundary {boundary!r}; "
                             f"{_named(boundaries, scene)}")
        for comp in components(section["fix"] or []):
            prescribed.append(Prescribed(boundary, comp, 0.0, section["method"]))
        if section["symmetry"]:
            prescribed.append(Prescribed(boundary, _symmetry_normal(mesh, boundary, name),
                                         0.0, section["method"]))
        for comp, value in prescribed_components(section["displacement"]).items():
            prescribed.append(Prescribed(boundary, comp, _values(value, f"{name}"),
                                         section["method"]))
        if section["pressure"] is not None and section["follower"]:
            followers.append(FollowerPressure(basis, boundary, section["pressure"], model))
        elif section["pressure"] is not None:
            loads.append(Pressure(boundary, section["pressure"]))
        if section["traction"] is not None:
            loads.append(Traction(boundary, prescribed_components(section["traction"])))
    load = BoundaryLoads(basis, loads, model) if loads else None
    tool_sections = {name: section for name, section in scene.items()
                     if name.startswith("tools.")}
    for name, section in tool_sections.items():
        for slave in section.get("slaves") or []:
            if slave not in boundaries:
                raise SceneError(f"[{name}] slaves: the mesh has no boundary {slave!r}; "
                                 f"{_named(boundaries, scene)}")
    tools = [tool_from_scene(name.split(".", 1)[1], section, basis, problem, scene)
             for name, section in tool_sections.items()]
    points = {k: np.asarray(v, float) for k, v in scene["output"]["points"].items()}
    return Simulation(scene, mesh, basis, problem, prescribed, load, tools, points, followers,
                      part)


def _partition(scene, method, mesh):
    """The cells of each MPI rank, when the run is partitioned: under
    ``mpiexec`` with the solver ``"petsc"``, RKPM and a cell integration
    scheme; None otherwise (nodal schemes, ``"vci_symmetric"`` and FEM
    run whole on every rank, with the solve distributed: scikit-fem's
    probes and the rows of higher-order elements need the whole mesh)."""
    ranks = world()[1]
    integration = scene["discretization"]["integration"]
    if ranks == 1 or scene["steps"]["solver"] != "petsc":
        return None
    if method != "rkpm" or integration not in ("vci", "gauss"):
        return None
    return partition(mesh, ranks)


def _named(boundaries, scene):
    """What boundaries the mesh has, for an error about a missing one."""
    if boundaries:
        return f"it has {sorted(boundaries)}"
    if scene["geometry"]["kind"] == "gmsh":
        what = (("surfaces", "Surface") if scene["model"]["type"] == "3d"
                else ("curves", "Curve"))
        return (f"the file {scene['geometry']['file']} defines no named boundaries: give "
                f"its boundary {what[0]} names with Physical {what[1]}(\"name\") = {{...}};")
    return "it has no named boundaries"


def _symmetry_normal(mesh, boundary, name):
    """The normal of a symmetry plane: a component number when it is a
    coordinate axis (reaction ``xmin[0]``), the direction otherwise."""
    try:
        normal = plane_normal(mesh, boundary)
    except ValueError as err:
        raise SceneError(f"[{name}] symmetry: {err}; a symmetry plane must be flat") \
            from None
    axis = int(np.argmax(np.abs(normal)))
    return axis if abs(normal[axis]) > 1.0 - 1e-12 else normal


def _symmetry_planes(mesh, scene):
    """``(boundary, normal)`` of the scene's symmetry planes (``symmetry =
    true``), for the contact nodes on them (:class:`SurfaceContact`)."""
    return [(name.split(".", 1)[1], plane_normal(mesh, name.split(".", 1)[1]))
            for name, section in scene.items()
            if name.startswith("boundary.") and section.get("symmetry")]


def _values(value, name):
    """The ``values`` of a :class:`Prescribed`: a number (reached linearly in
    t, as Prescribed does), or ``(t, x) -> value`` of a table in t."""
    if isinstance(value, (int, float)):
        return float(value)
    history = History(value, name)
    return lambda t, x: np.full(x.shape[1], history(t))


def tool_from_scene(name, section, basis, problem, scene=None):
    """A :class:`RigidContact` (2D) or :class:`SurfaceContact` (3D) from a
    ``[tools.NAME]`` section of a scene.

    The tool is :func:`skfem_rkpm.runs.scene_tools.tool_from`; ``friction``, ``slaves``,
    ``penalty``, ``penalty_factor`` (``factor``), ``collocation``,
    ``enforcement`` and ``tolerance`` as in :class:`RigidContact`; in 3D the
    scene's symmetry planes go to :class:`SurfaceContact` (``symmetry``).  With
    ``force`` the tool is driven by its push along ``direction`` (default
    the platen's normal): a :class:`ForceDrivenContact`.
    """
    dim = basis.mesh.dim()
    tool = tool_from(name, section, dim, (scene or {}).get("_base"))
    if problem.basis is not basis:
        raise ValueError("the basis must be the problem's basis")
    factor = section.get("penalty_factor")
    extra = {}
    if dim == 3:  # contact nodes on symmetry planes: no shear across them
        extra["symmetry"] = _symmetry_planes(basis.mesh, scene or {})
    try:
        contact = (SurfaceContact if dim == 3 else RigidContact)(
                               problem, tool, section.get("slaves"),
                               section.get("friction", 0.0),
                               section.get("collocation") or "nodal", section.get("penalty"),
                               factor=DEFAULT_PENALTY_FACTOR if factor is None else factor,
                               enforcement=section.get("enforcement") or "penalty",
                               tolerance=(section.get("tolerance")
                                          or DEFAULT_AUGMENTED_TOLERANCE), **extra)
    except ToolSideError as err:
        raise SceneError(f"the {err.what} of tools.{name} {err.fix} ({err.detail})") from None
    if section.get("force") is None:
        return contact
    direction = section.get("direction") or section.get("normal")
    try:
        return ForceDrivenContact(contact, direction, section["force"])
    except ValueError as err:
        raise SceneError(f"[tools.{name}]: {err}") from err
