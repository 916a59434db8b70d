"""A perforated sheet: copies of the hole H on a square or hexagonal lattice.

Every copy is H moved by a rigid motion: turned about H's centre (the centre of its bounding box)
by one of the pattern's turns, then moved to a lattice site; with ``mirror``, every other class
of sites holds H mirrored (reflected in the vertical line through its centre) before the turn, so
a part lying either side up finds a copy of its own silhouette. The lattice's pitch is chosen from
H itself: it starts where the web is guaranteed (bounding boxes ``web`` apart; for turned copies,
the circumscribed disks), then each lattice vector is shortened by bisection while every pair of
neighbouring copies stays at least ``web`` apart, measured exactly (:func:`gap`: the least
distance between the two polygons' edges, and no overlap). The last pitch accepted is the one
used, and the web between every pair of copies of the sheet is checked again once they are placed.
Copies are kept only where their bounding box lies ``border`` inside the plate.

**Why one hole's answers hold for the sheet.** The copies are pairwise disjoint closed sets (at
least ``web`` > 0 apart). A connected set inside their union lies inside one of them (each copy is
open and closed in the union). The projection of a connected shape is connected, so it fits the
union iff it fits one copy, and a copy is H up to a rigid motion of the plane, which a pose of
the shape absorbs; a mirrored copy too: the half turn about the y axis, (x, y, z) -> (-x, y, -z),
mirrors every projection along z (and takes a slab of the plate's thickness to another), so the
mirror image of any projection or section of B is one of B in another pose. So for a connected B the straight-passage verdict and its certificate on H
are the sheet's, and so is the thick-plate argument (a B inside the plate's slab projects into
the union). A ball proof holds for any B (the ball's disk is connected). Not so for a B of
several bodies (its projection may fall apart), nor for a slab-section proof of a thin plate (a
section of a connected B may be disconnected): those must be proved against the union of the
holes, and :meth:`Pattern.window` gives the part of it a shape can reach.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import manifold3d
import numpy as np

from sieve_mi.errors import SieveError
from sieve_mi.geometry.cliques import cliques, sites_within

__all__ = [
    "BISECTION_STEPS",
    "PATTERNS",
    "SYMMETRY_SLACK",
    "TRAY_MM",
    "from_settings",
    "WEB_SLACK",
    "check_turns",
    "Pattern",
    "gap",
    "lay_out",
    "placed_gap",
    "tray_size",
]

#: Accepted ``[fabrication] pattern`` values.
PATTERNS = ("single", "square", "hex")
#: The default sheet's side, millimetres (a tray a shaker holds).
TRAY_MM = 100.0
#: Bisection steps per lattice vector when the pitch is shortened.
BISECTION_STEPS = 24
#: A gap short of the web by no more than this fraction (float rounding of an exact tie, such as
#: two 10 mm squares 12 mm apart) counts as the web.
WEB_SLACK = 1e-9
#: H counts as centrally symmetric (:meth:`Pattern.patches`) when its union with its half turn
#: is within this fraction of its area.
SYMMETRY_SLACK = 1e-6
#: Millimetres per scene unit (``units``); a unit not listed is taken as millimetres.
_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4, "um": 1e-3}


def tray_size(units: str, pitch: float, border: float) -> tuple[float, float]:
    """The default sheet: :data:`TRAY_MM` square in the scene's units, or larger when that would
    not hold 3 × 3 copies (``2 * border + 3 * pitch``), scene units."""
    side = max(TRAY_MM / _MM.get(units, 1.0), 2.0 * border + 3.0 * pitch)
    return (side, side)


def _contours(section: manifold3d.CrossSection) -> list[np.ndarray]:
    return [np.asarray(c, dtype=np.float64) for c in section.to_polygons()]


def _edges(section: manifold3d.CrossSection) -> tuple[np.ndarray, np.ndarray]:
    """Every edge of every contour: start points (e, 2) and end points (e, 2)."""
    cs = _contours(section)
    a = np.concatenate(cs)
    b = np.concatenate([np.roll(c, -1, axis=0) for c in cs])
    return a, b


def _point_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances from points p (n, 1, 2) to segments a-b (1, m, 2): (n, m)."""
    d = b - a
    dd = np.maximum((d * d).sum(-1), 1e-300)
    t = np.clip(((p - a) * d).sum(-1) / dd, 0.0, 1.0)
    q = a + t[..., None] * d
    return np.sqrt(((p - q) ** 2).sum(-1))


def _crossing(a1, b1, a2, b2) -> np.ndarray:
    """Whether segments a1-b1 (n, 1, 2) and a2-b2 (1, m, 2) cross properly: (n, m). A segment
    touching the other, or collinear with it, has an end point at distance 0 from it instead."""

    def orient(p, q, r):
        return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (
            r[..., 0] - p[..., 0]
        )

    o1, o2 = orient(a1, b1, a2), orient(a1, b1, b2)
    o3, o4 = orient(a2, b2, a1), orient(a2, b2, b1)
    return (o1 * o2 < 0) & (o3 * o4 < 0)


def gap(p: manifold3d.CrossSection, q: manifold3d.CrossSection, within: float) -> float:
    """The least distance between two polygons, exact up to float rounding; 0 when they meet.

    For two closed polygons that do not meet, the least distance is attained between two edges,
    and for two segments that do not cross, at an end point of one of them: so it is the least of
    the end-point-to-segment distances. Only edges whose bounding boxes come within ``within`` of
    the other polygon's are compared (a pair further apart than ``within`` counts as ``within``).

    Parameters
    ----------
    p, q : manifold3d.CrossSection
    within : float
        Distances beyond this are not needed, scene units.

    Returns
    -------
    float
        The distance (``min(distance, within)``), scene units; 0 when the polygons overlap or
        touch.
    """
    if (p ^ q).area() > 0:  # one inside the other, or overlapping
        return 0.0
    a1, b1 = _near(p, q, within)
    a2, b2 = _near(q, p, within)
    if not len(a1) or not len(a2):
        return float(within)
    best = float(within)
    for k in range(0, len(a1), 512):  # blocks of 512 edges keep the arrays small
        s1, e1 = a1[k : k + 512, None], b1[k : k + 512, None]
        if _crossing(s1, e1, a2[None], b2[None]).any():
            return 0.0
        best = min(best, float(_point_segment(s1, a2[None], b2[None]).min()))
        best = min(best, float(_point_segment(e1, a2[None], b2[None]).min()))
    for k in range(0, len(a2), 512):
        s2, e2 = a2[k : k + 512, None], b2[k : k + 512, None]
        best = min(best, float(_point_segment(s2, a1[None], b1[None]).min()))
        best = min(best, float(_point_segment(e2, a1[None], b1[None]).min()))
    return best


def _near(p, q, within: float) -> tuple[np.ndarray, np.ndarray]:
    """The edges of ``p`` whose bounding boxes come within ``within`` of ``q``'s bounding box."""
    a, b = _edges(p)
    x0, y0, x1, y1 = q.bounds()
    lo = np.minimum(a, b)
    hi = np.maximum(a, b)
    keep = (
        (hi[:, 0] >= x0 - within)
        & (lo[:, 0] <= x1 + within)
        & (hi[:, 1] >= y0 - within)
        & (lo[:, 1] <= y1 + within)
    )
    return a[keep], b[keep]


@dataclass
class Pattern:
    """Copies of the hole H placed on a lattice over a plate.

    Attributes
    ----------
    kind : {"square", "hex"}
    outline : manifold3d.CrossSection
        H, scene units.
    centre : (2,) float
        H's centre (of its bounding box): copies turn about it.
    a1, a2 : (2,) float
        The lattice vectors, scene units: sites are ``centre + i a1 + j a2``.
    turns : tuple of float
        The turns (degrees), the first 0: site (i, j) holds H turned by ``turns[(i + j) % k]``.
    sites : (n, 2) int
        The kept sites' lattice indices (i, j); (0, 0), H itself, is the first.
    web : float
        The least material asked between two copies, scene units.
    least_gap : float
        The least distance found between two copies of the sheet (at least ``web``).
    plate : (2, 2) float
        The plate's corners ``[[x0, y0], [x1, y1]]``, scene units.
    mirror : bool
        Site (i, j) holds H mirrored when ``(i + j) % 2k >= k`` (k turns): the classes cycle
        through every turn plain, then every turn mirrored.
    """

    kind: str
    outline: manifold3d.CrossSection
    centre: np.ndarray
    a1: np.ndarray
    a2: np.ndarray
    turns: tuple
    sites: np.ndarray
    web: float
    least_gap: float
    plate: np.ndarray
    mirror: bool = False

    @property
    def count(self) -> int:
        """The number of holes."""
        return int(len(self.sites))

    @property
    def plate_size(self) -> tuple[float, float]:
        """Width and height of the plate, scene units."""
        w, h = self.plate[1] - self.plate[0]
        return float(w), float(h)

    @property
    def open_fraction(self) -> float:
        """The holes' area over the plate's area."""
        w, h = self.plate_size
        return self.count * float(self.outline.area()) / (w * h)

    def copy(self, i: int, j: int, turn: float | None = None) -> manifold3d.CrossSection:
        """The copy of H at site (i, j) (turned by ``turn`` degrees instead, if given)."""
        turn = self.turn(i, j) if turn is None else turn
        return _copy(self.outline, self.centre, self.at(i, j), turn, self.mirrored(i, j))

    def at(self, i: int, j: int) -> np.ndarray:
        """Site (i, j)'s position, scene units."""
        return self.centre + i * self.a1 + j * self.a2

    def turn(self, i: int, j: int) -> float:
        """The turn of site (i, j), degrees."""
        return float(self.turns[(i + j) % len(self.turns)])

    def mirrored(self, i: int, j: int) -> bool:
        """Whether site (i, j) holds H mirrored (before its turn)."""
        return _mirrored(i + j, len(self.turns), self.mirror)

    def holes(self) -> manifold3d.CrossSection:
        """The union of every copy on the plate."""
        return _union([self.copy(int(i), int(j)) for i, j in self.sites])

    def window(self, reach: float, outline=None) -> manifold3d.CrossSection:
        """The union of the copies a set of diameter ``reach`` touching H's copy can touch, on
        the unbounded lattice, each site holding H at every turn: a superset of what such a set
        meets anywhere on the sheet.

        A set that touches the copy at site s touches only copies at sites within ``reach + 2R``
        of s (R: H's circumscribed radius about its centre). Moving the lattice by the vector
        that takes s to (0, 0) moves every site onto a site; with every turn at every site the
        union is unchanged by that move, so what such a set could fit on the sheet it could fit
        in this window. A proof that a shape's section (or its projection, of diameter at most
        the shape's) does not fit the window is a proof for the whole sheet; with one turn the
        window is exact around H, with several it is larger than the sheet (a proof is then
        conservative).

        ``outline``, if given, stands for H at every site (H grown by a margin: the union of
        grown copies is the grown union); default H.
        """
        outline = self.outline if outline is None else outline
        radius = _circumradius(outline, self.centre)
        reach_sites = sites_within(self.a1, self.a2, reach + 2.0 * radius)
        parts = [_copy(outline, self.centre, self.at(i, j), t, m)
                 for i, j in reach_sites for t in self.turns
                 for m in {False, self.mirror}]  # fmt: skip
        return _union(parts)

    def patches(self, reach: float, outline=None) -> manifold3d.CrossSection:
        """The groups of copies a set of diameter ``reach`` can touch together, laid far apart:
        a region whose proofs hold for the whole sheet, smaller than :meth:`window`.

        A set of diameter at most ``reach`` inside the union of the copies lies in the union of
        the copies it touches, and any two of those are at most ``reach`` apart (a point of the
        set in each). So they form a clique of the graph joining two sites whose copies may be
        that close (centres within ``reach + 2R``, R: H's circumscribed radius; a superset of
        the true pairs), and lie in a maximal clique. With one turn every copy is H translated,
        and a lattice move takes any clique to one of the maximal cliques through (0, 0) up to
        translation (:func:`~sieve_mi.geometry.cliques.cliques`), or up to a half turn too where
        H is centrally symmetric (then H is replaced by its union with its half turn, within
        :data:`SYMMETRY_SLACK` of H's area and never smaller, and a half turn of a group is the
        same group for a shape at every turn); a copy of each, laid at least ``reach`` from the
        others, is a region such a set could fit in only by fitting one group, which it could fit only
        if it fits the sheet's copies somewhere, and conversely what fits the sheet fits here.
        So a proof that a section (of diameter at most ``reach``) does not fit this region is a
        proof for the whole sheet. On the nut sheet of docs/shake.md (discs 8.7 mm wide, 5 mm
        apart, a 10.4 mm M5) each group is three discs in a triangle, against the window's seven.
        With several turns it is :meth:`window`, unless they are half turns of a centrally
        symmetric H (0° and 180°: every copy is then H' translated); with mirrored copies
        (``mirror``) it is :meth:`window` too.

        ``outline`` stands for H at every site, as in :meth:`window`.
        """
        outline = self.outline if outline is None else outline
        radius = _circumradius(outline, self.centre)
        half_turned = _copy(outline, self.centre, self.centre, 180.0)
        both = _union([outline, half_turned])
        symmetric = both.area() <= outline.area() * (1.0 + SYMMETRY_SLACK)
        halves = all(float(t) % 180.0 == 0.0 for t in self.turns)
        if self.mirror or (len(self.turns) > 1 and not (symmetric and halves)):
            return self.window(reach, outline)
        if symmetric:  # H' = H and H half-turned, a superset: every copy is H' up to a half turn
            outline = both
        groups = cliques(self.a1, self.a2, reach + 2.0 * radius, symmetric)
        step = 0.0
        parts = []
        for group in groups:
            sites = [self.at(i, j) for i, j in group]
            copies = [_copy(outline, self.centre, site, 0.0) for site in sites]
            x0 = min(c.bounds()[0] for c in copies)
            parts += [c.translate([step - x0, 0.0]) for c in copies]
            step += max(c.bounds()[2] for c in copies) - x0 + 2.0 * reach + 2.0 * radius
        return _union(parts)

    def to_dict(self) -> dict:
        """report.json's ``fabrication.pattern``."""
        return {
            "kind": self.kind,
            "count": self.count,
            "pitch": [float(np.linalg.norm(self.a1)), float(np.linalg.norm(self.a2))],
            "web": float(self.web),
            "least_gap": float(self.least_gap),
            "turns": [float(t) for t in self.turns],
            "mirror": bool(self.mirror),
            "open_fraction": float(self.open_fraction),
            "plate_size": list(self.plate_size),
        }


def _mirrored(c: int, k: int, mirror: bool) -> bool:
    """Whether site class ``c`` (i + j) of a pattern of ``k`` turns holds H mirrored."""
    return bool(mirror) and c % (2 * k) >= k


def _copy(outline, centre, site, turn: float, mirror: bool = False) -> manifold3d.CrossSection:
    """H (mirrored in the vertical line through ``centre`` when ``mirror``) turned by ``turn``
    degrees about ``centre``, then moved so its centre is at ``site``."""
    if turn == 0.0 and not mirror and np.array_equal(site, centre):
        return outline
    moved = outline.translate([-centre[0], -centre[1]])
    if mirror:
        moved = moved.mirror([1.0, 0.0])
    if turn != 0.0:
        moved = moved.rotate(turn)
    return moved.translate([float(site[0]), float(site[1])])


def _union(parts: list) -> manifold3d.CrossSection:
    if len(parts) == 1:
        return parts[0]
    return manifold3d.CrossSection.batch_boolean(parts, manifold3d.OpType.Add)


def _circumradius(outline, centre) -> float:
    pts = np.concatenate(_contours(outline))
    return float(np.linalg.norm(pts - centre, axis=1).max())


def _keeps(found: float, web: float) -> bool:
    """Whether a measured gap is the web (up to :data:`WEB_SLACK`)."""
    return found >= web * (1.0 - WEB_SLACK)


def _lattice(kind: str, px: float, py: float) -> tuple[np.ndarray, np.ndarray]:
    """The lattice vectors: square ``(px, 0), (0, py)``; hex rows ``py`` apart, each shifted by
    half a pitch: ``(px, 0), (px / 2, py)``."""
    return np.array([px, 0.0]), np.array([0.5 * px if kind == "hex" else 0.0, py])


def _least_gap(outline, centre, turns, vectors, web: float, mirror: bool = False) -> float:
    """The least distance between a copy of each site class (turn, and mirrored or not) and
    every other copy near it, on the unbounded lattice (at most ``2 web``: only whether it
    reaches ``web`` matters)."""
    a1, a2 = vectors
    radius = _circumradius(outline, centre)
    near = sites_within(a1, a2, 2.0 * radius + web)[1:]
    k, best = len(turns), 2.0 * web
    for r in range(2 * k if mirror else k):  # site (r, 0) holds class r
        here = _copy(outline, centre, centre + r * a1, float(turns[r % k]), _mirrored(r, k, mirror))
        for i, j in near:
            c = r + i + j
            there = _copy(outline, centre, centre + (r + i) * a1 + j * a2, float(turns[c % k]),
                          _mirrored(c, k, mirror))  # fmt: skip
            best = min(best, gap(here, there, 2.0 * web))
            if not _keeps(best, web):
                return best
    return best


def _pitch(
    kind: str, outline, centre, turns, web: float, mirror: bool = False
) -> tuple[np.ndarray, np.ndarray, float]:
    """The lattice vectors (shortest found) and the least gap between copies on them.

    Start where the web holds by construction (bounding boxes, the same for a mirrored copy, or
    circumscribed disks for turned copies), then shorten ``px`` and then ``py`` by bisection, each step checked by
    :func:`_least_gap`; only a checked pitch is ever kept.
    """
    x0, y0, x1, y1 = outline.bounds()
    if len(turns) > 1:
        d = 2.0 * _circumradius(outline, centre) + web
        px, py = d, (d * math.sqrt(3.0) / 2.0 if kind == "hex" else d)
    else:
        px, py = x1 - x0 + web, y1 - y0 + web
    ok = _least_gap(outline, centre, turns, _lattice(kind, px, py), web, mirror)
    if not _keeps(ok, web):  # cannot happen by the construction above; refuse rather than guess
        raise SieveError(f"fabrication.pattern: no lattice keeps the web {web:g} between copies")
    for which in (0, 1):
        lo, hi = 0.25 * (px, py)[which], (px, py)[which]
        for _ in range(BISECTION_STEPS):
            mid = 0.5 * (lo + hi)
            trial = (mid, py) if which == 0 else (px, mid)
            found = _least_gap(outline, centre, turns, _lattice(kind, *trial), web, mirror)
            if _keeps(found, web):
                hi, ok = mid, found
            else:
                lo = mid
        px, py = (hi, py) if which == 0 else (px, hi)
    return *_lattice(kind, px, py), ok


def _fitting(outline, centre, vectors, turns, box, mirror: bool = False) -> list[tuple[int, int]]:
    """The sites (i, j) whose copy's bounding box lies inside ``box`` ``[[x0, y0], [x1, y1]]``."""
    a1, a2 = vectors
    k = 2 * len(turns) if mirror else len(turns)
    extents = []  # per site class: the copy's bounding box about its site
    for c in range(k):
        b = _copy(outline, centre, centre, float(turns[c % len(turns)]),
                  _mirrored(c, len(turns), mirror)).bounds()  # fmt: skip
        extents.append((np.array(b[:2]) - centre, np.array(b[2:]) - centre))
    span = float(np.linalg.norm(box[1] - box[0])) + float(np.linalg.norm(a1) + np.linalg.norm(a2))
    out = []
    for i, j in sites_within(a1, a2, span):
        lo, hi = extents[(i + j) % k]
        site = centre + i * a1 + j * a2
        if np.all(site + lo >= box[0]) and np.all(site + hi <= box[1]):
            out.append((i, j))
    return out


def lay_out(outline: manifold3d.CrossSection, kind: str, size, border: float, web: float,
            turns=None, units: str = "mm", mirror: bool = False) -> Pattern:  # fmt: skip
    """Copies of ``outline`` on a ``kind`` lattice over a plate of ``size``, ``border`` inside its
    edges and at least ``web`` apart (checked exactly, :func:`gap`).

    The plate is centred on H (or shifted by half a lattice vector when that holds more copies);
    H itself is always one of the copies, so a pose found for H is a pose over the sheet.

    Parameters
    ----------
    outline : manifold3d.CrossSection
        H, scene units.
    kind : {"square", "hex"}
    size : (float, float) or None
        The plate's width and height, scene units; None: :func:`tray_size`.
    border, web : float
        Scene units, > 0.
    turns : sequence of float, optional
        Degrees, one of them 0 (default: 0 only).
    units : str
        The scene's units (for the default size).
    mirror : bool
        Every other class of sites holds H mirrored (:class:`Pattern`).

    Returns
    -------
    Pattern

    Raises
    ------
    SieveError
        One line naming the key: no 0 among the turns, or a plate too small for one hole.
    """
    turns = _turns(turns)
    x0, y0, x1, y1 = outline.bounds()
    centre = np.array([(x0 + x1) / 2.0, (y0 + y1) / 2.0])
    a1, a2, least = _pitch(kind, outline, centre, turns, web, mirror)
    if size is None:
        size = tray_size(
            units, max(np.linalg.norm(a1), np.linalg.norm(a2), x1 - x0, y1 - y0), border
        )
    half = 0.5 * np.asarray(size, dtype=np.float64)
    best = None
    for shift in (np.zeros(2), 0.5 * a1, 0.5 * a2, 0.5 * (a1 + a2)):
        plate = np.array([centre + shift - half, centre + shift + half])
        inner = plate + [[border, border], [-border, -border]]
        sites = _fitting(outline, centre, (a1, a2), turns, inner, mirror)
        if (0, 0) in sites and (best is None or len(sites) > len(best[1])):
            best = (plate, sites)
    if best is None:
        w, h = x1 - x0, y1 - y0
        raise SieveError(
            f"fabrication.plate_size: {size[0]:g} x {size[1]:g} holds no hole of {w:.4g} x "
            f"{h:.4g} with border {border:g}; give at least {w + 2 * border:.4g} x "
            f"{h + 2 * border:.4g}"
        )
    plate, sites = best
    out = Pattern(kind, outline, centre, a1, a2, turns, np.array(sites, dtype=np.int64),
                  float(web), float(least), plate, bool(mirror))  # fmt: skip
    out.least_gap = placed_gap(out)
    if not _keeps(out.least_gap, web):  # the lattice was checked; this checks the sheet itself
        raise SieveError(f"fabrication.web: copies {out.least_gap:.6g} apart, less than {web:g}")
    return out


def placed_gap(pattern: Pattern) -> float:
    """The least distance between two copies of the sheet (every pair whose circumscribed disks
    come within ``2 web``), exact up to float rounding (:func:`gap`); at most ``2 web``."""
    from scipy.spatial import cKDTree

    web = pattern.web
    radius = _circumradius(pattern.outline, pattern.centre)
    at = np.array([pattern.at(int(i), int(j)) for i, j in pattern.sites])
    copies = [pattern.copy(int(i), int(j)) for i, j in pattern.sites]
    best = 2.0 * web
    for u, v in sorted(cKDTree(at).query_pairs(2.0 * radius + 2.0 * web)):
        best = min(best, gap(copies[u], copies[v], 2.0 * web))
    return best


def check_turns(turns, path: str | None = None) -> None:
    """Raise a one-line SieveError (naming ``path``, the scene file, if given) unless ``turns``
    (degrees) is None or holds a 0 (mod 360): one copy must be the hole itself."""
    if turns is not None and not any(float(t) % 360.0 == 0.0 for t in turns):
        where = f"{path}: " if path else ""
        raise SieveError(
            f"{where}fabrication.turns: {[float(t) for t in turns]} has no 0; one copy must be "
            "the hole itself (add 0)"
        )


def _turns(turns) -> tuple:
    """The turns as a tuple of floats, 0 first (the site of H itself)."""
    check_turns(turns)
    turns = tuple(float(t) for t in (turns or (0.0,)))
    k = next(i for i, t in enumerate(turns) if t % 360.0 == 0.0)
    return turns[k:] + turns[:k]


def from_settings(
    outline: manifold3d.CrossSection, fabrication, units: str = "mm"
) -> Pattern | None:
    """The sheet a scene's ``[fabrication]`` table asks for (``pattern``, ``plate_size``, ``web``,
    ``turns``, ``mirror``, ``border``) around the hole ``outline``; None for ``pattern =
    "single"``."""
    if fabrication.pattern == "single":
        return None
    return lay_out(outline, fabrication.pattern, fabrication.plate_size, fabrication.border,
                   fabrication.web, fabrication.turns, units, fabrication.mirror)  # fmt: skip
