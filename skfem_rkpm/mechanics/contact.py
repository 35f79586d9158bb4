"""Frictional contact by penalty, Sec. 4 of Chen, Pan, Roque & Wang (1998).

A *master* surface (a rigid tool, or the boundary of a deformable body) and a
set of *slave* points on the workpiece boundary.  Every slave point ``x`` is
projected onto the master surface (closest point ``x_C``, Eq. 4.7-4.9); the
signed normal gap is ``g_n = (x - x_C)·n`` (Eq. 4.1, 4.10) with ``n`` the
outward normal of the master surface, negative for penetration.  The contact
constraint ``g_n ≥ 0`` and Coulomb's law (Eq. 4.3) are enforced with the
penalized tractions of Eq. (4.5)-(4.6):

    t_n = ω_n ⟨-g_n⟩,
    t_t = t_t,n - ω_t Δg_t            if |t_t,n - ω_t Δg_t| ≤ μ t_n   (stick)
    t_t = μ t_n sgn(t_t,n - ω_t Δg_t)  otherwise                       (slip)

where ``Δg_t`` is the tangential slip of the slave point relative to the
master surface since the last converged step (Eq. 4.11) and ``t_t,n`` the
tangential traction of that step (the return map of a penalty regularized
Coulomb law).  ``t_n`` pushes the body along ``n``; ``t_t`` acts along the
tangent ``t`` of the master surface (``n = e_3 × t``, Eq. 4.7).

The law acts at the boundary particles (contact nodes ``K``); the slave
points where gaps are measured and forces applied depend on ``collocation``:

``"nodal"``
    The paper's choice: the boundary particles themselves, at their current
    positions ``x = X + û`` with the nodal displacements ``û = Λᵀ d``
    (Eq. 3.32).  The nodal contact forces ``f̂`` (Eq. 4.27) and stiffness
    ``K̂`` (Eq. 4.28-4.29), weighted by the tributary area
    ``W_K = ∫_Γ N_K dΓ`` of the particle (hat functions ``N_K`` on the
    boundary facets, with ``2πR`` for axisymmetric models), go back to the
    coefficients as ``f = Λ f̂``, ``K = Λ K̂ Λᵀ``.
``"quadrature"``
    The Gauss points ``x_q`` of the boundary facets, with
    ``u(x_q) = Σ_I Ψ_I(x_q) d_I``.  The particle ``K`` sees the hat-weighted
    averages ``ĝ_K = Σ_q N_K(x_q) w_q g_q / W_K`` of the gaps and slips (a
    mortar-type weighted gap), and its tractions are interpolated back,
    ``t(x_q) = Σ_K N_K(x_q) t_K``, and integrated as
    ``f_I = Σ_q w_q Ψ_I(x_q) t(x_q)``.  A uniform traction is then
    integrated exactly, so a homogeneous compression stays exact for RK
    bases, which nodal forces ``Σ_K Ψ_I(X_K) f̂_K`` cannot achieve; and
    there is one law per particle, as in the nodal case.  At a corner of
    the slave surface the particle carries one law per side, so that a
    weighted gap never mixes two faces.
``"gauss"``
    The law at every Gauss point.  Exact for homogeneous states too, but
    with three Gauss points per facet the boundary is over-constrained and
    friction converges badly (measured in ``docs/contact.md``).

All are written as ``u_points = G d`` with a sparse ``G`` (rows of ``Λᵀ``,
or shape function values at boundary Gauss points) so that
``f = Gᵀ f_points`` and ``K = Gᵀ K_points G``; for a finite element basis
``Λ`` is the identity.

A node that comes into contact during a step counts its slip from the moment
it touches (the gap interpolated linearly over the step), so that its
tangential traction starts from zero, also when it sticks.

Rigid tools (:class:`Platen`, :class:`Polyline`, :class:`Arc`) move with the
load factor; :class:`RigidContact` is their contribution to the Newton
iterations of :func:`skfem_rkpm.solvers.newton.newton_steps`.  Contact between two
deformable bodies of one mesh (node-to-segment, Eq. 4.13-4.19, frictionless)
is :class:`NodeToSegmentContact`.

Geometry convention: a master surface is traversed in a direction; the body
it touches lies on the *left* of that direction, and the outward normal of
the master surface is ``n = e_3 × t`` (Eq. 4.7), pointing toward the body.
"""

from dataclasses import dataclass

from functools import cached_property

import numpy as np
import scipy.sparse as sp

from ..approximation.constraints import transformation
from .problem import NonFiniteError

__all__ = ["DEFAULT_PENALTY_FACTOR", "DEFAULT_TANGENTIAL_FACTOR", "Projection", "Tool",
           "Platen", "Polyline", "polyline", "Arc", "SlavePoints", "slave_points",
           "default_penalty", "STICK_FRICTION", "friction_coefficient", "coulomb", "ContactState",
           "RigidContact", "NodeToSegmentContact", "from_scene"]

#: ω_n = DEFAULT_PENALTY_FACTOR · E / h_c per unit area of the contact
#: boundary (h_c the particle spacing along it).  A contact pressure p then
#: penetrates g = p h_c / (1000 E): for metals (p ≲ 3 σ_y ≈ 1e-2 E) below
#: 1e-5 h_c.  Between 1e2 and 1e4 the Newton iteration counts do not change
#: (measured, docs/contact.md).
DEFAULT_PENALTY_FACTOR = 1e3

#: ω_t = DEFAULT_TANGENTIAL_FACTOR · E / h_c.  The elastic slip of a
#: sticking point, t_t / ω_t ≤ μ (t_n / E) h_c, is then below 1 % of the
#: spacing for metals.  A stiffer ω_t turns the stick/slip law into a near
#: step function of the displacement and Newton cycles between stick and
#: reversed slip (measured: ω_t = ω_n needs cut-backs, docs/contact.md).
DEFAULT_TANGENTIAL_FACTOR = 1.0

_TWO_PI = 2.0 * np.pi


# ---------------------------------------------------------------------------
# geometry of rigid master surfaces
# ---------------------------------------------------------------------------


def _left(v):
    """``e_3 × v`` for vectors ``v`` (..., 2): the normal of Eq. (4.7)."""
    return np.stack([-v[..., 1], v[..., 0]], axis=-1)


def _tangent_of(n):
    """The tangent ``t`` with ``n = e_3 × t``."""
    return np.stack([n[..., 1], -n[..., 0]], axis=-1)


def _floats(value, what, shape):
    """``value`` as a float array; a ValueError naming ``what`` if it is not numbers."""
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be numbers of shape {shape}, not {value!r}") from None


def _number(value, what):
    """``value`` as a finite float; a ValueError naming ``what`` otherwise."""
    try:
        x = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        x = None
    if x is None or x.shape != () or isinstance(value, (bool, np.bool_)) \
            or not np.isfinite(x):
        raise ValueError(f"{what} must be a finite number, not {value!r}")
    return float(x)


def _unit(v, what):
    v = _floats(v, what, "(2,)")
    scale = np.abs(v).max() if v.shape == (2,) else np.nan
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"{what} must be a finite non-zero 2D vector, not {v.tolist()}")
    v = v / scale  # no overflow or underflow in the norm
    return v / np.linalg.norm(v)


def _point(p, what):
    p = _floats(p, what, "(2,)")
    if p.shape != (2,) or not np.all(np.isfinite(p)):
        raise ValueError(f"{what} must be two finite coordinates (x, y), not {p!r}")
    return p


def _motion(motion):
    """``t -> (dx, dy)`` of a callable or of a final displacement."""
    if callable(motion):
        return motion
    final = _floats(motion, "motion", "(2,)")
    if final.shape != (2,) or not np.all(np.isfinite(final)):
        raise ValueError("motion must be a callable t -> (dx, dy) or a final "
                         f"displacement (dx, dy), not {motion!r}")
    return lambda t: t * final


@dataclass
class Projection:
    """Closest points of slave points on a master surface (Eq. 4.7-4.10).

    Attributes
    ----------
    point : ndarray (2, n)
        Closest point ``x_C``.
    normal : ndarray (2, n)
        Outward unit normal ``n`` of the master surface at ``x_C``.
    tangent : ndarray (2, n)
        Unit tangent ``t`` with ``n = e_3 × t``.
    gap : ndarray (n,)
        Signed normal gap ``g_n = (x - x_C)·n``; negative is penetration.
    curvature : ndarray (n,)
        ``κ`` with ``∂n/∂x = κ t tᵀ`` (zero on straight parts).
    feature : ndarray (n,)
        Index of the closest feature (lines, then segments, then arcs).
    """

    point: np.ndarray
    normal: np.ndarray
    tangent: np.ndarray
    gap: np.ndarray
    curvature: np.ndarray
    feature: np.ndarray


def _vertex_frame(x, v, pseudo):
    """Normal and curvature when the closest point is the vertex ``v``.

    The normal is the unit vector from ``v`` to ``x``, signed by the
    pseudo-normal of the vertex (the mean of the normals of the features
    that meet there), so that points on the body side have a positive gap.
    ``x`` (n, F, 2), ``v`` and ``pseudo`` (F, 2).
    """
    r = x - v[None]
    rho = np.linalg.norm(r, axis=-1)
    sign = np.where(np.einsum("nfk,fk->nf", r, pseudo) >= 0.0, 1.0, -1.0)
    safe = np.where(rho > 0, rho, 1.0)
    n = np.where((rho > 0)[..., None], sign[..., None] * r / safe[..., None],
                 np.broadcast_to(pseudo[None], r.shape))
    return n, np.where(rho > 0, sign / safe, 0.0)


def _project_lines(x, p, t):
    """Closest points on infinite lines through ``p`` along ``t`` (F, 2)."""
    s = np.einsum("nfk,fk->nf", x - p[None], t)
    cp = p[None] + s[..., None] * t[None]
    n = np.broadcast_to(_left(t)[None], cp.shape)
    return cp, n, np.zeros(cp.shape[:2])


def _project_segments(x, a, b, pseudo_a, pseudo_b):
    """Closest points on segments ``a → b`` (Eq. 4.8-4.9 with ``α`` clamped
    to ``[0, 1]``; beyond an end the end vertex is the closest point)."""
    e = b - a
    length = np.linalg.norm(e, axis=-1)
    t = e / length[:, None]
    s = np.einsum("nfk,fk->nf", x - a[None], t)
    cp = a[None] + np.clip(s, 0.0, length)[..., None] * t[None]
    n = np.broadcast_to(_left(t)[None], cp.shape).copy()
    kappa = np.zeros(cp.shape[:2])
    for end, vertex, pseudo in ((s <= 0.0, a, pseudo_a), (s >= length, b, pseudo_b)):
        nv, kv = _vertex_frame(x, vertex, pseudo)
        n = np.where(end[..., None], nv, n)
        kappa = np.where(end, kv, kappa)
    return cp, n, kappa


def _arc_ends(c, r, theta0, sweep):
    start = c + r[:, None] * np.stack([np.cos(theta0), np.sin(theta0)], axis=-1)
    end = c + r[:, None] * np.stack([np.cos(theta0 + sweep), np.sin(theta0 + sweep)],
                                    axis=-1)
    return start, end


def _project_arcs(x, c, r, theta0, sweep, pseudo_start, pseudo_end):
    """Closest points on circular arcs from ``theta0`` through ``sweep``
    (counter-clockwise if positive).  The body is on the left: inside the
    circle for counter-clockwise arcs, outside for clockwise ones."""
    v = x - c[None]
    rho = np.linalg.norm(v, axis=-1)
    safe = np.where(rho > 0, rho, 1.0)
    orient = np.sign(sweep)
    phi = np.arctan2(v[..., 1], v[..., 0])
    inside = np.mod(orient * (phi - theta0), _TWO_PI) <= np.abs(sweep)
    inside &= rho > 0
    radial = v / safe[..., None]
    cp = c[None] + r[None, :, None] * radial
    n = -orient[None, :, None] * radial
    kappa = -orient[None] / safe
    start, end = _arc_ends(c, r, theta0, sweep)
    ns, ks = _vertex_frame(x, start, pseudo_start)
    ne, ke = _vertex_frame(x, end, pseudo_end)
    to_start = (np.linalg.norm(x - start[None], axis=-1)
                <= np.linalg.norm(x - end[None], axis=-1))
    cp = np.where(inside[..., None], cp, np.where(to_start[..., None], start[None],
                                                  end[None]))
    n = np.where(inside[..., None], n, np.where(to_start[..., None], ns, ne))
    kappa = np.where(inside, kappa, np.where(to_start, ks, ke))
    return cp, n, kappa


def _closest(x, candidates):
    """Pick per point the closest of all candidate features."""
    cp = np.concatenate([c[0] for c in candidates], axis=1)
    n = np.concatenate([c[1] for c in candidates], axis=1)
    kappa = np.concatenate([c[2] for c in candidates], axis=1)
    dist = np.linalg.norm(x[:, None, :] - cp, axis=-1)
    k = np.argmin(dist, axis=1)
    rows = np.arange(x.shape[0])
    cp, n, kappa = cp[rows, k], n[rows, k], kappa[rows, k]
    gap = np.einsum("nk,nk->n", x - cp, n)
    return Projection(cp.T, n.T, _tangent_of(n).T, gap, kappa, k)


class Tool:
    """A rigid master surface made of lines, segments and arcs, with a
    prescribed rigid translation.

    Use :class:`Platen`, :class:`Polyline` (or :func:`polyline`) and
    :class:`Arc` to build one.  The body lies on the left of every feature's
    direction; the outward normal ``n = e_3 × t`` points to it.

    Parameters
    ----------
    motion : callable or array_like (2,)
        ``motion(t) -> (dx, dy)`` at load factor ``t``, or the displacement
        at ``t = 1`` reached linearly.  ``(0, 0)`` is a fixed tool.
    name : str
        Key of the tool's force in :meth:`RigidContact.resultants`.
    """

    def __init__(self, motion=(0.0, 0.0), name="tool"):
        self.motion = _motion(motion)
        self.name = str(name)
        self._lines = (np.zeros((0, 2)), np.zeros((0, 2)))
        self._segments = (np.zeros((0, 2)),) * 4
        self._arcs = (np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0),
                      np.zeros((0, 2)), np.zeros((0, 2)))

    def translation(self, t):
        """Rigid displacement ``(dx, dy)`` of the tool at load factor ``t``."""
        dx = np.asarray(self.motion(t), dtype=float)
        if dx.shape != (2,) or not np.all(np.isfinite(dx)):
            raise ValueError(f"tool {self.name!r}: motion({t}) must return two "
                             f"finite numbers, not {dx!r}")
        return dx

    @property
    def nfeatures(self):
        return len(self._lines[0]) + len(self._segments[0]) + len(self._arcs[0])

    def project(self, x, t=0.0):
        """Closest-point projection of points ``x`` (2, n) on the tool at
        load factor ``t`` (Eq. 4.7-4.10), vectorized over points and
        features; the closest feature wins.

        Returns
        -------
        Projection
        """
        x = np.asarray(x, dtype=float)
        if x.ndim != 2 or x.shape[0] != 2:
            raise ValueError(f"points must have shape (2, n), not {x.shape}")
        shift = self.translation(t)
        local = (x - shift[:, None]).T
        candidates = []
        if len(self._lines[0]):
            candidates.append(_project_lines(local[:, None, :], *self._lines))
        if len(self._segments[0]):
            candidates.append(_project_segments(local[:, None, :], *self._segments))
        if len(self._arcs[0]):
            candidates.append(_project_arcs(local[:, None, :], *self._arcs))
        proj = _closest(local, candidates)
        proj.point = proj.point + shift[:, None]
        return proj

    def outline(self, t=0.0, points_per_arc=32, extent=1.0):
        """Points (2, m) along the tool at load factor ``t`` for plotting.

        Lines are drawn over ``±extent`` around their anchor point.
        """
        parts = []
        for p, tt in zip(*self._lines):
            parts.append(np.array([p - extent * tt, p + extent * tt]))
        for a, b, *_ in zip(*self._segments):
            parts.append(np.array([a, b]))
        for c, r, th, sw, *_ in zip(*self._arcs):
            ang = th + sw * np.linspace(0.0, 1.0, points_per_arc)
            parts.append(c + r * np.stack([np.cos(ang), np.sin(ang)], axis=-1))
        nan = np.full((1, 2), np.nan)
        joined = np.concatenate([q for part in parts for q in (part, nan)][:-1])
        return joined.T + self.translation(t)[:, None]

    def __repr__(self):
        return (f"{type(self).__name__}({self.name!r}: {len(self._lines[0])} lines, "
                f"{len(self._segments[0])} segments, {len(self._arcs[0])} arcs)")


class Platen(Tool):
    """A flat rigid platen: the infinite line through ``point``.

    Parameters
    ----------
    point : array_like (2,)
        A point of the platen surface.
    normal : array_like (2,)
        Normal pointing to the body (need not be unit).
    motion, name
        See :class:`Tool`.
    """

    def __init__(self, point, normal, motion=(0.0, 0.0), name="platen"):
        super().__init__(motion, name)
        p = _point(point, "platen point")
        n = _unit(normal, "platen normal")
        self._lines = (p[None], _tangent_of(n)[None])


def _fillet(p0, p1, p2, radius):
    """Tangent points and arc replacing the corner ``p1`` by a circle of
    ``radius`` on the inside of the turn.

    Returns ``(tangent_in, tangent_out, center, theta0, sweep)``; the sweep
    is the signed turning angle (positive for a left turn).
    """
    d1 = (p1 - p0) / np.linalg.norm(p1 - p0)
    d2 = (p2 - p1) / np.linalg.norm(p2 - p1)
    turn = np.arctan2(d1[0] * d2[1] - d1[1] * d2[0], d1 @ d2)
    cut = radius * np.tan(abs(turn) / 2.0)
    t_in, t_out = p1 - cut * d1, p1 + cut * d2
    center = t_in + np.sign(turn) * radius * _left(d1)
    theta0 = np.arctan2(*(t_in - center)[::-1])
    return t_in, t_out, center, theta0, turn


def _chain_normals(kinds, geometry):
    """Normals at the start and end of every feature of a chain."""
    starts, ends = [], []
    for kind, g in zip(kinds, geometry):
        if kind == "segment":
            n = _left((g[1] - g[0]) / np.linalg.norm(g[1] - g[0]))
            starts.append(n)
            ends.append(n)
        else:
            c, r, th, sw = g
            o = np.sign(sw)
            starts.append(-o * np.array([np.cos(th), np.sin(th)]))
            ends.append(-o * np.array([np.cos(th + sw), np.sin(th + sw)]))
    return np.array(starts), np.array(ends)


def _pseudo_normals(starts, ends, closed):
    """Vertex pseudo-normals: the normalized sum of the normals of the two
    features meeting at a vertex; an open end keeps its feature's normal."""
    nxt = np.roll(starts, -1, axis=0)
    joint = ends + nxt
    joint /= np.maximum(np.linalg.norm(joint, axis=1), 1e-300)[:, None]
    end_pseudo = joint.copy()
    start_pseudo = np.roll(joint, 1, axis=0)
    if not closed:
        end_pseudo[-1] = ends[-1]
        start_pseudo[0] = starts[0]
    return start_pseudo, end_pseudo


class Polyline(Tool):
    """A rigid tool made of straight segments through ``points``, corners
    optionally rounded by circular fillets (a die with a shoulder radius).

    Parameters
    ----------
    points : array_like (m, 2)
        Vertices in order; the body lies on the left of the direction of
        travel: with the body above it, a floor is traversed in +x; a die
        cavity opening upward is traversed from its left rim down, across
        its floor and up to its right rim.
    fillet : float
        Radius of the arc replacing every interior corner (0: sharp).
    closed : bool
        Join the last point to the first.
    motion, name
        See :class:`Tool`.

    Raises
    ------
    ValueError
        Fewer than two points, repeated consecutive points, a negative
        fillet, or a fillet that does not fit on the adjacent segments.
    """

    def __init__(self, points, fillet=0.0, closed=False, motion=(0.0, 0.0),
                 name="polyline"):
        super().__init__(motion, name)
        pts = _floats(points, "polyline points", "(m, 2)")
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
            raise ValueError("polyline points must have shape (m, 2) with m >= 2, "
                             f"not {pts.shape}")
        if not np.all(np.isfinite(pts)):
            raise ValueError("polyline points must be finite")
        if closed:
            pts = np.vstack([pts, pts[:1]])
        with np.errstate(over="ignore", invalid="ignore"):
            lengths = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        if not np.all(np.isfinite(lengths)):
            raise ValueError("polyline coordinates are too large: segment "
                             f"{int(np.flatnonzero(~np.isfinite(lengths))[0])} has an "
                             "infinite length; use smaller units")
        if np.any(lengths <= 1e-14 * max(np.abs(pts).max(), 1.0)):
            k = int(np.argmin(lengths))
            raise ValueError(f"polyline points {k} and {k + 1} coincide: "
                             "segments need a positive length")
        fillet = _number(fillet, "fillet radius")
        if not fillet >= 0:
            raise ValueError(f"fillet radius must be >= 0, not {fillet!r}")
        kinds, geometry = self._build_chain(pts, float(fillet), closed, lengths)
        starts, ends = _chain_normals(kinds, geometry)
        ps, pe = _pseudo_normals(starts, ends, closed)
        seg = [k for k, kind in enumerate(kinds) if kind == "segment"]
        arc = [k for k, kind in enumerate(kinds) if kind == "arc"]
        self._segments = (np.array([geometry[k][0] for k in seg]).reshape(-1, 2),
                          np.array([geometry[k][1] for k in seg]).reshape(-1, 2),
                          ps[seg].reshape(-1, 2), pe[seg].reshape(-1, 2))
        self._arcs = (np.array([geometry[k][0] for k in arc]).reshape(-1, 2),
                      np.array([geometry[k][1] for k in arc], dtype=float),
                      np.array([geometry[k][2] for k in arc], dtype=float),
                      np.array([geometry[k][3] for k in arc], dtype=float),
                      ps[arc].reshape(-1, 2), pe[arc].reshape(-1, 2))

    @staticmethod
    def _build_chain(pts, fillet, closed, lengths):
        """Segments (trimmed by the fillets) and fillet arcs in order."""
        nseg = len(pts) - 1
        cut = np.zeros((nseg, 2))  # length trimmed at the start / end of a segment
        arcs = {}  # segment index -> the fillet arc that follows it
        corners = list(range(1, nseg)) + ([nseg] if closed else [])
        for i in corners if fillet > 0 else []:
            j, k = i - 1, i % nseg
            t_in, t_out, c, th, sw = _fillet(pts[j], pts[i], pts[k + 1], fillet)
            if abs(sw) < 1e-12:  # collinear: no corner
                continue
            arcs[j] = (c, fillet, th, sw)
            cut[j, 1] = np.linalg.norm(pts[i] - t_in)
            cut[k, 0] = np.linalg.norm(t_out - pts[i])
        excess = cut.sum(axis=1) - lengths
        if np.any(excess > 1e-12 * lengths):
            k = int(np.argmax(excess))
            raise ValueError(f"fillet radius {fillet} does not fit on segment {k} "
                             f"(length {lengths[k]:.4g}); use a smaller radius")
        kinds, geometry = [], []
        for k in range(nseg):
            d = (pts[k + 1] - pts[k]) / lengths[k]
            a, b = pts[k] + cut[k, 0] * d, pts[k + 1] - cut[k, 1] * d
            if np.linalg.norm(b - a) > 1e-12 * lengths[k]:
                kinds.append("segment")
                geometry.append((a, b))
            if k in arcs:
                kinds.append("arc")
                geometry.append(arcs[k])
        return kinds, geometry


def polyline(points, fillet=0.0, closed=False, motion=(0.0, 0.0), name="polyline"):
    """A :class:`Polyline` tool (segments through ``points``, body on the left)."""
    return Polyline(points, fillet, closed, motion, name)


class Arc(Tool):
    """A rigid circular arc (a cylindrical punch, a die radius).

    Parameters
    ----------
    center : array_like (2,)
    radius : float
    angles : (float, float)
        Start and end angle in degrees.  The arc runs from start to end,
        counter-clockwise if ``end > start``; the body lies on its left:
        *inside* the circle for a counter-clockwise arc, *outside* (a convex
        punch) for a clockwise one, e.g. ``angles=(0, -180)`` is the lower
        half of a punch pressing downward on a body below it.
    motion, name
        See :class:`Tool`.
    """

    def __init__(self, center, radius, angles, motion=(0.0, 0.0), name="arc"):
        super().__init__(motion, name)
        c = _point(center, "arc center")
        radius = _number(radius, "arc radius")
        if not radius > 0:
            raise ValueError(f"arc radius must be positive, not {radius!r}")
        a = _floats(angles, "arc angles", "(2,)")
        if a.shape != (2,) or not np.all(np.isfinite(a)):
            raise ValueError(f"arc angles must be (start, end) in degrees, not {angles!r}")
        sweep = np.radians(a[1] - a[0])
        if not 0 < abs(sweep) <= _TWO_PI:
            raise ValueError("arc angles must differ by more than 0 and at most 360 "
                             f"degrees, not {a.tolist()}")
        th = np.radians(a[0])
        starts, ends = _chain_normals(["arc"], [(c, radius, th, sweep)])
        closed = np.isclose(abs(sweep), _TWO_PI)
        ps, pe = _pseudo_normals(starts, ends, closed)
        self._arcs = (c[None], np.array([float(radius)]), np.array([th]),
                      np.array([sweep]), ps, pe)


# ---------------------------------------------------------------------------
# slave points
# ---------------------------------------------------------------------------


@dataclass
class SlavePoints:
    """Slave points on the workpiece boundary and the contact nodes that
    carry the contact law.

    Attributes
    ----------
    X : ndarray (2, n)
        Reference positions of the points.
    weights : ndarray (n,)
        Boundary area of each point (``2πR`` included for axisymmetric
        models).
    G : sparse (2n, N)
        Displacements of the points, interleaved ``(u_x, u_y)`` per point,
        are ``G @ d``.
    spacing : float
        Mean length ``h_c`` of the slave boundary facets.
    hats : sparse (n, m)
        Values ``N_K(x_q)`` of the boundary hat function of contact node
        ``K`` at the points (the identity for nodal collocation).
    node_weights : ndarray (m,)
        ``W_K = Σ_q N_K(x_q) w_q = ∫_Γ N_K dΓ``.
    nodes : ndarray (m,) or None
        Mesh vertex of each contact node.
    """

    X: np.ndarray
    weights: np.ndarray
    G: object
    spacing: float
    hats: object
    node_weights: np.ndarray
    nodes: np.ndarray = None

    @property
    def n(self):
        return self.X.shape[1]

    @property
    def m(self):
        return self.node_weights.shape[0]

    @cached_property
    def weighted_hats(self):
        """``M = Nᵀ diag(w)`` (m × n): nodal integrals of point values."""
        return (self.hats.T @ sp.diags(self.weights)).tocsr()

    def displacements(self, d):
        """Displacements (2, n) of the points for coefficients ``d``."""
        return (self.G @ d).reshape(-1, 2).T

    def average(self, values):
        """Hat-weighted nodal averages ``Σ_q N_K(x_q) w_q v_q / W_K``."""
        return (self.hats.T @ (self.weights * values)) / self.node_weights


def _facets(mesh, boundaries):
    """Facet indices of boundary names (or of the whole boundary)."""
    named = mesh.boundaries or {}
    if boundaries is None:
        return np.asarray(mesh.boundary_facets())
    if isinstance(boundaries, str):
        boundaries = [boundaries]
    if isinstance(boundaries, np.ndarray) and boundaries.dtype.kind in "iu":
        return np.unique(boundaries)
    out = []
    for b in boundaries:
        if isinstance(b, str):
            if b not in named:
                raise ValueError(f"the mesh has no boundary named {b!r}; it has "
                                 f"{sorted(named)}")
            out.append(np.asarray(named[b]))
        else:
            out.append(np.atleast_1d(np.asarray(b, dtype=np.int64)))
    if not out:
        raise ValueError("no slave boundary given")
    return np.unique(np.concatenate(out))


def _facet_spacing(mesh, facets):
    """Mean reference length of the facets: the spacing ``h_c``."""
    e = mesh.p[:, mesh.facets[1, facets]] - mesh.p[:, mesh.facets[0, facets]]
    return float(np.mean(np.linalg.norm(e, axis=0)))


def _scalar_value_matrix(fb):
    """Sparse (facet quadrature points × scalar dofs) values of a FacetBasis."""
    nq = fb.X.shape[-1]
    rows = np.arange(fb.nelems * nq).reshape(fb.nelems, nq)
    data = [np.asarray(fb.basis[i][0]).ravel() for i in range(fb.Nbfun)]
    cols = [np.repeat(fb.element_dofs[i], nq) for i in range(fb.Nbfun)]
    return sp.csr_matrix((np.concatenate(data),
                          (np.tile(rows.ravel(), fb.Nbfun), np.concatenate(cols))),
                         shape=(fb.nelems * nq, fb.N))


def _boundary_quadrature(mesh, facets, intorder, axisymmetric):
    """Gauss points (2, nq) and weights (with ``2πR``) on the facets, and the
    facet hat functions there (sparse nq × nvertices)."""
    from skfem import FacetBasis

    fb = FacetBasis(mesh, type(mesh).elem(), facets=facets, intorder=intorder)
    x = np.asarray(fb.global_coordinates()).reshape(2, -1)
    w = np.asarray(fb.dx).ravel()
    if axisymmetric:
        w = _TWO_PI * x[0] * w
    return x, w, _scalar_value_matrix(fb)


def _is_rk(basis):
    return hasattr(basis, "element_nodes") and hasattr(basis, "nodal_matrix")


def _check_2d(basis, model):
    if basis.mesh.dim() != 2 or model == "3d":
        raise ValueError("contact is implemented for 2D models (plane strain, "
                         "axisymmetric) only")
    if model not in ("plane_strain", "axisymmetric"):
        raise ValueError(f"model must be 'plane_strain' or 'axisymmetric', not {model!r}")


def _vertex_dof_check(basis):
    mesh = basis.mesh
    if _is_rk(basis):
        if basis.nodes is not mesh.p and not (basis.nodes.shape == mesh.p.shape
                                              and np.allclose(basis.nodes, mesh.p)):
            raise ValueError("nodal collocation needs the particles at the mesh "
                             "vertices; use collocation='quadrature'")
    elif basis.N != 2 * mesh.nvertices:
        raise ValueError("nodal collocation needs one dof per vertex and component "
                         "(linear elements); use collocation='quadrature'")


def _interleaved(nodes):
    """Vector dofs ``2K, 2K + 1`` of nodes ``K``, point-major."""
    return (2 * np.asarray(nodes)[:, None] + np.arange(2)[None]).ravel()


def _nodal_points(basis, facets, axisymmetric):
    """Boundary particles with hat-function weights ``w_K = ∫_Γ N_K dΓ`` and
    ``G`` = the rows of ``Λᵀ`` (Eq. 3.33) of their nodal values."""
    mesh = basis.mesh
    _vertex_dof_check(basis)
    _, w, hats = _boundary_quadrature(mesh, facets, 2, axisymmetric)
    nodes = np.unique(mesh.facets[:, facets])
    weights = np.asarray(hats.T @ w).ravel()[nodes]
    G = transformation(basis)[_interleaved(nodes)]
    return SlavePoints(mesh.p[:, nodes], weights, sp.csr_matrix(G),
                       _facet_spacing(mesh, facets), sp.identity(len(nodes), format="csr"),
                       weights, nodes)


def _quadrature_points(basis, facets, axisymmetric, intorder, pointwise=False):
    """Gauss points of the boundary facets, with ``G`` built from the shape
    functions there: ``Ψ_I(x_q)`` (RK) or the element's facet values (FEM);
    the contact nodes are the boundary vertices with their hat functions
    (or, ``pointwise``, every Gauss point is its own contact node)."""
    from skfem import FacetBasis

    mesh = basis.mesh
    if intorder is None:
        intorder = getattr(basis, "intorder", None) or 2 * basis.elem.maxdeg
    x, w, hats = _boundary_quadrature(mesh, facets, intorder, axisymmetric)
    if _is_rk(basis):
        S = basis._shape_table(x, gradients=False).matrix()
    else:
        scalar = basis.elem.elem if hasattr(basis.elem, "elem") else basis.elem
        S = _scalar_value_matrix(FacetBasis(mesh, scalar, facets=facets,
                                            intorder=intorder))
    G = sp.kron(S, sp.identity(2), format="csr")
    spacing = _facet_spacing(mesh, facets)
    if pointwise:
        return SlavePoints(x, w, G, spacing, sp.identity(len(w), format="csr"), w)
    hats, nodes = _split_at_corners(mesh, facets, hats)
    return SlavePoints(x, w, G, spacing, hats, np.asarray(hats.T @ w).ravel(), nodes)


#: facets meeting at more than this angle make a corner of the slave surface
CORNER_ANGLE = 30.0


def _corner_vertices(mesh, fv):
    """Vertices where exactly two slave facets meet at more than
    :data:`CORNER_ANGLE` degrees, and the second of the two facets (index
    into the slave facets), given the facet vertices ``fv`` (2, nf)."""
    d = mesh.p[:, fv[1]] - mesh.p[:, fv[0]]
    d /= np.linalg.norm(d, axis=0)
    verts = fv.T.ravel()
    order = np.argsort(verts, kind="stable")
    facet = order // 2
    vertex, start, count = np.unique(verts[order], return_index=True, return_counts=True)
    two = count == 2
    a, b = facet[start[two]], facet[start[two] + 1]
    sharp = np.abs(d[0, a] * d[1, b] - d[1, a] * d[0, b]) > np.sin(np.radians(CORNER_ANGLE))
    return vertex[two][sharp], b[sharp]


def _split_at_corners(mesh, facets, hats):
    """Contact nodes: one per slave vertex, two at a corner of the slave
    surface (one per side, each with its half of the hat function), so
    that a weighted gap never mixes the two faces of a corner.

    Returns the hat values at the Gauss points (sparse nq × m; the rows of
    ``hats`` are facet-major) and the vertex of every contact node."""
    fv = mesh.facets[:, facets]
    nodes = np.unique(fv)
    corners, second = _corner_vertices(mesh, fv)
    coo = sp.coo_matrix(hats)
    keep = np.isin(coo.col, nodes) & (coo.data != 0)
    row, col, data = coo.row[keep], coo.col[keep], coo.data[keep]
    facet = row // (hats.shape[0] // len(facets))
    k = np.minimum(np.searchsorted(corners, col), len(corners) - 1)
    split = (np.isin(col, corners) & (second[k] == facet) if len(corners)
             else np.zeros(len(col), bool))
    column = np.where(split, len(nodes) + k, np.searchsorted(nodes, col))
    out = sp.csr_matrix((data, (row, column)), shape=(hats.shape[0], len(nodes) + len(corners)))
    return out, np.concatenate([nodes, corners])


def slave_points(basis, boundaries=None, collocation="nodal", model="plane_strain",
                 intorder=None):
    """The slave points of the named boundaries of a basis.

    Parameters
    ----------
    basis : RKBasis or skfem vector basis
    boundaries : str, sequence of str, facet indices, or None
        Named boundaries (``mesh.boundaries``), facet indices, or the whole
        boundary.
    collocation : {"nodal", "quadrature", "gauss"}
        ``"nodal"``: the boundary particles (Eq. 4.26-4.29).
        ``"quadrature"``: the boundary Gauss points, with the contact law
        applied at the boundary particles to hat-weighted averages of the
        Gauss point gaps and slips.  ``"gauss"``: the contact law at every
        Gauss point (over-constrains the boundary; kept for comparison).
    model : {"plane_strain", "axisymmetric"}
        Axisymmetric weights include ``2πR`` (forces for the full ring).
    intorder : int, optional
        Facet quadrature degree (``"quadrature"``); default that of the RK
        basis (so that a uniform traction is integrated like the VCI
        boundary terms) or twice the FEM element degree.

    Returns
    -------
    SlavePoints
    """
    _check_2d(basis, model)
    facets = _facets(basis.mesh, boundaries)
    if len(facets) == 0:
        raise ValueError("the slave boundary has no facets")
    axisymmetric = model == "axisymmetric"
    if collocation == "nodal":
        return _nodal_points(basis, facets, axisymmetric)
    if collocation in ("quadrature", "gauss"):
        return _quadrature_points(basis, facets, axisymmetric, intorder,
                                  pointwise=collocation == "gauss")
    raise ValueError("collocation must be 'nodal', 'quadrature' or 'gauss', "
                     f"not {collocation!r}")


# ---------------------------------------------------------------------------
# penalty Coulomb friction
# ---------------------------------------------------------------------------


def default_penalty(E, spacing, factor=DEFAULT_PENALTY_FACTOR):
    """Penalty ``ω = factor · E / h_c`` per unit boundary area (Eq. 4.5).

    Independent of the mesh in the sense that the penetration under a given
    pressure, ``g = p / ω``, is a fixed fraction ``p / (factor E)`` of the
    particle spacing ``h_c``.
    """
    if not (np.isfinite(E) and E > 0):
        raise ValueError(f"Young's modulus must be positive, not {E!r}")
    if not (np.isfinite(factor) and factor > 0):
        raise ValueError(f"penalty factor must be positive, not {factor!r}")
    return factor * E / spacing


#: the Coulomb coefficient that models ``friction = "stick"``
STICK_FRICTION = 10.0


def friction_coefficient(friction):
    """``μ`` of ``friction``: a number ``≥ 0``, or ``"stick"``.

    Sticking means no slip wherever the tool presses, the limit ``μ → ∞``
    of Eq. (4.6).  The limit itself is discontinuous where a node leaves
    the tool: its shear drops from the sticking value to zero while its
    pressure is already zero.  At a corner that folds onto the tool the
    penalty problem then has no solution (the node is pushed back in by
    the shear it loses when it separates) and Newton's method cycles
    between the two states.  ``"stick"`` is therefore the Coulomb law with
    ``μ = STICK_FRICTION`` (10): the shear a node can hold vanishes with
    its pressure.  Measured on the paper's stick ring (100 steps to 50 %
    height reduction): 99 % of the pressed nodes carry ``|t_t| ≤ 1.1 t_n``;
    at most one node slips in any step, at the edge of the contact, with a
    pressure below 0.6 % (RKPM) / 4.8 % (FEM Q1) of the largest; the inner
    radius at mid-height differs by 3e-5 (relative) between μ = 10, 100 and
    1000, and both runs reach 50 % (the limit law stops them near 49 %).
    """
    if isinstance(friction, str):
        if friction == "stick":
            return STICK_FRICTION
        raise ValueError(f'friction must be a number >= 0 or "stick", not {friction!r}')
    mu = float(friction)
    if not (np.isfinite(mu) and mu >= 0):
        raise ValueError(f'friction must be a number >= 0 or "stick", not {friction!r}')
    return mu


def coulomb(pressure, trial, mu):
    """Return map of the penalized Coulomb law (Eq. 4.6).

    Parameters
    ----------
    pressure : ndarray
        Normal traction ``t_n ≥ 0``.
    trial : ndarray
        Trial tangential traction ``t_t,n - ω_t Δg_t``.
    mu : float
        Friction coefficient (0: frictionless).

    Returns
    -------
    shear : ndarray
        Tangential traction: the trial value in stick, ``μ t_n sgn(trial)``
        in slip.
    slip : ndarray of bool
    """
    if mu == 0.0:
        return np.zeros_like(trial), pressure > 0
    slip = np.abs(trial) > mu * pressure
    return np.where(slip, mu * pressure * np.sign(trial), trial), slip


@dataclass
class ContactState:
    """Contact data at one evaluation.

    Per slave point: ``x`` (2, n) current positions, ``gap`` (n,) normal
    gaps ``g_n``, ``normal``/``tangent`` (2, n) master frame at the closest
    points, ``relative`` (2, n) positions relative to the tool,
    ``x - x_tool(t)`` (for the slip of Eq. 4.11).  Per contact node:
    ``pressure`` ``t_n``, ``shear`` ``t_t`` (along the tangent), ``slip``
    and ``active`` (bool), and ``node_gap`` (the nodal gap, or the
    hat-weighted average of the point gaps).  ``force`` (2,) is the force of
    the master surface on the body.
    """

    x: np.ndarray
    gap: np.ndarray
    normal: np.ndarray
    tangent: np.ndarray
    relative: np.ndarray
    node_gap: np.ndarray
    pressure: np.ndarray
    shear: np.ndarray
    slip: np.ndarray
    active: np.ndarray
    force: np.ndarray

    @property
    def penetration(self):
        """Largest penetration ``max(-g_n, 0)`` over the slave points."""
        return float(max(0.0, -self.gap.min(initial=0.0)))


def _outer(a, b):
    return np.einsum("ni,nj->nij", a, b)


def _block_diagonal(blocks):
    """Sparse block-diagonal matrix of (n, m, m) blocks."""
    n, m, _ = blocks.shape
    base = m * np.arange(n)
    rows = np.broadcast_to(base[:, None, None] + np.arange(m)[None, :, None], blocks.shape)
    cols = np.broadcast_to(base[:, None, None] + np.arange(m)[None, None, :], blocks.shape)
    return sp.csr_matrix((blocks.ravel(), (rows.ravel(), cols.ravel())),
                         shape=(n * m, n * m))


def _directional(G, vectors):
    """Rows ``v_qᵀ G_q`` (sparse n × N): the derivative of ``v_q · u(x_q)``."""
    n = vectors.shape[1]
    P = sp.csr_matrix((vectors.T.ravel(), (np.repeat(np.arange(n), 2), np.arange(2 * n))),
                      shape=(n, 2 * n))
    return (P @ G).tocsr()


def _curvature_blocks(proj, pressure, shear):
    """Per point ``∂(-(p n + s t))/∂x`` at fixed tractions ``p, s``:
    ``-p κ t tᵀ + s κ n tᵀ`` (``∂n/∂x = κ t tᵀ``, ``∂t/∂x = -κ n tᵀ``)."""
    n, t, kappa = proj.normal.T, proj.tangent.T, proj.curvature
    return ((-pressure * kappa)[:, None, None] * _outer(t, t)
            + (shear * kappa)[:, None, None] * _outer(n, t))


def _rigid_tangent(pts, proj, Bn, slipped, law, omega_n, omega_t, mu):
    """Consistent tangent of the rigid-tool contact force (Eq. 4.28-4.29).

    With ``B_n``, ``B_t`` the rows ``n_qᵀ G_q``, ``t_qᵀ G_q`` of the slave
    points, ``M = Nᵀ w`` (hat functions times point weights; the diagonal
    of the weights for nodal collocation) and ``W`` the node weights, the
    nodal gap ``ĝ = W⁻¹ M g`` has the derivative ``W⁻¹ M B_n`` and

        K = ω_n B_nᵀ Mᵀ H W⁻¹ M B_n                        (normal, symmetric)
          + ω_t B_tᵀ Mᵀ S φ W⁻¹ M a B_t                    (stick)
          + ω_t B_tᵀ Mᵀ S Δĝ_t φ' W⁻¹ M B_n                (stick, touching)
          + μ ω_n B_tᵀ Mᵀ sgn(t_t) Σ W⁻¹ M B_n             (slip, non-symmetric)
          + Gᵀ w (-p κ t tᵀ + s κ n tᵀ) G                  (curved masters)

    ``H``, ``S``, ``Σ`` select the nodes in contact, sticking and slipping,
    ``a_q = 1 - κ_q (Δξ_q·n_q)`` comes from the rotation of ``t`` and
    ``φ(ĝ)`` is the part of the step spent in contact (:meth:`RigidContact._law`).
    """
    pressure, shear, slip, active, slip_t, phi, dphi = law
    G, w = pts.G, pts.weights
    M = pts.weighted_hats
    inv_W = 1.0 / pts.node_weights
    K = omega_n * (Bn.T @ M.T @ sp.diags(active * inv_W) @ M @ Bn)
    if mu > 0:
        a = 1.0 - proj.curvature * np.einsum("ni,ni->n", slipped, proj.normal.T)
        Bt = _directional(G, proj.tangent)
        stick = omega_t * (active & ~slip) * inv_W
        K = K + Bt.T @ M.T @ (sp.diags(stick * phi) @ M @ sp.diags(a) @ Bt
                              + sp.diags(stick * slip_t * dphi) @ M @ Bn)
        sliding = mu * omega_n * np.sign(shear) * (slip & active) * inv_W
        K = K + Bt.T @ M.T @ sp.diags(sliding) @ M @ Bn
    p, s = pts.hats @ pressure, pts.hats @ shear
    blocks = w[:, None, None] * _curvature_blocks(proj, p, s)
    return (K + G.T @ _block_diagonal(blocks) @ G).tocsr()


def _touch_fraction(gap, previous_gap, was_active):
    """Part ``φ`` of the step that a node spends in contact, by linear
    interpolation of its gap from the last converged step, and ``dφ/dĝ``.

    ``φ = 1`` for nodes already in contact; for a node that touches during
    the step ``φ = -ĝ / (ĝ_0 - ĝ)``, so that its slip is counted from the
    moment it touches and its tangential traction starts from zero."""
    g0 = np.where(was_active, 0.0, np.maximum(previous_gap, 0.0))
    depth = np.maximum(-gap, 0.0)
    span = g0 + depth
    safe = np.where(span > 0, span, 1.0)
    phi = np.where(span > 0, depth / safe, 1.0)
    dphi = np.where((span > 0) & (gap < 0), -g0 / safe**2, 0.0)
    return phi, dphi


def _warn_if_out_of_reach(tool, X, samples=21):
    """Warn if ``tool`` stays clear of the reference points ``X`` at every
    load factor of ``[0, 1]`` (sampled): a misplaced tool or a motion in the
    wrong direction.  Only a warning: loads may still deform the part onto it."""
    import warnings

    gaps = [tool.project(X, t).gap.min() for t in np.linspace(0.0, 1.0, samples)]
    k = int(np.argmin(gaps))
    if gaps[k] > 0:
        warnings.warn(f"tool {tool.name!r} does not reach the part during its motion: the "
                      f"smallest gap to the undeformed slave boundary is {gaps[k]:.4g} "
                      f"(at t = {k / (samples - 1):g}); unless other loads deform the part "
                      "onto it, it carries no force; check its position and motion",
                      stacklevel=3)


def _check_finite_traction(traction, X, name):
    """NonFiniteError naming the first slave point with a NaN or inf traction."""
    finite = np.isfinite(traction).all(axis=0)
    if not finite.all():
        bad = np.flatnonzero(~finite)
        raise NonFiniteError(
            f"the contact traction of tool {name!r} is not finite at {bad.size} slave "
            f"points; first at X = ({X[0, bad[0]]:.4g}, {X[1, bad[0]]:.4g})", bad)


class RigidContact:
    """Penalty frictional contact of a body with a rigid moving tool
    (Sec. 4.3, Eq. 4.25-4.29), a contribution for
    :func:`skfem_rkpm.solvers.newton.newton_steps`.

    The contact law (Eq. 4.5-4.6) acts at the boundary particles.  With
    ``collocation="nodal"`` it sees the gap and slip of the particle itself
    (the paper).  With ``"quadrature"`` it sees their averages over the
    boundary Gauss points, weighted by the particle's boundary hat function
    ``N_K``, and its tractions are interpolated back with the hat
    functions and integrated at the Gauss points,
    ``f_I = Σ_q w_q Ψ_I(x_q) t(x_q)``: a uniform traction is then
    integrated exactly (homogeneous states stay exact for RK bases), with
    one contact law per particle, as in the nodal case.

    Parameters
    ----------
    problem : SolidProblem
        Supplies the basis, the model and Young's modulus.
    tool : Tool
    slaves : str, sequence of str, facet indices, or None
        Boundaries whose points may touch the tool (default: all).
    friction : float or "stick"
        Coulomb coefficient ``μ`` (0: frictionless) or ``"stick"`` (:func:`friction_coefficient`).
    collocation : {"nodal", "quadrature", "gauss"}
        See :func:`slave_points`.
    penalty : float, optional
        Normal penalty ``ω_n`` per unit area; default
        ``factor · E / h_c`` (:func:`default_penalty`).
    tangential_penalty : float, optional
        ``ω_t`` per unit area; default ``tangential_factor · E / h_c``.
    factor, tangential_factor : float
        Factors of the default penalties.
    intorder : int, optional
        Facet quadrature degree for ``collocation="quadrature"``.
    """

    def __init__(self, problem, tool, slaves=None, friction=0.0, collocation="nodal",
                 penalty=None, tangential_penalty=None, factor=DEFAULT_PENALTY_FACTOR,
                 tangential_factor=DEFAULT_TANGENTIAL_FACTOR, intorder=None):
        if not isinstance(tool, Tool):
            raise TypeError(f"tool must be a Tool (Platen, Polyline, Arc), not {tool!r}")
        self.problem, self.tool, self.name = problem, tool, tool.name
        self.mu = friction_coefficient(friction)
        self.collocation = collocation
        self.points = slave_points(problem.basis, slaves, collocation, problem.model,
                                   intorder)
        self.omega_n = (default_penalty(problem.material.E, self.points.spacing, factor)
                        if penalty is None else _positive(penalty, "penalty"))
        self.omega_t = (default_penalty(problem.material.E, self.points.spacing,
                                        tangential_factor)
                        if tangential_penalty is None
                        else _positive(tangential_penalty, "tangential penalty"))
        self.state = self.trial = self._initial_state()
        _warn_if_out_of_reach(tool, self.points.X)

    def _initial_state(self):
        X, m = self.points.X, self.points.m
        proj = self.tool.project(X, 0.0)
        relative = X - self.tool.translation(0.0)[:, None]
        return ContactState(X.copy(), proj.gap, proj.normal, proj.tangent, relative,
                            self.points.average(proj.gap), np.zeros(m), np.zeros(m),
                            np.zeros(m, bool), np.zeros(m, bool), np.zeros(2))

    def _law(self, proj, slipped):
        """Nodal tractions (Eq. 4.5-4.6, 4.11) from the nodal gap ``ĝ`` and
        slip ``Δĝ_t`` (the particle's own, or hat-weighted averages of the
        Gauss point values ``g_n`` and ``Δg_t = Δξ·t``):
        ``t_n = ω_n ⟨-ĝ⟩``, the trial ``t_t,n - ω_t φ Δĝ_t`` with the part
        ``φ`` of the step spent in contact, and Coulomb's return map."""
        pts, state = self.points, self.state
        node_gap = pts.average(proj.gap)
        active = node_gap <= 0.0
        pressure = self.omega_n * np.maximum(-node_gap, 0.0)
        slip_t = pts.average(np.einsum("ni,ni->n", slipped, proj.tangent.T))
        phi, dphi = _touch_fraction(node_gap, state.node_gap, state.active)
        shear, slip = coulomb(pressure, state.shear - self.omega_t * phi * slip_t, self.mu)
        law = (pressure, np.where(active, shear, 0.0), slip & active, active, slip_t, phi,
               dphi)
        return node_gap, law

    def evaluate(self, d, t):
        """Contact force (added to the internal force) and its tangent at
        coefficients ``d`` and load factor ``t``."""
        pts = self.points
        x = pts.X + pts.displacements(d)
        proj = self.tool.project(x, t)
        relative = x - self.tool.translation(t)[:, None]
        slipped = (relative - self.state.relative).T
        node_gap, law = self._law(proj, slipped)
        pressure, shear = law[0], law[1]
        traction = (pts.hats @ pressure) * proj.normal + (pts.hats @ shear) * proj.tangent
        _check_finite_traction(traction, pts.X, self.name)
        f = pts.G.T @ (-(pts.weights * traction)).T.ravel()
        Bn = _directional(pts.G, proj.normal)
        K = _rigid_tangent(pts, proj, Bn, slipped, law, self.omega_n, self.omega_t, self.mu)
        self._normal_rows = Bn  # for touching(): the linearized gaps
        self.trial = ContactState(x, proj.gap, proj.normal, proj.tangent, relative,
                                  node_gap, pressure, shear, law[2], law[3],
                                  (pts.weights * traction).sum(axis=1))
        return f, K

    def touching(self, delta):
        """Penalty force and stiffness of the contact nodes that the update
        ``delta`` would bring into contact, in the linear model of the last
        evaluation.

        A node that is apart at the last evaluation has no stiffness in
        the tangent, so a Newton update may push it deep into the tool (a
        die node under a punch stroke).  Its linearized gap after the
        update is ``ĝ + Ĝ δ`` with ``Ĝ = W⁻¹ M B_n``; if that is negative,
        the normal law of Eq. (4.5) acts in the linear model as the force
        ``ω_n Ĝᵀ W ĝ`` plus the stiffness ``ω_n Ĝᵀ W Ĝ``, which
        :func:`skfem_rkpm.solvers.newton.newton_steps` adds before it solves again
        (an active-set iteration).  Returns ``(nodes, f, K)`` (``nodes`` a
        boolean mask of the touching nodes) or ``None`` if no node is
        predicted to touch.
        """
        apart = ~self.trial.active
        if not apart.any():
            return None
        pts = self.points
        rows = (pts.weighted_hats @ self._normal_rows) / pts.node_weights[:, None]
        predicted = self.trial.node_gap + rows @ delta
        touching = apart & (predicted < 0.0)
        if not touching.any():
            return None
        scale = self.omega_n * pts.node_weights * touching
        f = rows.T @ (scale * self.trial.node_gap)
        K = rows.T @ sp.diags(scale) @ rows
        return touching, f, K.tocsr()

    def commit(self):
        """Accept the last evaluation as the converged state (Eq. 4.11)."""
        self.state = self.trial

    def resultants(self):
        """``{tool name: (Fx, Fy)}``, the force of the tool on the body."""
        return {self.name: self.state.force.copy()}

    def penetration(self):
        """Largest penetration ``max(-g_n, 0)`` at the last evaluation."""
        return self.trial.penetration

    def gauges(self, t):
        """Tool position and penetration, for output tables."""
        dx = self.tool.translation(t)
        return {f"{self.name} dx": float(dx[0]), f"{self.name} dy": float(dx[1]),
                f"{self.name} penetration": self.penetration()}

    def get_state(self):
        """The committed state (for checkpoints)."""
        return self.state

    def set_state(self, state):
        """Restore a state returned by :meth:`get_state`."""
        if state.gap.shape != (self.points.n,) or state.shear.shape != (self.points.m,):
            raise ValueError("the state belongs to a contact with different slave points")
        self.state = self.trial = state


def _positive(value, what):
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{what} must be positive, not {value!r}")
    return value


# ---------------------------------------------------------------------------
# two deformable bodies: node-to-segment contact, Eq. (4.13)-(4.19)
# ---------------------------------------------------------------------------


def _oriented_segments(mesh, facets):
    """Master facets as node pairs ``(M1, M2)`` ordered so that ``e_3 × t``
    points out of the master body (away from the adjacent cell)."""
    seg = mesh.facets[:, facets].T.copy()
    cells = mesh.f2t[0, facets]
    centroid = mesh.p[:, mesh.t[:, cells]].mean(axis=1).T
    a, b = mesh.p[:, seg[:, 0]].T, mesh.p[:, seg[:, 1]].T
    flip = np.einsum("nk,nk->n", _left(b - a), 0.5 * (a + b) - centroid) < 0
    seg[flip] = seg[flip][:, ::-1]
    return seg


def _closest_segments(xs, a, b):
    """Per slave point (n, 2) the closest segment ``a → b`` (m, 2): index,
    natural coordinate ``α`` (Eq. 4.8, unclamped), gap (Eq. 4.10), length,
    tangent and normal (Eq. 4.7)."""
    e = b - a
    length = np.linalg.norm(e, axis=1)
    t = e / length[:, None]
    alpha = np.einsum("nmk,mk->nm", xs[:, None, :] - a[None], t) / length[None]
    cp = a[None] + np.clip(alpha, 0.0, 1.0)[..., None] * e[None]
    k = np.argmin(np.linalg.norm(xs[:, None, :] - cp, axis=-1), axis=1)
    rows = np.arange(xs.shape[0])
    n = _left(t)[k]
    gap = np.einsum("nk,nk->n", xs - a[k], n)
    return k, alpha[rows, k], gap, length[k], t[k], n


def _composite_vectors(alpha, t, n):
    """``C_n``, ``T``, ``P`` of Eq. (4.16), (4.23), (4.21), each (n, 6)
    in the order of Eq. (4.14): slave, M1, M2."""
    a = alpha[:, None]
    zero = np.zeros_like(n)
    Cn = np.hstack([n, -(1 - a) * n, -a * n])
    T = np.hstack([t, -(1 - a) * t, -a * t])
    P = np.hstack([zero, -n, n])
    return Cn, T, P


def _node_to_segment_tangent(Cn, T, P, gap, length, omega):
    """Frictionless part of Eq. (4.19):
    ``ω C_n C_nᵀ + (λ_n / l)(P Tᵀ + T Pᵀ + (g_n / l) P Pᵀ)``, ``λ_n = -ω g_n``."""
    lam = -omega * gap
    return (omega * _outer(Cn, Cn)
            + (lam / length)[:, None, None]
            * (_outer(P, T) + _outer(T, P) + (gap / length)[:, None, None] * _outer(P, P)))


def _scatter_composite(dofs, f_hat, K_hat, N):
    """Nodal force vector and stiffness (N, N) from the composite vectors
    (n, 6) and matrices (n, 6, 6) of Eq. (4.14)-(4.19) on nodal ``dofs``."""
    f = np.bincount(dofs.ravel(), weights=f_hat.ravel(), minlength=N)
    rows = np.repeat(dofs, dofs.shape[1], axis=1).ravel()
    cols = np.tile(dofs, (1, dofs.shape[1])).ravel()
    return f, sp.csr_matrix((K_hat.ravel(), (rows, cols)), shape=(N, N))


class NodeToSegmentContact:
    """Frictionless penalty contact between two deformable bodies of one
    basis (Eq. 4.13-4.19): the slave particles of one boundary against the
    segments between the current positions of the master boundary particles.

    For RK bases the shape functions of one body must not reach into the
    other (supports do not see the mesh): keep the bodies apart in the
    reference configuration by more than the support radius.

    Parameters
    ----------
    problem : SolidProblem
    slave, master : str, sequence of str or facet indices
        The two boundaries.
    penalty : float, optional
        ``ω_n`` per unit area; default :func:`default_penalty`.
    factor : float
        Penalty factor of the default.
    extension : float
        A slave particle whose projection falls at most this fraction of a
        segment length beyond the segment's ends (``-e ≤ α ≤ 1 + e``) is
        still in contact with it: the corner particles of a slave surface
        then do not chatter in and out of contact at the end of the master
        surface or at a convex master vertex.
    name : str
        Key of the force in :meth:`resultants`.

    Notes
    -----
    A slave particle is in contact when its gap (Eq. 4.10) on the closest
    master segment is negative and its natural coordinate (Eq. 4.8) lies in
    ``[-e, 1 + e]``.
    """

    def __init__(self, problem, slave, master, penalty=None,
                 factor=DEFAULT_PENALTY_FACTOR, extension=0.1, name="contact"):
        basis = problem.basis
        if not (np.isfinite(extension) and 0 <= extension < 0.5):
            raise ValueError(f"extension must lie in [0, 0.5), not {extension!r}")
        self.extension = float(extension)
        _check_2d(basis, problem.model)
        self.problem, self.name = problem, name
        mesh = basis.mesh
        self.slaves = _nodal_points(basis, _facets(mesh, slave),
                                    problem.model == "axisymmetric")
        self.segments = _oriented_segments(mesh, _facets(mesh, master))
        if np.intersect1d(self.slaves.nodes, self.segments).size:
            raise ValueError("slave and master boundaries share particles")
        self.omega = (default_penalty(problem.material.E, self.slaves.spacing, factor)
                      if penalty is None else _positive(penalty, "penalty"))
        self.Lt = sp.csr_matrix(transformation(basis))
        self.state = self.trial = None

    def _positions(self, d):
        """Current nodal positions ``X + û`` (2, nnodes), ``û = Λᵀ d``."""
        mesh = self.problem.basis.mesh
        return mesh.p + (self.Lt @ d).reshape(-1, 2).T

    def evaluate(self, d, t):
        """Contact force and tangent at coefficients ``d`` (``t`` unused)."""
        x = self._positions(d)
        s = self.slaves.nodes
        m1, m2 = self.segments[:, 0], self.segments[:, 1]
        k, alpha, gap, length, tan, nrm = _closest_segments(x[:, s].T, x[:, m1].T,
                                                            x[:, m2].T)
        reach = self.extension
        active = (gap <= 0) & (alpha >= -reach) & (alpha <= 1 + reach)
        Cn, T, P = _composite_vectors(alpha, tan, nrm)
        w = self.slaves.weights * active
        lam = self.omega * np.maximum(-gap, 0.0)
        f_hat = -(w * lam)[:, None] * Cn  # Eq. (4.15): f̂ = λ_n C_n, as internal force
        K_hat = w[:, None, None] * _node_to_segment_tangent(Cn, T, P, gap, length,
                                                             self.omega)
        dofs = np.hstack([_interleaved(nodes).reshape(-1, 2) for nodes in (s, m1[k], m2[k])])
        fn, Kn = _scatter_composite(dofs, f_hat, K_hat, self.Lt.shape[0])
        gap = np.where(active, gap, np.inf)  # no contact beyond the master ends
        self.trial = ContactState(x[:, s], gap, nrm.T, tan.T, x[:, s], gap, lam * active,
                                  np.zeros_like(gap), np.zeros(len(s), bool), active,
                                  ((w * lam)[:, None] * nrm).sum(axis=0))
        return self.Lt.T @ fn, (self.Lt.T @ Kn @ self.Lt).tocsr()

    def commit(self):
        """Accept the last evaluation (frictionless: no history)."""
        self.state = self.trial

    def resultants(self):
        """``{name: (Fx, Fy)}``, the force of the master body on the slave body."""
        return {self.name: (np.zeros(2) if self.state is None else self.state.force.copy())}

    def penetration(self):
        """Largest penetration of a slave particle at the last evaluation."""
        return 0.0 if self.trial is None else self.trial.penetration


# ---------------------------------------------------------------------------
# scene files
# ---------------------------------------------------------------------------


def from_scene(name, section, basis, problem, scene=None):
    """A :class:`RigidContact` from a ``[tools.NAME]`` section of a scene.

    ``kind`` is ``"platen"`` (``point``, ``normal``), ``"polyline"``
    (``points``, ``fillet``) or ``"arc"`` (``center``, ``radius``,
    ``angles`` in degrees); ``motion``, ``friction``, ``slaves``,
    ``penalty`` and ``collocation`` as in :class:`RigidContact`.
    """
    kind = section.get("kind", "platen")
    motion = section.get("motion") or (0.0, 0.0)
    if kind == "platen":
        tool = Platen(section["point"], section["normal"], motion, name)
    elif kind == "polyline":
        tool = Polyline(section["points"], section.get("fillet") or 0.0, motion=motion,
                        name=name)
    elif kind == "arc":
        tool = Arc(section["center"], section["radius"], section["angles"], motion, name)
    else:
        raise ValueError(f"tools.{name}.kind must be platen, polyline or arc, not {kind!r}")
    if problem.basis is not basis:
        raise ValueError("the basis must be the problem's basis")
    return RigidContact(problem, tool, section.get("slaves"),
                        section.get("friction", 0.0),
                        section.get("collocation") or "nodal", section.get("penalty"))
