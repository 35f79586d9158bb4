"""Rigid tool surfaces in 3D: planes, cylinders, spheres and tori.

The 3D counterpart of :mod:`.tools`.  A surface is a rigid tool with a
prescribed rigid motion (a translation and a rotation about a fixed axis);
the body it touches lies on one side of it, and the unit normal ``n`` points
to that side.  Every surface projects points onto itself: closest point
``x_C``, normal, signed gap ``g_n = (x - x_C)·n`` (Eq. 4.1, 4.10) and the
curvature tensor ``C = ∂n/∂x``, the Hessian of the signed distance
(:class:`SurfaceProjection`).  Triangulated surfaces (a tool from CAD, read
with meshio) are in :mod:`.triangulated`.
"""

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from .tools import _floats, _number

__all__ = ["SurfaceProjection", "Surface", "Plane", "Cylinder", "Sphere", "Torus",
           "axis_rotation"]

_SIDES = {"outside": 1.0, "inside": -1.0}


def _vector(value, what):
    """``value`` as three finite floats; a ValueError naming ``what`` otherwise."""
    v = _floats(value, what, "(3,)")
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{what} must be three finite numbers (x, y, z), not {value!r}")
    return v


def _unit(value, what):
    """``value`` scaled to unit length; a ValueError if it is zero."""
    v = _vector(value, what)
    scale = np.abs(v).max()
    if not scale > 0:
        raise ValueError(f"{what} must be a non-zero vector, not {v.tolist()}")
    v = v / scale  # no overflow or underflow in the norm
    return v / np.linalg.norm(v)


def _positive(value, what):
    x = _number(value, what)
    if not x > 0:
        raise ValueError(f"{what} must be positive, not {value!r}")
    return x


def _side(side):
    """+1 for a body outside the surface, -1 inside."""
    if not isinstance(side, str) or side not in _SIDES:
        raise ValueError(f'side must be "outside" (the body is outside the surface) '
                         f'or "inside" (the body is inside it), not {side!r}')
    return _SIDES[side]


def _perpendicular(a):
    """A unit vector perpendicular to the unit vector ``a``."""
    e = np.zeros(3)
    e[np.argmin(np.abs(a))] = 1.0
    p = np.cross(a, e)
    return p / np.linalg.norm(p)


def _radial(v, fallback):
    """Unit vectors along the rows of ``v`` (n, 3) and their lengths;
    ``fallback`` (3,) or (n, 3) where a row is zero."""
    rho = np.linalg.norm(v, axis=1)
    zero = rho == 0.0
    u = v / np.where(zero, 1.0, rho)[:, None]
    return np.where(zero[:, None], fallback, u), rho


def _inverse(rho):
    """``1/rho``, 0 where ``rho`` is 0 (the curvature of a point on an axis
    or a centre, where the closest point is not unique, is set to zero)."""
    return np.where(rho > 0.0, 1.0 / np.where(rho > 0.0, rho, 1.0), 0.0)


def _projector(u):
    """``I - u uᵀ`` for the rows of ``u`` (n, 3): (n, 3, 3)."""
    return np.eye(3) - u[:, :, None] * u[:, None, :]


def axis_rotation(axis, angle):
    """Rotation matrix (3, 3) of ``angle`` radians about the unit ``axis``
    (right-hand rule; Rodrigues' formula)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                  [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * (k @ k)


def _motion(motion):
    """``t -> (dx, dy, dz)`` of a callable or of a final translation."""
    if callable(motion):
        return motion
    final = _floats(motion, "motion", "(3,)")
    if final.shape != (3,) or not np.all(np.isfinite(final)):
        raise ValueError("motion must be a callable t -> (dx, dy, dz) or a final "
                         f"translation (dx, dy, dz), not {motion!r}")
    return lambda t: t * final


def _rotation(rotation):
    """``(axis, point, angle)`` of a rotation dict, ``angle`` a callable
    ``t -> degrees``; None for no rotation."""
    if rotation is None:
        return None
    usage = ("rotation must be None or dict(axis=(ax, ay, az), point=(x, y, z), "
             "angle=degrees at t = 1 or a callable t -> degrees)")
    if not isinstance(rotation, dict):
        raise ValueError(f"{usage}, not {rotation!r}")
    unknown = sorted(set(rotation) - {"axis", "point", "angle"})
    missing = sorted({"axis", "angle"} - set(rotation))
    if unknown or missing:
        raise ValueError(f"{usage}; unknown keys {unknown}, missing keys {missing}")
    axis = _unit(rotation["axis"], "rotation axis")
    point = _vector(rotation.get("point", (0.0, 0.0, 0.0)), "rotation point")
    angle = rotation["angle"]
    if not callable(angle):
        final = _number(angle, "rotation angle (degrees at t = 1)")
        angle = lambda t: t * final  # noqa: E731
    return axis, point, angle


@dataclass
class SurfaceProjection:
    """Closest points of points ``x`` on a rigid surface, in the world frame.

    Attributes
    ----------
    point : ndarray (3, n)
        Closest point ``x_C`` on the surface.
    normal : ndarray (3, n)
        Unit normal at ``x_C`` pointing to the body (the side where the gap
        is positive); at edges and vertices of a triangulated surface the
        unit vector from ``x_C`` to ``x``, signed by the pseudo-normal.
    gap : ndarray (n,)
        Signed gap ``g_n = (x - x_C)·n`` (Eq. 4.1, 4.10); negative is
        penetration.  ``∂g_n/∂x = n``.
    curvature : ndarray (n, 3, 3)
        ``C = ∂n/∂x`` at ``x``: the Hessian of the signed distance,
        symmetric, zero on flat parts; e.g. ``(I - n nᵀ)/ρ`` outside a
        sphere, ``ρ = |x - center|``.
    feature : ndarray (n,)
        Index of the closest feature (0 for the analytic surfaces, the
        triangle for a triangulated one).
    """

    point: np.ndarray
    normal: np.ndarray
    gap: np.ndarray
    curvature: np.ndarray
    feature: np.ndarray


class Surface(ABC):
    """A rigid tool surface in 3D with a prescribed rigid motion.

    A point fixed to the tool moves as ``x = R(t) x_body + b(t)``: first a
    rotation by ``angle(t)`` about an axis through ``point``, then the
    translation ``motion(t)``; at ``t = 0`` with no motion the body frame is
    the world frame.  Use :class:`Plane`, :class:`Cylinder`, :class:`Sphere`,
    :class:`Torus` or :class:`~skfem_rkpm.mechanics.triangulated.TriangulatedSurface`.

    Parameters
    ----------
    motion : callable or array_like (3,)
        ``motion(t) -> (dx, dy, dz)`` at load factor ``t``, or the
        translation at ``t = 1`` reached linearly.
    rotation : dict, optional
        ``dict(axis=(3,), point=(3,), angle=...)``: a rotation about the
        fixed axis through ``point`` (default the origin) by ``angle``
        degrees at ``t = 1``, linear in ``t``, or by ``angle(t)`` degrees if
        ``angle`` is callable (a roll).
    name : str
        Key of the tool's force in the contact output.
    """

    def __init__(self, motion=(0.0, 0.0, 0.0), rotation=None, name="tool"):
        self.motion = _motion(motion)
        self.rotation = _rotation(rotation)
        self.name = str(name)

    def _shift(self, t):
        dx = np.asarray(self.motion(t), dtype=float)
        if dx.shape != (3,) or not np.all(np.isfinite(dx)):
            raise ValueError(f"tool {self.name!r}: motion({t}) must return three "
                             f"finite numbers, not {dx!r}")
        return dx

    def placement(self, t):
        """``(R, b)`` at load factor ``t``: ``x_world = R @ x_body + b``."""
        shift = self._shift(t)
        if self.rotation is None:
            return np.eye(3), shift
        axis, point, angle = self.rotation
        degrees = _number(angle(t), f"tool {self.name!r}: rotation angle({t})")
        R = axis_rotation(axis, np.radians(degrees))
        return R, point - R @ point + shift

    def displacement(self, t):
        """The prescribed translation ``motion(t)`` (what a gauge reports;
        without the swing of a rotation)."""
        return self._shift(t)

    def translation(self, t):
        """``b(t)``: the position of the body-frame origin, i.e. its
        displacement ``(dx, dy, dz)`` from the world origin (the motion, plus
        the swing of the origin when the tool rotates about an axis that
        misses it)."""
        return self.placement(t)[1]

    def to_body(self, x, t):
        """Body-frame coordinates ``Rᵀ (x - b)`` (3, n) of world points ``x``."""
        R, b = self.placement(t)
        return R.T @ (_points(x) - b[:, None])

    def project(self, x, t=0.0):
        """Closest-point projection of world points ``x`` (3, n) on the
        surface at load factor ``t``; the gap is Eq. (4.1, 4.10).

        Returns
        -------
        SurfaceProjection
            In the world frame.
        """
        x = _points(x)
        R, b = self.placement(t)
        local = (R.T @ (x - b[:, None])).T
        point, normal, gap, curvature, feature = self._project_body(local)
        return SurfaceProjection(R @ point.T + b[:, None], R @ normal.T, gap,
                                 R @ curvature @ R.T, feature)

    def outline(self, t=0.0, resolution=32, extent=1.0):
        """A triangulation of (a bounded piece of) the surface at ``t`` for
        plotting: ``(points (3, m), triangles (3, k))``.

        The triangles are counter-clockwise seen from the body, so that
        ``TriangulatedSurface(points.T, triangles.T)`` is a faceted copy of
        the tool.  ``resolution`` is the number of segments around a full
        circle; infinite surfaces are cut at ``extent`` from their anchor.
        """
        resolution = int(resolution)
        if resolution < 3:
            raise ValueError(f"resolution must be at least 3, not {resolution}")
        extent = _positive(extent, "extent")
        points, triangles = self._outline_body(resolution, extent)
        R, b = self.placement(t)
        return R @ points.T + b[:, None], triangles.T

    @property
    def nfeatures(self):
        return 1

    @abstractmethod
    def _project_body(self, x):
        """``(point, normal, gap, curvature, feature)`` of body-frame points
        ``x`` (n, 3), arrays (n, 3), (n, 3), (n,), (n, 3, 3), (n,)."""

    @abstractmethod
    def _outline_body(self, resolution, extent):
        """``(points (m, 3), triangles (k, 3))`` of the surface in the body
        frame, counter-clockwise seen from the body."""

    def __repr__(self):
        return f"{type(self).__name__}({self.name!r}: {self._describe()})"

    def _describe(self):
        return ""


def _points(x):
    """World points (3, n) as a finite float array; errors name the point."""
    x = _floats(x, "points", "(3, n)")
    if x.ndim != 2 or x.shape[0] != 3:
        raise ValueError(f"points must have shape (3, n), not {x.shape}")
    bad = ~np.all(np.isfinite(x), axis=0)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(f"point {k} is not finite: {x[:, k].tolist()}")
    return x


def _grid_triangles(nu, nv, periodic_u, periodic_v):
    """Triangles (k, 3) of an ``nu × nv`` grid of points (index ``i nv + j``),
    counter-clockwise in the ``(u, v)`` plane, closed where periodic."""
    mu, mv = (nu if periodic_u else nu - 1), (nv if periodic_v else nv - 1)
    i, j = np.meshgrid(np.arange(mu), np.arange(mv), indexing="ij")
    i, j = i.ravel(), j.ravel()
    a, b = i * nv + j, (i + 1) % nu * nv + j
    c, d = (i + 1) % nu * nv + (j + 1) % nv, i * nv + (j + 1) % nv
    return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def _icosphere(resolution):
    """Unit-sphere points (m, 3) and outward triangles (k, 3): an icosahedron
    refined until about ``resolution`` segments go around a great circle."""
    g = (1.0 + 5.0 ** 0.5) / 2.0
    p = np.array([[-1, g, 0], [1, g, 0], [-1, -g, 0], [1, -g, 0], [0, -1, g],
                  [0, 1, g], [0, -1, -g], [0, 1, -g], [g, 0, -1], [g, 0, 1],
                  [-g, 0, -1], [-g, 0, 1]], dtype=float)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
                  [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
                  [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
                  [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    for _ in range(max(0, int(np.ceil(np.log2(resolution / 5.0))))):
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), 1)
        unique, inverse = np.unique(edges, axis=0, return_inverse=True)
        ab, bc, ca = len(p) + inverse.reshape(3, -1)
        p = np.vstack([p, 0.5 * (p[unique[:, 0]] + p[unique[:, 1]])])
        a, b, c = f.T
        f = np.concatenate([np.stack(v, 1) for v in
                            ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    return p / np.linalg.norm(p, axis=1)[:, None], f


def _oriented(triangles, sign):
    """Outward triangles turned inward for a body inside (``sign < 0``)."""
    return triangles if sign > 0 else triangles[:, ::-1]


class Plane(Surface):
    """An infinite flat tool through ``point``; the body is on the side
    ``normal`` points to (a platen, a die face).

    Parameters
    ----------
    point : array_like (3,)
    normal : array_like (3,)
        Need not be unit; must not be zero.
    motion, rotation, name
        See :class:`Surface`.
    """

    def __init__(self, point, normal, motion=(0.0, 0.0, 0.0), rotation=None,
                 name="plane"):
        super().__init__(motion, rotation, name)
        self.point = _vector(point, "plane point")
        self.normal = _unit(normal, "plane normal")

    def _project_body(self, x):
        gap = (x - self.point) @ self.normal
        n = len(x)
        return (x - gap[:, None] * self.normal, np.tile(self.normal, (n, 1)), gap,
                np.zeros((n, 3, 3)), np.zeros(n, dtype=int))

    def _outline_body(self, resolution, extent):
        e1 = _perpendicular(self.normal)
        e2 = np.cross(self.normal, e1)
        corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float)
        points = self.point + extent * (corners[:, :1] * e1 + corners[:, 1:] * e2)
        return points, np.array([[0, 1, 2], [0, 2, 3]])

    def _describe(self):
        return f"point {self.point.tolist()}, normal {self.normal.tolist()}"


class Cylinder(Surface):
    """An infinite circular cylinder: a roll or a punch (``side="outside"``,
    the body outside it) or a die bore (``side="inside"``).

    Parameters
    ----------
    point : array_like (3,)
        A point of the axis.
    axis : array_like (3,)
        Axis direction (need not be unit; not zero).
    radius : float
        Positive.
    side : {"outside", "inside"}
        Where the body is.
    motion, rotation, name
        See :class:`Surface`.

    Notes
    -----
    ``C = s (I - a aᵀ - n nᵀ)/ρ`` with ``ρ`` the distance of ``x`` from the
    axis ``a`` and ``s = ±1`` for outside/inside.  A point on the axis is
    projected along a fixed direction, with ``C = 0``.
    """

    def __init__(self, point, axis, radius, side="outside", motion=(0.0, 0.0, 0.0),
                 rotation=None, name="cylinder"):
        super().__init__(motion, rotation, name)
        self.point = _vector(point, "cylinder axis point")
        self.axis = _unit(axis, "cylinder axis")
        self.radius = _positive(radius, "cylinder radius")
        self.side = side
        self._sign = _side(side)

    def _project_body(self, x):
        v = x - self.point
        h = v @ self.axis
        u, rho = _radial(v - h[:, None] * self.axis, _perpendicular(self.axis))
        s = self._sign
        curvature = s * (_projector(u) - np.outer(self.axis, self.axis)) \
            * _inverse(rho)[:, None, None]
        return (self.point + h[:, None] * self.axis + self.radius * u, s * u,
                s * (rho - self.radius), curvature, np.zeros(len(x), dtype=int))

    def _outline_body(self, resolution, extent):
        e1 = _perpendicular(self.axis)
        e2 = np.cross(self.axis, e1)
        theta = np.linspace(0.0, 2.0 * np.pi, resolution, endpoint=False)
        nz = max(2, int(np.ceil(resolution * extent / (np.pi * self.radius))) + 1)
        z = np.linspace(-extent, extent, nz)
        ring = self.radius * (np.cos(theta)[:, None] * e1 + np.sin(theta)[:, None] * e2)
        points = self.point + ring[:, None, :] + z[None, :, None] * self.axis
        triangles = _grid_triangles(resolution, nz, True, False)
        return points.reshape(-1, 3), _oriented(triangles, self._sign)

    def _describe(self):
        return (f"point {self.point.tolist()}, axis {self.axis.tolist()}, "
                f"radius {self.radius}, body {self.side}")


class Sphere(Surface):
    """A sphere: a ball punch (``side="outside"``) or a spherical cavity
    (``side="inside"``).

    Parameters
    ----------
    center : array_like (3,)
    radius : float
        Positive.
    side : {"outside", "inside"}
        Where the body is.
    motion, rotation, name
        See :class:`Surface`.

    Notes
    -----
    ``C = s (I - n nᵀ)/ρ``, ``ρ = |x - center|``, ``s = ±1`` for
    outside/inside.  The centre is projected along a fixed direction, with
    ``C = 0``.
    """

    def __init__(self, center, radius, side="outside", motion=(0.0, 0.0, 0.0),
                 rotation=None, name="sphere"):
        super().__init__(motion, rotation, name)
        self.center = _vector(center, "sphere center")
        self.radius = _positive(radius, "sphere radius")
        self.side = side
        self._sign = _side(side)

    def _project_body(self, x):
        u, rho = _radial(x - self.center, np.array([0.0, 0.0, 1.0]))
        s = self._sign
        return (self.center + self.radius * u, s * u, s * (rho - self.radius),
                s * _projector(u) * _inverse(rho)[:, None, None],
                np.zeros(len(x), dtype=int))

    def _outline_body(self, resolution, extent):
        points, triangles = _icosphere(resolution)
        return self.center + self.radius * points, _oriented(triangles, self._sign)

    def _describe(self):
        return (f"center {self.center.tolist()}, radius {self.radius}, "
                f"body {self.side}")


class Torus(Surface):
    """A ring torus: the tube of radius ``minor_radius`` around the circle of
    radius ``major_radius`` about ``axis`` through ``center``.  With the body
    outside the tube it models a die shoulder (a draw die's entry radius);
    ``side="inside"`` puts the body inside the tube.

    Parameters
    ----------
    center : array_like (3,)
    axis : array_like (3,)
        Normal of the plane of the major circle (not zero).
    major_radius, minor_radius : float
        ``0 < minor_radius < major_radius``.  Horn and spindle tori
        (``minor_radius >= major_radius``) are refused: they intersect
        themselves, and the distance to the tube is no longer the distance
        to the surface for points inside.
    side : {"outside", "inside"}
        Where the body is.
    motion, rotation, name
        See :class:`Surface`.

    Notes
    -----
    The closest point lies on the segment from ``x`` to the nearest point
    ``q`` of the major circle.  With ``s`` the distance ``|x - q|``, ``ρ``
    the distance of ``x`` from the axis and ``e`` the circle's tangent,
    ``C = ±(I - n nᵀ - (R/ρ) e eᵀ)/s``.  Points on the axis (every circle
    point is nearest) use a fixed meridian and drop the ``e eᵀ`` term.
    """

    def __init__(self, center, axis, major_radius, minor_radius, side="outside",
                 motion=(0.0, 0.0, 0.0), rotation=None, name="torus"):
        super().__init__(motion, rotation, name)
        self.center = _vector(center, "torus center")
        self.axis = _unit(axis, "torus axis")
        self.major_radius = _positive(major_radius, "torus major radius")
        self.minor_radius = _positive(minor_radius, "torus minor radius")
        if not self.minor_radius < self.major_radius:
            raise ValueError(f"torus minor radius {self.minor_radius} must be smaller "
                             f"than its major radius {self.major_radius} (a ring "
                             "torus); horn and spindle tori intersect themselves")
        self.side = side
        self._sign = _side(side)

    def _project_body(self, x):
        v = x - self.center
        h = v @ self.axis
        w, rho = _radial(v - h[:, None] * self.axis, _perpendicular(self.axis))
        R, s = self.major_radius, self._sign
        u, dist = _radial(x - (self.center + R * w), w)
        e = np.cross(self.axis, w)
        tangential = (R * _inverse(rho))[:, None, None] * (e[:, :, None] * e[:, None, :])
        curvature = s * (_projector(u) - tangential) * _inverse(dist)[:, None, None]
        return (self.center + R * w + self.minor_radius * u, s * u,
                s * (dist - self.minor_radius), curvature, np.zeros(len(x), dtype=int))

    def _outline_body(self, resolution, extent):
        e1 = _perpendicular(self.axis)
        e2 = np.cross(self.axis, e1)
        nminor = max(8, int(np.ceil(resolution * self.minor_radius / self.major_radius)))
        theta = np.linspace(0.0, 2.0 * np.pi, resolution, endpoint=False)[:, None, None]
        phi = np.linspace(0.0, 2.0 * np.pi, nminor, endpoint=False)[None, :, None]
        w = np.cos(theta) * e1 + np.sin(theta) * e2
        r, R = self.minor_radius, self.major_radius
        points = self.center + (R + r * np.cos(phi)) * w + r * np.sin(phi) * self.axis
        triangles = _grid_triangles(resolution, nminor, True, True)
        return points.reshape(-1, 3), _oriented(triangles, self._sign)

    def _describe(self):
        return (f"center {self.center.tolist()}, axis {self.axis.tolist()}, radii "
                f"{self.major_radius}/{self.minor_radius}, body {self.side}")
