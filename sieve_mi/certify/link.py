"""The link test of the slab-section proof: a ring cannot straddle a web of the sheet.

A hex nut stood on its side across a web narrower than its bore has a slab section of two bars,
one in each of two neighbouring holes, and no section test can exclude it: the section does fit.
What keeps the nut out is topology (docs/certify.md, "The link test"):

* Let gamma be a closed polygon in the interior of B (a *loop*; around a through-hole it is
  useful), and lambda_i a closed curve in the plate's material around one copy C_i of the hole
  (in the mid-plane, just outside C_i). While B moves without entering the material, gamma and
  lambda_i never meet, so their linking number never changes; it is 0 while B is wholly above
  the plate. It equals the algebraic number of crossings of gamma through the mid-plane inside
  lambda_i, and gamma can cross the mid-plane only in the holes (its points are interior points
  of B). So in every reachable pose gamma crosses the mid-plane as often up as down in each copy.
* Over a cell of directions n, a loop vertex v (less the pin) is *surely above* the plane through
  the pin if n_c . v exceeds 2 sin(alpha / 2) |v| (and margins), *surely below* likewise. When
  the surely-signed vertices change sign exactly twice around the loop and every other vertex
  lies on one of the two *stretches* (from the last vertex of one sign to the first of the
  other), every crossing lies on a stretch's segment, stretch 1
  crossing down once net and stretch 2 up once net (a segment between two vertices of one sign
  does not cross). If each stretch's vertices are band points stepping by less than the
  chain test's g (the least gap between two copies' hulls), each stretch with its crossings lies
  in one copy's hull (a crossing lies on a segment between two of its vertices); were the two
  copies different, gamma would cross the first copy once net. So both stretches lie in one copy.
* The chain test (:mod:`~sieve_mi.certify.chain`) then runs over the band points with both
  stretches joined: a chain from one end of the section to the other through them, ends further
  apart than one copy's diameter, excludes the cell.

:func:`find_loops` looks for loops: the regular polygon about the shape's centre, in a plane
through it normal to a coordinate or principal axis, furthest inside the mesh, whose flat disc
leaves the shape at its centre (a through-hole; elsewhere a loop joins only what the material
joins); then its copies at other radii and shifted along that axis that are inside too (exact
distances and winding numbers, :mod:`sieve_mi.geometry.solid`). Their vertices are points of
the shape like any other: those in the band step across the section's inside, where a mesh has
few vertices. The replay (:mod:`sieve_mi.certify.replay_section`) re-checks the loops and every
link with its own code.
"""

from __future__ import annotations

import math

import numpy as np

from sieve_mi.geometry.meshes import Shape

__all__ = ["LOOP_RADII", "LOOP_SPACING", "LOOP_STEP", "Link", "find_loops", "inside_clearance"]

#: Radii tried for a loop, as fractions of the shape's radius.
LOOP_RADII = np.linspace(0.1, 0.95, 18)
#: The loop's vertices are at most this fraction of the shape's radius apart.
LOOP_SPACING = 0.06
#: Loops at other radii and shifted along the axis are this fraction of the radius apart.
LOOP_STEP = 0.08
#: Relative margin on every bound (as the section search's).
MARGIN = 1e-9


def _frame(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    h = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(h, a)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(a, e1)


def inside_clearance(loop: np.ndarray, tri: np.ndarray, samples: int = 2) -> float:
    """The least distance to the mesh ``tri`` (F, 3, 3) of points sampled on the closed polygon
    ``loop`` (m, 3), less half the sample spacing (each point of an edge is within that of a
    sample, so the loop never meets the surface), scene units; -inf where its first vertex is
    outside (winding number below 1/2). Positive: the whole polygon lies in the mesh's interior
    (it is connected, and on the side of its first vertex)."""
    return float(_rooms([loop], tri, samples)[0])


def _rooms(loops: list, tri: np.ndarray, samples: int = 2) -> np.ndarray:
    """:func:`inside_clearance` of each loop, (n,), all loops at once."""
    from sieve_mi.geometry.solid import triangle_distance, winding_numbers

    out = np.full(len(loops), -np.inf)
    if not loops:
        return out
    first = winding_numbers(np.array([q[0] for q in loops]), tri)
    keep = [k for k in range(len(loops)) if first[k] >= 0.5]
    if not keep:
        return out
    s = np.arange(samples)[:, None, None] / samples
    pts, half = [], []
    for k in keep:
        a, b = loops[k], np.roll(loops[k], -1, axis=0)
        pts.append((a[None] + s * (b - a)[None]).reshape(-1, 3))
        half.append(0.5 * float(np.linalg.norm(b - a, axis=1).max()) / samples)
    ends = np.cumsum([len(p) for p in pts])[:-1]
    near = np.split(triangle_distance(np.concatenate(pts), tri).min(axis=1), ends)
    for k, d, h in zip(keep, near, half):
        out[k] = float(d.min()) - h * (1 + MARGIN)
    return out


def _ring(centre, e1, e2, rho: float, spacing: float) -> np.ndarray:
    m = max(12, math.ceil(2 * math.pi * rho / spacing))
    t = 2 * math.pi * np.arange(m) / m
    return centre + rho * (np.cos(t)[:, None] * e1 + np.sin(t)[:, None] * e2)


def find_loops(shape: Shape) -> list:
    """Loops for the link test (module docstring): a list of (m, 3) vertex arrays, the shape's
    centred frame, scene units; empty when the shape's centre is inside it or no tried polygon
    about the centre is inside."""
    from sieve_mi.geometry.solid import winding_numbers

    tri = shape.vertices[shape.faces]
    if winding_numbers(np.zeros((1, 3)), tri)[0] >= 0.5:
        return []  # no through-hole at the centre: a loop would join only what B joins
    hull = np.asarray(shape.hull, dtype=np.float64)
    axes = list(np.eye(3)) + list(np.linalg.eigh(np.cov((hull - hull.mean(0)).T))[1].T)
    spacing = LOOP_SPACING * shape.radius

    best, found = 0.0, None
    for k, a in enumerate(axes):
        if any(abs(float(a @ b)) > 1 - 1e-9 for b in axes[:k]):
            continue
        a = a / np.linalg.norm(a)
        radii = LOOP_RADII * shape.radius
        got = _rooms([_ring(np.zeros(3), *_frame(a), rho, spacing) for rho in radii], tri)
        if got.max() > best:
            best, found = float(got.max()), (a, float(radii[int(got.argmax())]))
    if found is None:
        return []
    a, rho0 = found
    step = LOOP_STEP * shape.radius
    tried = [
        _ring(h * a, *_frame(a), rho, spacing)
        for h in step * np.arange(-math.floor(1 / LOOP_STEP), math.floor(1 / LOOP_STEP) + 1)
        for rho in rho0 + step * np.arange(-math.floor(rho0 / step), math.floor(1 / LOOP_STEP))
        if rho > 0
    ]
    return [q for q, room in zip(tried, _rooms(tried, tri)) if room > 0]


class Link:
    """The link test for a shape's loops, a pin and a band (module docstring).

    Parameters
    ----------
    loops : list of (m, 3) ndarray
        The loops' vertices, centred frame, scene units.
    pin : (3,) ndarray
    band : float
        Half the plate's thickness, scene units.
    eta : float
        The search's slack, scene units.
    """

    def __init__(self, loops: list, pin: np.ndarray, band: float, eta: float):
        pin = np.asarray(pin, dtype=np.float64)
        self.loops = [np.asarray(q, dtype=np.float64) - pin for q in loops]
        self.v = np.concatenate(self.loops)
        self.which = np.concatenate([np.full(len(q), k) for k, q in enumerate(self.loops)])
        self.at = np.concatenate([np.arange(len(q)) for q in self.loops])
        self.start = np.concatenate([[0], np.cumsum([len(q) for q in self.loops])])
        self.lengths = np.linalg.norm(self.v, axis=1)
        self.band, self.eta = float(band), float(eta)

    def stretches(self, z: np.ndarray, chord: float, inband: np.ndarray, k: int) -> list | None:
        """Loop ``k``'s two stretches (its vertex indices) over a cap, from every loop vertex's
        ``z`` = n_c . v, the cap's ``chord`` and band membership; None unless the surely-signed
        vertices change sign exactly twice, every other vertex lies on a stretch (so no segment
        off them crosses the plane) and both stretches lie in the band."""
        s0, s1 = self.start[k], self.start[k + 1]
        zk = z[s0:s1]
        reach = chord * self.lengths[s0:s1] * (1 + MARGIN) + self.eta
        sign = np.where(zk > reach, 1, np.where(zk < -reach, -1, 0))
        sure = np.flatnonzero(sign)
        if len(sure) < 2:
            return None
        change = np.flatnonzero(sign[sure] != sign[np.roll(sure, 1)])
        if len(change) != 2:
            return None
        m, out = s1 - s0, []
        for c in change:
            a, b = int(sure[c - 1]), int(sure[c])
            out.append([(a + i) % m for i in range((b - a) % m + 1)])
        if len(sure) + sum(len(q) - 2 for q in out) != m:
            return None  # an unsure vertex between two of one sign: a crossing off the stretches
        return out if all(inband[s0:s1][q].all() for q in out) else None

    def evidence(self, chain, plane, c: int, cell: tuple, pair) -> dict | None:
        """Link evidence for cell ``c`` of a :class:`~sieve_mi.certify.section.Plane` (``cell``:
        its band points' candidate indices, plane coordinates and bounds) from one to the other
        of the candidate pair ``pair``, or None: ``{"kind": "link", "points": [candidates],
        "path": [...]}``, the path's items an index into ``points`` or ``[loop, vertex]``; each
        step a chain step, or two vertices of one loop's stretches (the link)."""
        from sieve_mi.certify.chain import fewest_steps

        cols, x, r = cell
        at = np.searchsorted(cols, pair)
        if chain is None or chain.step <= 0 or len(cols) < 3 or np.any(at >= len(cols)):
            return None
        if np.any(cols[at] != pair):
            return None
        i, j = int(at[0]), int(at[1])
        if np.linalg.norm(x[i] - x[j]) - r[i] - r[j] <= chain.diameter:
            return None
        n_c, a = plane.centre[c], float(plane.alpha[c])
        chord = 2.0 * math.sin(0.5 * a)
        z = self.v @ n_c
        inband = (
            np.abs(z) + chord * self.lengths * (1 + MARGIN) < self.band * (1 - MARGIN) - self.eta
        )
        linked = [(q, f) for q in range(len(self.loops))
                  if (f := self.stretches(z, chord, inband, q)) is not None]  # fmt: skip
        if not linked and not inband.any():
            return None
        rl = (2 * (1 - math.cos(a)) * self.lengths + math.sin(a) * np.abs(z)) * (1 + MARGIN)
        rl += self.eta
        xl = np.column_stack([self.v @ plane.e1[c], self.v @ plane.e2[c]])
        use = np.flatnonzero(inband)
        k = len(cols)
        pts, rad = np.concatenate([x, xl[use]]), np.concatenate([r, rl[use]])
        node = np.full(len(self.v), -1)
        node[use] = k + np.arange(len(use))
        joins = []
        for q, found in linked:
            ids = [self.start[q] + np.asarray(f) for f in found]
            steps = [np.linalg.norm(np.diff(xl[f], axis=0), axis=1) + rl[f][:-1] + rl[f][1:]
                     for f in ids]  # fmt: skip
            if any(np.any(s >= chain.step) for s in steps):
                continue
            hub = node[np.concatenate(ids)]
            joins.append(np.column_stack([np.full(len(hub) - 1, hub[0]), hub[1:]]))
        path = fewest_steps(pts, rad, chain.step, i, j, joins)
        if path is None:
            return None
        if all(p < k for p in path):
            return None  # a chain of mesh points: the chain test's
        chosen = [p for p in path if p < k]
        loop_of = {int(node[g]): g for g in use}
        items = []
        for p in path:
            g = loop_of.get(p)
            items.append(chosen.index(p) if g is None else [int(self.which[g]), int(self.at[g])])
        return {"kind": "link", "points": cols[chosen].tolist(), "path": items}
