"""Rigid tool geometry: platens, polylines with fillets, circular arcs.

A master surface is traversed in a direction; the body it touches lies on
the *left* of that direction, and the outward normal of the master surface
is ``n = e_3 × t`` (Eq. 4.7), pointing toward the body.  Every tool moves
rigidly with the load factor (``motion``) and projects points onto itself:
closest point ``x_C``, normal, tangent, signed gap ``g_n = (x - x_C)·n``
(Eq. 4.1, 4.7-4.10) and curvature (:class:`Projection`).
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["Projection", "Tool", "Platen", "Polyline", "polyline", "Arc"]

_TWO_PI = 2.0 * np.pi



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
