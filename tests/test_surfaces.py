"""3D rigid tool surfaces: closest points, normals, gaps and curvature of
planes, cylinders, spheres, tori and triangulated surfaces, checked against
exact geometry, brute force and finite differences; rigid motions; files.
"""

import meshio
import numpy as np
import pytest
from scipy.spatial import cKDTree

from skfem_rkpm.mechanics.surfaces import Cylinder, Plane, Sphere, Torus
from skfem_rkpm.mechanics.triangulated import (TriangulatedSurface,
                                               closest_points_on_triangles)

RNG = np.random.default_rng(20240518)


@pytest.fixture(autouse=True)
def same_points_in_every_run():
    """Every test draws its random points from the same seed, whichever
    tests run before it."""
    global RNG
    RNG = np.random.default_rng(20240518)


def random_directions(n):
    v = RNG.normal(size=(3, n))
    return v / np.linalg.norm(v, axis=0)


def cube_mesh(n=4):
    """The unit cube [0, 1]^3, each face split into n x n quads (two triangles
    each), counter-clockwise seen from outside: points (m, 3), triangles (k, 3)."""
    s = np.linspace(0.0, 1.0, n + 1)
    e = np.eye(3)
    faces = [(np.zeros(3), e[2], e[1]), (e[0], e[1], e[2]), (np.zeros(3), e[0], e[2]),
             (e[1], e[2], e[0]), (np.zeros(3), e[1], e[0]), (e[2], e[0], e[1])]
    points, triangles = [], []
    for origin, du, dv in faces:  # du x dv is the outward normal
        u, v = np.meshgrid(s, s, indexing="ij")
        grid = origin + u.reshape(-1, 1) * du + v.reshape(-1, 1) * dv
        i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
        a = (i * (n + 1) + j).ravel() + sum(len(p) for p in points)
        b, c, d = a + n + 1, a + n + 2, a + 1
        triangles += [np.stack([a, b, c], 1), np.stack([a, c, d], 1)]
        points.append(grid)
    return np.concatenate(points), np.concatenate(triangles)


def box_distance(x):
    """Exact signed distance (n,) of points x (3, n) to the unit cube, positive outside."""
    q = np.abs(x - 0.5) - 0.5
    return (np.linalg.norm(np.maximum(q, 0.0), axis=0) + np.minimum(q.max(axis=0), 0.0))


def brute_force_distance(x, corners):
    """Distance (n,) from points x (n, 3) to the nearest triangle of corners
    (k, 3, 3): the plane projection when it falls inside the triangle, else
    the nearest of the three edges (independent of Ericson's regions)."""
    out = np.empty(len(x))
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    normal = np.cross(b - a, c - a)
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    for start in range(0, len(x), 200):
        p = x[start:start + 200, None, :]
        height = np.einsum("pkj,kj->pk", p - a, normal)
        foot = p - height[..., None] * normal
        inside = np.ones(height.shape, dtype=bool)
        edge_distance = np.full(height.shape, np.inf)
        for u, v in ((a, b), (b, c), (c, a)):
            inside &= np.einsum("pkj,kj->pk", np.cross(v - u, foot - u), normal) >= 0
            e = v - u
            s = np.clip(np.einsum("pkj,kj->pk", p - u, e) / np.einsum("kj,kj->k", e, e),
                        0.0, 1.0)
            edge_distance = np.minimum(edge_distance, np.linalg.norm(
                p - u - s[..., None] * e, axis=-1))
        out[start:start + 200] = np.where(inside, np.abs(height), edge_distance).min(axis=1)
    return out


def analytic_surfaces(**motion):
    return [Plane((0.2, -0.1, 0.3), (1.0, 2.0, -0.5), **motion),
            Cylinder((0.1, 0.2, -0.3), (1.0, -1.0, 2.0), 0.7, "outside", **motion),
            Cylinder((0.1, 0.2, -0.3), (1.0, -1.0, 2.0), 0.7, "inside", **motion),
            Sphere((0.3, -0.2, 0.1), 0.8, "outside", **motion),
            Sphere((0.3, -0.2, 0.1), 0.8, "inside", **motion),
            Torus((0.1, 0.0, -0.2), (0.3, 1.0, 0.5), 1.5, 0.4, "outside", **motion),
            Torus((0.1, 0.0, -0.2), (0.3, 1.0, 0.5), 1.5, 0.4, "inside", **motion)]


def points_near(surface, n, spread):
    """Points within ``spread`` (per coordinate) of random surface points."""
    p, t = surface.outline(resolution=24, extent=1.0)
    pick = p[:, RNG.integers(0, p.shape[1], n)]
    return pick + spread * RNG.uniform(-1, 1, (3, n))


def on_surface_residual(surface, p):
    """How far points p (3, n) are from the implicit surface, exactly."""
    if isinstance(surface, Plane):
        return (p - surface.point[:, None]).T @ surface.normal
    if isinstance(surface, Sphere):
        return np.linalg.norm(p - surface.center[:, None], axis=0) - surface.radius
    v = p - (surface.point if isinstance(surface, Cylinder) else surface.center)[:, None]
    h = surface.axis @ v
    rho = np.linalg.norm(v - np.outer(surface.axis, h), axis=0)
    if isinstance(surface, Cylinder):
        return rho - surface.radius
    return np.hypot(rho - surface.major_radius, h) - surface.minor_radius


# --- hand values --------------------------------------------------------------

@pytest.mark.parametrize("surface, x, point, normal, gap, curvature", [
    (Plane((0, 0, 1), (0, 0, -3)), (0.5, 2.0, 0.25), (0.5, 2.0, 1.0), (0, 0, -1), 0.75,
     np.zeros((3, 3))),
    (Cylinder((0, 0, 0), (0, 0, 2), 1.0), (2.0, 0.0, 5.0), (1, 0, 5), (1, 0, 0), 1.0,
     np.diag([0, 0.5, 0])),
    (Cylinder((0, 0, 0), (0, 0, 1), 1.0, "inside"), (0, 0.5, 1.0), (0, 1, 1), (0, -1, 0),
     0.5, np.diag([-2.0, 0, 0])),
    (Sphere((1, 1, 1), 2.0), (1, 1, 5), (1, 1, 3), (0, 0, 1), 2.0,
     np.diag([0.25, 0.25, 0])),
    (Sphere((0, 0, 0), 2.0, "inside"), (0, -1, 0), (0, -2, 0), (0, 1, 0), 1.0,
     np.diag([-1.0, 0, -1.0])),
    (Torus((0, 0, 0), (0, 0, 1), 2.0, 0.5), (3, 0, 0), (2.5, 0, 0), (1, 0, 0), 0.5,
     np.diag([0, 1 / 3, 1.0])),      # along the circle (ρ - R)/(ρ s) = 1/3
    (Torus((0, 0, 0), (0, 0, 1), 2.0, 0.5), (2, 0, 1), (2, 0, 0.5), (0, 0, 1), 0.5,
     np.diag([1.0, 0, 0])),
    (Torus((0, 0, 0), (0, 0, 1), 2.0, 0.5), (1, 0, 0), (1.5, 0, 0), (-1, 0, 0), 0.5,
     np.diag([0, -1.0, 1.0])),       # inner equator: saddle, (1 - 2)/(1 * 1) = -1
    (Torus((0, 0, 0), (0, 0, 1), 2.0, 0.5, "inside"), (0, 2.2, 0), (0, 2.5, 0),
     (0, -1, 0), 0.3, -np.diag([(2.2 - 2) / (2.2 * 0.2), 0, 1 / 0.2])),
])
def test_hand_values(surface, x, point, normal, gap, curvature):
    proj = surface.project(np.array(x, dtype=float)[:, None])
    np.testing.assert_allclose(proj.point[:, 0], point, atol=1e-14)
    np.testing.assert_allclose(proj.normal[:, 0], normal, atol=1e-14)
    np.testing.assert_allclose(proj.gap, [gap], atol=1e-14)
    np.testing.assert_allclose(proj.curvature[0], curvature, atol=1e-14)
    assert proj.feature.tolist() == [0] and surface.nfeatures == 1


@pytest.mark.parametrize("surface", analytic_surfaces(), ids=repr)
def test_closest_point_is_on_the_surface_and_nearest(surface):
    """The closest point lies on the surface (exact implicit equation), x - x_C
    = g n, and no point of a dense sampling of the surface is closer than |g|;
    the nearest sample is at most the sample spacing farther."""
    x = points_near(surface, 300, 0.5)
    proj = surface.project(x)
    np.testing.assert_allclose(on_surface_residual(surface, proj.point), 0.0, atol=1e-13)
    np.testing.assert_allclose(np.linalg.norm(proj.normal, axis=0), 1.0, atol=1e-14)
    np.testing.assert_allclose(x - proj.point, proj.gap * proj.normal, atol=1e-13)
    if isinstance(surface, Plane):
        return  # on the plane with x - x_C along n: the foot of the perpendicular
    samples, triangles = surface.outline(resolution=600, extent=3.0)
    spacing = max(np.linalg.norm(samples[:, triangles[i]] - samples[:, triangles[i - 1]],
                                 axis=0).max() for i in range(3))
    nearest, _ = cKDTree(samples.T).query(x.T)
    assert np.all(np.abs(proj.gap) <= nearest + 1e-12)
    assert np.all(nearest <= np.abs(proj.gap) + spacing)


@pytest.mark.parametrize("surface", analytic_surfaces(), ids=repr)
def test_gap_sign_puts_the_body_on_its_side(surface):
    x = points_near(surface, 200, 0.3)
    proj = surface.project(x)
    side = on_surface_residual(surface, x)  # > 0 outside the solid (plane: normal side)
    sign = -1.0 if getattr(surface, "side", "outside") == "inside" else 1.0
    np.testing.assert_allclose(proj.gap, sign * side, atol=1e-13)


# --- derivatives by finite differences ----------------------------------------

def fd_check(surface, x, t=0.0, step=1e-6):
    """Central differences of the normal and the gap against C and n.

    Errors: truncation step² |∂³| (the third derivatives are at most a few
    1/ρ³ for these points, ρ >= 0.05: < 1e-8) plus rounding 1e-16/step
    (1e-10); the tolerances 1e-6 (C) and 1e-8 (∇g) leave a wide margin."""
    proj = surface.project(x, t)
    dn, dg = np.zeros_like(proj.curvature), np.zeros_like(x)
    for j in range(3):
        e = np.zeros((3, 1))
        e[j] = step
        plus, minus = surface.project(x + e, t), surface.project(x - e, t)
        dn[:, :, j] = ((plus.normal - minus.normal) / (2 * step)).T
        dg[j] = (plus.gap - minus.gap) / (2 * step)
    np.testing.assert_allclose(proj.curvature, dn, atol=1e-6)
    np.testing.assert_allclose(proj.curvature, proj.curvature.transpose(0, 2, 1),
                               atol=1e-12)
    np.testing.assert_allclose(dg, proj.normal, atol=1e-8)
    return proj


@pytest.mark.parametrize("surface", analytic_surfaces(), ids=repr)
def test_curvature_and_gap_gradient_by_finite_differences(surface):
    x = points_near(surface, 40, 0.2)  # at least 0.05 from the torus core circle
    proj = fd_check(surface, x)
    if not isinstance(surface, Plane):
        assert np.abs(proj.curvature).max() > 0.1  # the check is not of zeros


def test_derivatives_of_a_moving_rotated_torus():
    torus = Torus((0.1, 0.0, -0.2), (0.3, 1.0, 0.5), 1.5, 0.4, motion=(0.2, -0.4, 0.9),
                  rotation=dict(axis=(1, 2, 0), point=(0.5, 0.5, 0.0), angle=70))
    R, b = torus.placement(0.6)
    x = R @ points_near(Torus((0.1, 0.0, -0.2), (0.3, 1.0, 0.5), 1.5, 0.4), 40, 0.2) \
        + b[:, None]
    fd_check(torus, x, t=0.6)


def cube_points():
    """Points (3, 7) in the regions of the unit cube: face, edge, vertex,
    edge (outside); face, face (inside); vertex (outside); 0.05 < |g| < 0.6."""
    return np.array([[0.3, 0.4, 1.2], [1.3, 1.2, 0.45], [1.3, 1.2, 1.4], [-0.2, 0.37, -0.1],
                     [0.9, 0.95, 0.5], [0.2, 0.6, 0.1], [-0.1, -0.3, -0.2]]).T


@pytest.mark.parametrize("orientation", [1, -1], ids=["punch", "cavity"])
def test_triangulated_derivatives_at_faces_edges_and_vertices(orientation):
    """The cube as a punch (body outside) and as a cavity (body inside, the
    triangles reversed: edges and vertices seen from outside are concave)."""
    points, triangles = cube_mesh(3)
    cube = TriangulatedSurface(points, triangles[:, ::orientation])
    x = cube_points()
    proj = fd_check(cube, x)
    np.testing.assert_allclose(proj.gap, orientation * box_distance(x), atol=1e-14)
    # the edge region (1.3, 1.2, z): ρ = |(0.3, 0.2)|, C = s (I - t tᵀ - n nᵀ)/ρ
    rho = np.hypot(0.3, 0.2)
    n = np.array([0.3, 0.2, 0.0]) / rho
    np.testing.assert_allclose(proj.curvature[1], orientation * (
        np.diag([1.0, 1.0, 0.0]) - np.outer(n, n)) / rho, atol=1e-14)
    assert np.abs(proj.curvature[[0, 4, 5]]).max() == 0.0  # on faces


# --- triangulated surfaces: exactness and search --------------------------------

def test_closest_points_on_triangles_against_an_independent_method():
    a, b, c = RNG.normal(size=(3, 5000, 3))
    x = RNG.normal(size=(5000, 3)) * 2.0
    point, region = closest_points_on_triangles(x, a, b, c)
    corners = np.stack([a, b, c], axis=1)
    expected = np.array([brute_force_distance(x[i:i + 1], corners[i:i + 1])[0]
                         for i in range(0, 5000, 10)])
    np.testing.assert_allclose(np.linalg.norm(x - point, axis=1)[::10], expected,
                               rtol=1e-12, atol=1e-12)
    assert set(np.unique(region)) == set(range(7))  # every region was visited


@pytest.mark.parametrize("kind", ["sphere", "cube"])
def test_search_equals_brute_force(kind):
    """The k-d tree search finds the exact nearest triangle: the distances
    equal those of all point × triangle pairs (1e-12: both are exact up to
    rounding), for 3000 points near the surface, inside and outside, and
    the closest point lies in the reported triangle."""
    if kind == "sphere":
        points, triangles = Sphere((0, 0, 0), 1.0).outline(resolution=40)
        points, triangles = points.T, triangles.T
        r = RNG.uniform(0.6, 1.5, 3000)
        x = (random_directions(3000) * r).T
    else:
        points, triangles = cube_mesh(4)
        x = RNG.uniform(-0.4, 1.4, (3000, 3))
    surface = TriangulatedSurface(points, triangles)
    proj = surface.project(x.T)
    corners = surface.points[surface.triangles]
    np.testing.assert_allclose(np.abs(proj.gap), brute_force_distance(x, corners),
                               rtol=1e-12, atol=1e-12)
    a, b, c = corners[proj.feature].transpose(1, 0, 2)
    own, _ = closest_points_on_triangles(x, a, b, c)
    np.testing.assert_allclose(own, proj.point.T, atol=1e-14)
    if kind == "cube":
        np.testing.assert_allclose(proj.gap, box_distance(x.T), atol=1e-13)
    else:  # a convex polyhedron: outside iff in front of some face plane
        normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        height = x @ normal.T - np.einsum("kj,kj->k", corners[:, 0], normal)
        assert np.array_equal(proj.gap > 0, height.max(axis=1) > 0)


@pytest.mark.parametrize("orientation", [1, -1], ids=["punch", "cavity"])
def test_pseudo_normal_signs_near_cube_edges_and_corners(orientation):
    """Points within 1e-4 .. 0.05 of the cube's edges and corners, inside and
    outside: the gap equals the exact signed distance of the box."""
    corners = np.array(np.meshgrid([0, 1], [0, 1], [0, 1])).reshape(3, -1)
    edge_points = np.array([[0.5, 0, 0], [0, 0.5, 0], [0, 0, 0.5], [1, 1, 0.3],
                            [0.7, 1, 1], [1, 0.2, 1], [0, 1, 0.8], [1, 0, 0.1]]).T
    anchors = np.concatenate([corners, edge_points], axis=1)
    pick = RNG.integers(0, anchors.shape[1], 4000)
    x = anchors[:, pick] + random_directions(4000) * RNG.uniform(1e-4, 0.05, 4000)
    points, triangles = cube_mesh(2)
    cube = TriangulatedSurface(points, triangles[:, ::orientation])
    proj = cube.project(x)
    exact = orientation * box_distance(x)
    np.testing.assert_allclose(proj.gap, exact, atol=1e-14)
    assert (exact > 0).sum() > 500 and (exact < 0).sum() > 500  # 1/4, 1/8 inside


def test_pseudo_normal_signs_at_sharp_edges_where_face_normals_fail():
    """A regular tetrahedron (dihedral angle 70.5°): near its edges and
    vertices the normal of the closest triangle alone gives the wrong sign
    for many points; the pseudo-normals give the sign of the exact inside
    test (behind all four face planes) and the brute-force distance."""
    vertices = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)
    # faces (0, 1, 2) and (1, 3, 2) as fans of 9 thin triangles over their common
    # edge, so that an unweighted mean of the triangle normals at vertices 0
    # and 3 would lean to one face and give wrong signs
    chain = np.r_[1, 4 + np.arange(8), 2]
    split = vertices[1] + np.linspace(0, 1, 10)[1:-1, None] * (vertices[2] - vertices[1])
    faces = np.concatenate([[[0, 3, 1], [0, 2, 3]],
                            np.stack([np.zeros(9, int), chain[:-1], chain[1:]], 1),
                            np.stack([np.full(9, 3), chain[1:], chain[:-1]], 1)])
    mesh_points = np.concatenate([vertices, split])
    corners = mesh_points[faces]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    assert np.all(np.einsum("kj,kj->k", normal, corners.mean(axis=1)) > 0)  # outward
    edges = 0.5 * (vertices[[0, 0, 0, 1, 1, 2]] + vertices[[1, 2, 3, 2, 3, 3]])
    anchors = np.concatenate([vertices, edges])
    x = (anchors[RNG.integers(0, 10, 4000)]
         + random_directions(4000).T * RNG.uniform(1e-4, 0.3, (4000, 1)))
    proj = TriangulatedSurface(mesh_points, faces).project(x.T)
    inside = (x @ normal.T - np.einsum("kj,kj->k", corners[:, 0], normal)).max(axis=1) < 0
    exact = np.where(inside, -1.0, 1.0) * brute_force_distance(x, corners)
    np.testing.assert_allclose(proj.gap, exact, atol=1e-14)
    naive = np.einsum("kj,kj->k", normal[proj.feature], x - proj.point.T)
    assert np.mean(np.sign(naive) != np.sign(exact)) > 0.05


def test_triangulated_sphere_converges_to_the_sphere_at_second_order():
    """|g_h - g| is bounded by the Hausdorff distance of the inscribed
    polyhedron, max over triangles of R - sqrt(R² - r_c²) (r_c the
    circumradius), ≈ h²/(6R) for near-equilateral triangles: the observed
    order with the edge length halving is 2."""
    sphere = Sphere((0.1, 0.2, 0.3), 1.3)
    x = sphere.center[:, None] + random_directions(2000) * RNG.uniform(0.9, 1.6, 2000)
    errors, lengths = [], []
    for resolution in (10, 20, 40, 80):
        p, t = sphere.outline(resolution=resolution)
        faceted = TriangulatedSurface(p.T, t.T)
        error = np.abs(faceted.project(x).gap - sphere.project(x).gap).max()
        c = faceted.points[faceted.triangles]
        ab, ac = c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]
        circumradius = (np.linalg.norm(ab, axis=1) * np.linalg.norm(ac, axis=1)
                        * np.linalg.norm(c[:, 2] - c[:, 1], axis=1)
                        / (2 * np.linalg.norm(np.cross(ab, ac), axis=1)))
        hausdorff = (1.3 - np.sqrt(1.3 ** 2 - circumradius ** 2)).max()
        assert hausdorff / 2 < error <= hausdorff + 1e-12
        errors.append(error)
        lengths.append(np.linalg.norm(ab, axis=1).max())
    order = np.log(np.array(errors[:-1]) / errors[1:]) / np.log(
        np.array(lengths[:-1]) / lengths[1:])
    assert np.all((order > 1.9) & (order < 2.1)), order


@pytest.mark.parametrize("surface", analytic_surfaces()[1:], ids=repr)
def test_outline_is_a_faceted_copy_with_the_body_on_the_same_side(surface):
    p, t = surface.outline(resolution=48, extent=2.0)
    assert p.shape[0] == 3 and t.shape[0] == 3 and t.max() < p.shape[1]
    faceted = TriangulatedSurface(p.T, t.T)  # consistent orientation, manifold
    x = points_near(surface, 300, 0.3)
    exact, approximate = surface.project(x).gap, faceted.project(x).gap
    clear = np.abs(exact) > 0.05  # the facets are within 0.02 of these surfaces
    assert clear.sum() > 200
    assert np.array_equal(np.sign(exact[clear]), np.sign(approximate[clear]))


# --- rigid motion ---------------------------------------------------------------

def test_translation_moves_the_gap_with_the_tool():
    sphere = Sphere((0, 0, 0), 1.0, motion=(0.4, -0.2, 1.0))
    x = RNG.normal(size=(3, 50))
    d = np.array([0.4, -0.2, 1.0])
    at0, at = sphere.project(x), sphere.project(x + 0.5 * d[:, None], t=0.5)
    np.testing.assert_allclose(at.gap, at0.gap, atol=1e-14)
    np.testing.assert_allclose(at.point, at0.point + 0.5 * d[:, None], atol=1e-14)
    np.testing.assert_allclose(sphere.translation(0.5), 0.5 * d, atol=1e-15)
    callable_motion = Plane((0, 0, 0), (0, 0, 1), motion=lambda t: (0, 0, -t ** 2))
    np.testing.assert_allclose(callable_motion.project(np.zeros((3, 1)), 0.5).gap, [0.25])


def test_rotation_about_a_fixed_axis_hand_values():
    """A quarter turn about z through (1, 0, 0): the origin goes to (1, -1, 0)."""
    plane = Plane((0, 0, 0), (1, 0, 0),
                  rotation=dict(axis=(0, 0, 5), point=(1, 0, 0), angle=90))
    R, b = plane.placement(1.0)
    np.testing.assert_allclose(R @ [2, 0, 0] + b, [1, 1, 0], atol=1e-15)
    np.testing.assert_allclose(plane.translation(1.0), [1, -1, 0], atol=1e-15)
    np.testing.assert_allclose(plane.project(np.array([[3.0], [2.0], [0.0]]), 1.0).normal[:, 0],
                               [0, 1, 0], atol=1e-15)
    roll = Cylinder((0, 0, 1), (0, 1, 0), 1.0,
                    rotation=dict(axis=(0, 1, 0), point=(0, 0, 1), angle=lambda t: 360 * t))
    np.testing.assert_allclose(roll.placement(0.25)[0], [[0, 0, 1], [0, 1, 0], [-1, 0, 0]],
                               atol=1e-15)


MOVING = analytic_surfaces(motion=lambda t: (0.5 * t, -t, 2 * t),
                           rotation=dict(axis=(1, -2, 0.5), point=(0.3, 0.1, -1), angle=120))


@pytest.mark.parametrize("surface", MOVING, ids=repr)
def test_points_fixed_to_a_rotating_moving_tool_keep_their_gap(surface):
    body = points_near(surface, 30, 0.4)  # at t = 0 the body frame is the world frame
    R0, b0 = surface.placement(0.0)
    np.testing.assert_allclose(R0, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(b0, 0.0, atol=1e-15)
    start = surface.project(body, 0.0)
    R, b = surface.placement(0.8)
    assert not np.allclose(R, np.eye(3), atol=0.1)
    world = R @ body + b[:, None]
    moved = surface.project(world, 0.8)
    np.testing.assert_allclose(surface.to_body(world, 0.8), body, atol=1e-13)
    np.testing.assert_allclose(moved.gap, start.gap, atol=1e-13)
    np.testing.assert_allclose(moved.point, R @ start.point + b[:, None], atol=1e-13)
    np.testing.assert_allclose(moved.normal, R @ start.normal, atol=1e-13)
    np.testing.assert_allclose(moved.curvature, R @ start.curvature @ R.T, atol=1e-12)


def test_triangulated_surface_moves_rigidly():
    points, triangles = cube_mesh(2)
    cube = TriangulatedSurface(points, triangles, motion=(1, 2, 3),
                               rotation=dict(axis=(1, 1, 1), point=(0.5, 0.5, 0.5),
                                             angle=30))
    x = cube_points()
    R, b = cube.placement(1.0)
    moved = cube.project(R @ x + b[:, None], 1.0)
    np.testing.assert_allclose(moved.gap, box_distance(x), atol=1e-14)


# --- files ----------------------------------------------------------------------

@pytest.mark.parametrize("suffix, kwargs, tolerance", [
    (".stl", {"binary": True}, 1e-6),  # binary STL stores float32: 6e-8 relative
    (".stl", {"binary": False}, 1e-12),
    (".msh", {"file_format": "gmsh22", "binary": False}, 1e-12),
    (".msh", {"file_format": "gmsh"}, 1e-12),
    (".msh", {"file_format": "ansys"}, 1e-12),
    (".obj", {}, 1e-12),
])
def test_from_file_round_trip(tmp_path, suffix, kwargs, tolerance):
    p, t = Sphere((0, 0, 0), 1.0).outline(resolution=20)
    direct = TriangulatedSurface(p.T, t.T)
    path = tmp_path / f"punch{suffix}"
    meshio.write(path, meshio.Mesh(p.T, [("triangle", t.T)]), **kwargs)
    read = TriangulatedSurface.from_file(path, motion=(0, 0, -1))
    assert read.name == "punch" and read.nfeatures == direct.nfeatures
    x = random_directions(500) * RNG.uniform(0.5, 1.5, 500)
    np.testing.assert_allclose(read.project(x).gap, direct.project(x).gap, atol=tolerance)
    np.testing.assert_allclose(read.translation(1.0), [0, 0, -1])


def test_from_file_splits_quadrilaterals(tmp_path):
    points, triangles = cube_mesh(3)
    halves = triangles.reshape(6, 2, 9, 3)  # per face: the (a, b, c), then the (a, c, d)
    quads = np.concatenate([halves[:, 0], halves[:, 1, :, 2:]], axis=2).reshape(-1, 4)
    path = tmp_path / "die.msh"
    meshio.write(path, meshio.Mesh(points, [("quad", quads), ("line", quads[:3, :2])]),
                 file_format="gmsh22")
    cube = TriangulatedSurface.from_file(path, name="die")
    assert cube.nfeatures == 2 * len(quads) and cube.name == "die"
    x = RNG.uniform(-0.3, 1.3, (3, 500))
    np.testing.assert_allclose(cube.project(x).gap, box_distance(x), atol=1e-14)


def test_from_file_errors_name_the_file(tmp_path):
    with pytest.raises(ValueError, match="missing.stl.*does not exist"):
        TriangulatedSurface.from_file(tmp_path / "missing.stl")
    garbage = tmp_path / "garbage.stl"
    garbage.write_text("this is not a mesh\n")
    with pytest.raises(ValueError, match="cannot read .*garbage.stl"):
        TriangulatedSurface.from_file(garbage)
    lines = tmp_path / "lines.msh"
    meshio.write(lines, meshio.Mesh(np.eye(3), [("line", np.array([[0, 1], [1, 2]]))]),
                 file_format="gmsh")
    with pytest.raises(ValueError, match="lines.msh.*no triangles or quadrilaterals "
                                         r"\(cell types: line\)"):
        TriangulatedSurface.from_file(lines)
    flat = tmp_path / "flat.msh"
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]], dtype=float)
    meshio.write(flat, meshio.Mesh(pts, [("triangle", np.array([[0, 1, 2], [0, 1, 3]]))]),
                 file_format="gmsh")
    with pytest.raises(ValueError, match=r"flat.msh.*1 degenerate.*first: 1.*"
                                         r"triangle 1: triangle cell 1\)"):
        TriangulatedSurface.from_file(flat)
    points, triangles = cube_mesh(1)  # quads: (a, b, c), (a, c, d) per face
    quads = np.concatenate([triangles[0::2], triangles[1::2, 2:]], axis=1)
    quads[4] = quads[4, ::-1]
    turned = tmp_path / "turned.msh"
    meshio.write(turned, meshio.Mesh(points, [("quad", quads)]), file_format="gmsh22")
    with pytest.raises(ValueError, match=r"turned.msh.*same direction.*triangles \[1, 9\]"
                                         r".*triangle 1: quad cell 0, triangle 9: quad cell 4"):
        TriangulatedSurface.from_file(turned)


# --- input checks ---------------------------------------------------------------

@pytest.mark.parametrize("build, message", [
    (lambda: Plane((0, 0, 0), (0, 0, 0)), "plane normal must be a non-zero vector"),
    (lambda: Plane((0, np.nan, 0), (0, 0, 1)), "plane point must be three finite"),
    (lambda: Plane((0, 0), (0, 0, 1)), "plane point must be three finite"),
    (lambda: Cylinder((0, 0, 0), (0, 0, 1), -1.0), "cylinder radius must be positive"),
    (lambda: Cylinder((0, 0, 0), (0, 0, 1), 1.0, side="above"), 'side must be "outside"'),
    (lambda: Sphere((0, 0, 0), "big"), "sphere radius must be a finite number"),
    (lambda: Torus((0, 0, 0), (0, 0, 1), 1.0, 1.0), "minor radius 1.0 must be smaller"),
    (lambda: Torus((0, 0, 0), (np.inf, 0, 1), 2.0, 1.0), "torus axis must be three finite"),
    (lambda: Plane((0, 0, 0), (0, 0, 1), motion=(1, 2)), "motion must be a callable"),
    (lambda: Plane((0, 0, 0), (0, 0, 1), rotation=dict(axis=(0, 0, 1), angel=3)),
     r"unknown keys \['angel'\], missing keys \['angle'\]"),
    (lambda: Plane((0, 0, 0), (0, 0, 1), rotation=dict(axis=(0, 0, 0), angle=3)),
     "rotation axis must be a non-zero vector"),
    (lambda: Plane((0, 0, 0), (0, 0, 1), rotation=90), "rotation must be None or dict"),
    (lambda: Sphere((0, 0, 0), 1.0).outline(resolution=2), "resolution must be at least 3"),
])
def test_bad_input_is_refused_with_a_message(build, message):
    with pytest.raises(ValueError, match=message):
        build()


def test_bad_points_and_motions_at_projection_time():
    plane = Plane((0, 0, 0), (0, 0, 1), motion=lambda t: (0, t))
    with pytest.raises(ValueError, match=r"points must have shape \(3, n\)"):
        plane.project(np.zeros((2, 4)))
    x = np.zeros((3, 5))
    x[1, 3] = np.nan
    with pytest.raises(ValueError, match="point 3 is not finite"):
        Plane((0, 0, 0), (0, 0, 1)).project(x)
    with pytest.raises(ValueError, match=r"tool 'plane': motion\(0.5\) must return three"):
        plane.project(np.zeros((3, 1)), 0.5)
    turning = Plane((0, 0, 0), (0, 0, 1), rotation=dict(axis=(0, 0, 1),
                                                        angle=lambda t: None))
    with pytest.raises(ValueError, match="rotation angle"):
        turning.project(np.zeros((3, 1)), 0.5)


def test_bad_triangulations_are_refused():
    points, triangles = cube_mesh(2)
    flipped = triangles.copy()
    flipped[5] = flipped[5, ::-1]
    with pytest.raises(ValueError, match=r"in the same direction.*triangles \[.*5.*\].*"
                                         "counter-clockwise"):
        TriangulatedSurface(points, flipped)
    fin = np.concatenate([triangles, [[triangles[0, 0], triangles[0, 1], 0]]])
    extra = np.concatenate([points, [[0.5, 0.5, 0.5]]])
    fin[-1, 2] = len(points)
    with pytest.raises(ValueError, match="shared by more than two triangles"):
        TriangulatedSurface(extra, fin)
    with pytest.raises(ValueError, match="triangle 1 refers to points"):
        TriangulatedSurface(points, np.array([[0, 1, 2], [0, 1, 999]]))
    with pytest.raises(ValueError, match="must hold integer point numbers"):
        TriangulatedSurface(points, triangles.astype(float))
    with pytest.raises(ValueError, match="point 2 is not finite"):
        TriangulatedSurface(np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]]), [[0, 1, 2]])
    with pytest.raises(ValueError, match=r"tool surface 'bad': 1 degenerate triangle.*"
                                         r"first: 0"):
        TriangulatedSurface(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]]), [[0, 1, 1]],
                            name="bad")


def test_repr_and_centre_points_are_finite():
    assert "radius 2.0, body inside" in repr(Sphere((0, 0, 0), 2.0, "inside"))
    points, triangles = cube_mesh(1)
    assert repr(TriangulatedSurface(points, triangles, name="c")) == \
        "TriangulatedSurface('c': 12 triangles, 8 points)"
    for surface in analytic_surfaces()[1:]:  # a point on the axis or at the centre
        anchor = getattr(surface, "center", getattr(surface, "point", None))
        proj = surface.project(anchor[:, None])
        assert np.all(np.isfinite(proj.curvature)) and np.isfinite(proj.gap).all()
        np.testing.assert_allclose(np.linalg.norm(proj.normal), 1.0)


# --- with the contact law -------------------------------------------------------

@pytest.mark.parametrize("tool", ["roll", "box corner"])
def test_the_contact_tangent_with_real_surfaces_is_the_derivative_of_the_force(tool):
    """:class:`SurfaceContact` on an FEM Hex1 cube pressed by a turning,
    moving roll, or into the corner of a triangulated box cavity, where the
    pressed top nodes lie in face, concave edge and concave vertex regions
    (whose curvature enters the tangent): the tangent equals central
    differences of the force to 1e-7 of its largest entry (h = 1e-7 against
    displacements of 1e-2: truncation ~h², rounding ~1e-16/h)."""
    from skfem import Basis, ElementHex1, ElementVector, MeshHex

    from skfem_rkpm.mechanics.materials import J2Material, linear
    from skfem_rkpm.mechanics.problem import SolidProblem
    from skfem_rkpm.mechanics.surface_contact import SurfaceContact

    if tool == "roll":
        surface = Cylinder((0.5, 0.5, 2.0), (1.0, 0.2, 0.0), 1.03, motion=(0.1, 0.05, -0.05),
                           rotation=dict(axis=(1.0, 0.2, 0.0), point=(0.5, 0.5, 2.0),
                                         angle=-20))
    else:  # the cavity [-0.5, 0.99] x [-0.5, 0.98] x [-0.5, 0.985], body inside
        points, triangles = cube_mesh(2)
        surface = TriangulatedSurface(points * [1.49, 1.48, 1.485] - 0.5,
                                      triangles[:, ::-1], motion=(0.01, 0.0, -0.01))
    grid = np.linspace(0.0, 1.0, 3)
    mesh = MeshHex.init_tensor(grid, grid, grid).with_boundaries(
        {"top": lambda x: x[2] > 1.0 - 1e-9})
    problem = SolidProblem(Basis(mesh, ElementVector(ElementHex1()), intorder=2),
                           J2Material(200e3, 0.3, linear(300.0, 2000.0)), "3d")
    contact = SurfaceContact(problem, surface, "top", 0.3, "nodal", penalty=1e5,
                             tangential_penalty=2e4)
    d0 = 0.01 * RNG.normal(size=problem.N)
    contact.evaluate(d0, 0.5)
    contact.commit()
    d = d0 + 0.01 * RNG.normal(size=problem.N)
    _, K = contact.evaluate(d, 0.6)
    active = contact.trial.active
    assert active.any()
    if tool == "box corner":
        x = (contact.points.X + contact.points.displacements(d))[:, active]
        local = surface.to_body(x, 0.6).T
        best = surface._closest_triangles(local)
        a, b, c = surface.points[surface.triangles[best]].transpose(1, 0, 2)
        regions = closest_points_on_triangles(local, a, b, c)[1]
        assert {0} < set(regions.tolist()) and (regions >= 4).any()  # face, edge, vertex
    h = 1e-7
    fd = np.column_stack([(contact.evaluate(d + h * e, 0.6)[0]
                           - contact.evaluate(d - h * e, 0.6)[0]) / (2 * h)
                          for e in np.eye(len(d))])
    K = K.toarray()
    assert np.abs(K - fd).max() < 1e-7 * np.abs(K).max()
