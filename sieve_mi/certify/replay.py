"""Independent replay of a certificate: re-check every leaf without the search code.

Nothing here uses manifold3d or :mod:`sieve_mi.certify.bounds` / ``search``: the hole is the
certificate's contours, distances are exact point-to-segment distances computed by the replay's
own geometry (:mod:`sieve_mi.certify.replay_geometry`), point in polygon is matplotlib's ``Path``
(even-odd over the contours), and the distance to the mesh for the ball evidence is trimesh's
``triangles.closest_point``. The replay

0. checks the structure (:func:`sieve_mi.certify.structure.check_structure`: every field's type
   and shape, every number finite and at most
   :data:`~sieve_mi.certify.structure.MAX_COORDINATE`, every index in range; a SieveError naming
   the field otherwise);
1. checks that the stored mesh matches its hash (and the file at ``shape.path``, when present) and
   that every evidence point is a vertex of the mesh or lies on one of its edges (recomputed here
   from the edge and its parameter; edge points only without a symmetry reduction);
2. checks the claimed symmetry group on the mesh and that the tree's roots are its domain's faces;
3. walks the tree, rebuilding each cell's box by halving (so the leaves cover the domain by
   construction; a split node must have exactly 8 children);
4. re-proves each leaf with each point's displacement bound over the cell, 2 sin(theta) |p| or,
   for certificates whose ``settings.bound`` is ``"first-order"``, the smaller of that and the
   first-order bound (:func:`~sieve_mi.certify.replay_geometry.first_order_bounds`, computed here by the chain rule through the
   normalised quaternion; docs/certify.md): ``width`` evidence by the width inequality along its
   direction,
   ``translations`` evidence by a quadtree over translations that must discard every box (a box of
   centre c and half-diagonal e is discarded when some point i has c + pi_i outside H at distance
   > r_i + e; boxes are refined down to the slack the search left, kappa times the displacement
   bound of the shape's radius), ``ball`` evidence by the winding number, the distance to the mesh
   and a quadtree showing that no disk of the ball's radius fits in H;
5. checks a claimed passage: every vertex inside H, no projected edge crossing H's boundary, and no
   vertex of H inside a projected triangle;
6. re-derives the ``status`` from what steps 1-5 showed (a ball root, every cell excluded, or a
   slab-section proof re-proved by :mod:`~sieve_mi.certify.replay_section` beside open cells:
   proved; a passage that fits: passage; open cells, no section and no passage: undecided) and
   rejects a claimed status that differs, or claims that contradict (a ball proof with a
   passage or a cell tree, a passage where every cell is excluded or beside a section). Every
   rejection lists at least one error, each starting with the field it concerns;
7. checks the scope of the claim (``plate``, when the certificate has one): its ``diameter``
   against the mesh's, recomputed here, and its ``holds_for`` against what the evidence gives: a
   ball proof or a passage holds on any plate, a complete cell-tree proof only on plates at
   least the diameter thick (the thick-plate argument), a section proof on plates at least its
   thickness thick (with open cells too: a straight passage would pass every plate, so the
   section excludes it), an undecided tree on none. A certificate claiming more (``"any
   plate"`` for a cell tree) is invalid. Certificates written before ``plate`` are replayed as
   before, with the scope derived.
"""

from __future__ import annotations

import hashlib
import math
import os
import time

import numpy as np

from sieve_mi.certify.replay_geometry import (
    Hole,
    cell_angle,
    disk_never_fits,
    first_order_bounds,
    no_translation,
    points_in_triangles,
    rotation,
    segments_cross,
)
from sieve_mi.certify.structure import certificate_where, check_structure, load_certificate
from sieve_mi.errors import SieveError

__all__ = ["MAX_ERRORS", "STATUSES", "Replay", "replay"]


class Replay:
    """State of one replay: the certificate, the hole, and the problems found."""

    def __init__(self, cert: dict):
        self.cert = cert
        self.errors: list[str] = []
        shape = cert["shape"]
        self.vertices = np.asarray(shape["vertices"], dtype=np.float64)
        self.faces = np.asarray(shape["faces"], dtype=np.int64)
        self.points = np.asarray(shape["points"], dtype=np.float64).reshape(-1, 3)
        self.hole = Hole(cert["hole"])
        self.radius = float(np.linalg.norm(self.vertices[np.unique(self.faces)], axis=1).max())
        self.kappa = float(cert["settings"]["kappa"])
        self.bound = cert["settings"].get("bound", "isotropic")
        if self.bound not in ("isotropic", "first-order"):
            self.errors.append(f"settings.bound: unknown displacement bound {self.bound!r}")
        m = int(cert["settings"]["directions"])
        a = np.pi * np.arange(m) / m
        self.dirs = np.column_stack([np.cos(a), np.sin(a)])
        self.leaves = self.open = 0
        self.section: float | None = None  # the thickness a replayed section proof covers
        self._edges = None

    def check_mesh(self) -> None:
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(self.vertices).tobytes())
        h.update(np.ascontiguousarray(self.faces).tobytes())
        if h.hexdigest() != self.cert["shape"]["sha256"]:
            self.errors.append("shape.sha256: does not match the stored mesh (vertices, faces)")
        path = self.cert["shape"].get("path", "")
        if path and os.path.isfile(path):
            s = self._load_mesh(path)
            if s is not None and not (
                np.array_equal(s.vertices, self.vertices) and np.array_equal(s.faces, self.faces)
            ):
                self.errors.append(f"shape.path: {path} differs from the certificate's mesh")
        known = {tuple(v) for v in self.vertices[np.unique(self.faces)]}
        refs = self.cert["shape"].get("on_edge") or [None] * len(self.points)
        if len(refs) != len(self.points):
            self.errors.append("shape.on_edge: not one entry per point")
            return
        bad = [
            i
            for i, (p, r) in enumerate(zip(self.points, refs))
            if not self._on_mesh(i, p, r, known)
        ]
        if bad:
            self.errors.append(
                f"shape.points: points {bad[:5]} are neither vertices nor on edges of the mesh"
            )

    def _load_mesh(self, path: str):
        """The mesh file the certificate names, or None (and an error) when it cannot be read."""
        from sieve_mi.geometry.meshes import load_shape

        try:
            return load_shape(path, scale=float(self.cert["shape"].get("scale", 1.0)))
        except SieveError as exc:
            self.errors.append(f"shape.path: {exc}")
            return None

    def _on_mesh(self, k: int, p: np.ndarray, ref, known: set) -> bool:
        """Whether point k is a vertex, or lies on the mesh edge ``ref`` = [i, j, lam] (then its
        coordinates are recomputed here from the edge and used by the replay)."""
        if ref is None:
            return tuple(p) in known
        i, j, lam = int(ref[0]), int(ref[1]), float(ref[2])
        if self._edges is None:
            f = np.sort(self.faces, axis=1)
            self._edges = {
                tuple(e) for e in np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [0, 2]]])
            }
        if (min(i, j), max(i, j)) not in self._edges or not 0.0 <= lam <= 1.0:
            return False
        a, b = self.vertices[i], self.vertices[j]
        self.points[k] = a + lam * (b - a)
        return True

    def check_symmetry(self) -> tuple[list[int], float]:
        """Verify the claimed group; the domain's faces and half-width."""
        group = self.cert["symmetry"]
        turns = {
            "klein": [np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]), np.diag([-1.0, -1, 1])],
            "octahedral": [
                np.diag([1.0, -1, -1]),
                np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]),
                np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]]),
                np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]),
            ],
        }
        if group not in ("none", "klein", "octahedral"):
            self.errors.append(f"symmetry: unknown group {group!r}")
            return [0, 1, 2, 3], 1.0
        verts = self.vertices[np.unique(self.faces)]
        known = set(map(tuple, verts))
        for m in turns.get(group, []):
            if set(map(tuple, verts @ m.T)) != known:
                self.errors.append(
                    f"symmetry: the mesh is not symmetric under the claimed {group} group"
                )
                break
        if group == "none":
            return [0, 1, 2, 3], 1.0
        if any(r is not None for r in self.cert["shape"].get("on_edge") or []):
            self._check_edge_symmetry(turns[group])
        return [0], (1.0 if group == "klein" else 0.41422)

    def _check_edge_symmetry(self, generators: list) -> None:
        """Evidence on an edge needs that edge in a set of edges the group maps onto itself:
        the largest set closed under the generators, computed here."""
        f = self.faces
        ends = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [0, 2]]])
        v = self.vertices
        closed = {frozenset((tuple(v[i]), tuple(v[j]))) for i, j in ends}
        while True:
            out = {
                e
                for e in closed
                for m in generators
                if frozenset(tuple(m @ np.array(p)) for p in e) not in closed
            }
            if not out:
                break
            closed -= out
        for ref in self.cert["shape"].get("on_edge") or []:
            if ref is not None:
                e = frozenset((tuple(v[int(ref[0])]), tuple(v[int(ref[1])])))
                if e not in closed:
                    self.errors.append(
                        "shape.on_edge: a point on an edge the symmetry does not preserve"
                    )
                    return

    def check_leaf(self, face: int, lo: np.ndarray, hi: np.ndarray, ev: dict) -> bool:
        """Re-prove one excluded cell from its evidence."""
        if not isinstance(ev, dict) or not isinstance(ev.get("points"), list):
            return False
        idx = np.asarray(ev.get("points", []), dtype=np.int64)
        if len(idx) == 0 or idx.min() < 0 or idx.max() >= len(self.points):
            return False
        q0, theta = cell_angle(face, lo, hi)
        p = self.points[idx]
        proj = p @ rotation(q0)[:2].T
        radii = 2.0 * math.sin(theta) * np.linalg.norm(p, axis=1)
        if self.bound == "first-order":
            proj, first = first_order_bounds(face, lo, hi, p)
            radii = np.minimum(radii, first)
        elif self.bound != "isotropic":
            return False
        if ev.get("kind") == "width":
            u = self.dirs[int(ev["direction"]) % len(self.dirs)]
            dots = proj @ u
            hv = self.hole.vertices @ u
            spread = (dots - radii).max() - (dots + radii).min()
            return bool(spread > (hv.max() - hv.min()) * (1 + 1e-12) + 1e-12)
        if ev.get("kind") == "translations":
            resolve = self.kappa * 2.0 * math.sin(theta) * self.radius
            return no_translation(self.hole, proj, radii, resolve)
        return False

    def walk(self, node: dict, face: int, lo: np.ndarray, hi: np.ndarray, depth: int = 0) -> None:
        """Check a subtree: split nodes have 8 children, leaves re-proved, open leaves counted.

        Stops once :data:`MAX_ERRORS` problems are known: the certificate is invalid then, and a
        tampered one (every leaf failing, each failure slower than a success) ends in seconds.
        """
        if len(self.errors) >= MAX_ERRORS:
            return
        if not isinstance(node, dict):
            self.errors.append(f"tree: a node at depth {depth} is not an object")
        elif depth > 60:
            self.errors.append("tree: deeper than 60 levels")
        elif "c" in node:
            kids = node["c"]
            if not isinstance(kids, list) or len(kids) != 8:
                n = len(kids) if isinstance(kids, list) else "no list of"
                self.errors.append(f"tree: a split cell at depth {depth} has {n} children, not 8")
                return
            mid = 0.5 * (lo + hi)
            for c, kid in enumerate(kids):
                upper = np.array([(c >> (2 - j)) & 1 for j in range(3)], dtype=bool)
                self.walk(kid, face, np.where(upper, mid, lo), np.where(upper, hi, mid), depth + 1)
        elif "e" in node:
            self.leaves += 1
            if not self.check_leaf(face, lo, hi, node["e"]):
                self.errors.append(
                    f"tree: leaf face {face} box {lo.tolist()}..{hi.tolist()}: evidence does not hold"
                )
        else:
            self.open += 1

    def check_ball(self, root: dict) -> None:
        """A ball inside the closed mesh, and no disk of its radius inside H."""
        import trimesh

        mesh = trimesh.Trimesh(self.vertices, self.faces, process=False)
        centre, rho = np.asarray(root["centre"], dtype=np.float64), float(root["radius"])
        if not (mesh.is_watertight and mesh.is_winding_consistent):
            self.errors.append("root: ball evidence needs a closed, consistently oriented mesh")
            return
        tri = self.vertices[self.faces]
        foot = trimesh.triangles.closest_point(tri, np.repeat(centre[None], len(tri), axis=0))
        if not np.linalg.norm(foot - centre, axis=1).min() >= rho:
            self.errors.append(f"root.radius: the ball of radius {rho} is not inside the mesh")
        a = self.vertices[self.faces] - centre
        la, lb, lc = np.linalg.norm(a, axis=2).T
        triple = np.einsum("ij,ij->i", a[:, 0], np.cross(a[:, 1], a[:, 2]))
        den = la * lb * lc + lc * (a[:, 0] * a[:, 1]).sum(1)
        den += la * (a[:, 1] * a[:, 2]).sum(1) + lb * (a[:, 2] * a[:, 0]).sum(1)
        if abs(np.arctan2(triple, den).sum() / (2 * np.pi)) < 0.5:
            self.errors.append("root.centre: the ball's centre is not enclosed by the mesh")
        if not disk_never_fits(self.hole, rho):
            self.errors.append(f"root.radius: a disk of radius {rho} may fit in the hole")

    def check_passage(self, passage: dict) -> None:
        """The pose puts the exact projection inside H."""
        q = np.asarray(passage["quaternion"], dtype=np.float64)
        t = np.asarray(passage["translation"], dtype=np.float64)
        p = self.vertices @ rotation(q)[:2].T + t
        if not self.hole.contains(p[np.unique(self.faces)]).all():
            self.errors.append("passage: a vertex lies outside the hole")
            return
        edges = np.unique(
            np.sort(
                np.concatenate(
                    [self.faces[:, [0, 1]], self.faces[:, [1, 2]], self.faces[:, [2, 0]]]
                ),
                axis=1,
            ),
            axis=0,
        )
        if segments_cross(p[edges[:, 0]], p[edges[:, 1]], self.hole.a, self.hole.b):
            self.errors.append("passage: an edge of the shape crosses the hole's boundary")
        tri = p[self.faces]
        if points_in_triangles(self.hole.vertices, tri):
            self.errors.append("passage: a corner of the hole lies inside the shape's projection")


#: Problems after which a replay stops (the first ones are reported; the verdict is "invalid").
MAX_ERRORS = 10


#: The claims a certificate can make.
STATUSES = ("proved", "passage", "undecided")


def replay(source) -> dict:
    """Re-check a certificate (a path or the loaded dict) independently of the search.

    Every claimed field is re-derived from the evidence: the mesh from its hash (and the file at
    ``shape.path``), the symmetry from the mesh, each leaf, the ball and the passage by their own
    tests, and the ``status`` from what the evidence shows (a ball proof or a complete tree of
    excluded cells: proved; a passage that fits: passage; open cells and no passage: undecided).
    A claim the evidence does not support makes the certificate invalid, with an error naming the
    field; an invalid certificate always has at least one error.

    Returns
    -------
    dict
        ``valid`` (every check passed and the claimed status is the one the evidence shows),
        ``proved`` (valid and proved: for straight passage, or by a section proof on plates
        at least its thickness), ``status`` claimed, ``holds_for`` (what the claim covers:
        ``"any plate"``, ``"plates at least the diameter thick"``, ``"plates at least the
        section's thickness thick"`` (then ``section_thickness``) or None), ``diameter``
        (recomputed), ``thickness`` (the plate's, as recorded, or None),
        ``covers_plate`` (whether the claim holds on that plate; None without one), ``leaves``
        re-proved, ``open`` cells, ``errors`` (the first 10 problems) and ``seconds``.

    Raises
    ------
    SieveError
        If ``source`` is not a path or a dict, the file cannot be read, or it is not a
        well-formed sieve-mi certificate (a missing key, a wrong type, a number that is not
        finite or is out of range); one line naming the field.
    """
    t0 = time.perf_counter()
    where = certificate_where(source)
    cert = load_certificate(source, where)
    check_structure(cert, where)
    try:
        r = _run_checks(cert)
    except (KeyError, TypeError, ValueError, IndexError, OverflowError, AttributeError) as exc:
        raise SieveError(f"{where}: malformed certificate ({type(exc).__name__}: {exc})") from None
    except RecursionError:
        raise SieveError(f"{where}: malformed certificate (nested too deeply)") from None
    status = cert["status"]
    plate, plate_errors = _plate_scope(cert, r)
    r.errors[:0] = _status_errors(cert, r) + plate_errors  # first: among those reported
    return {
        "valid": not r.errors,
        "proved": not r.errors and status == "proved",
        "status": status,
        **plate,
        "leaves": r.leaves,
        "open": r.open,
        "errors": r.errors[:MAX_ERRORS],
        "seconds": time.perf_counter() - t0,
    }


def _run_checks(cert: dict) -> Replay:
    """Every check of the evidence (module docstring, steps 1-5); the problems in ``errors``."""
    r = Replay(cert)
    r.check_mesh()
    faces, half = r.check_symmetry()
    if cert["root"]:
        r.check_ball(cert["root"])
        if cert["tree"]:
            r.errors.append("tree: a ball proof (root) has no cell tree")
    elif len(cert["tree"]) != len(faces):
        r.errors.append(
            f"tree: {len(cert['tree'])} roots, the {cert['symmetry']} domain has {len(faces)}"
        )
    else:
        for face, node in zip(faces, cert["tree"]):
            r.walk(node, face, np.full(3, -half), np.full(3, half))
    if cert["passage"]:
        r.check_passage(cert["passage"])
    if cert.get("section") is not None:
        from sieve_mi.certify.replay_section import SectionReplay

        own = cert["section"].get("hole")  # a perforated sheet's copies within reach
        s = SectionReplay(
            cert["section"], r.vertices, r.faces, r.hole if own is None else Hole(own)
        )
        r.section = s.thickness if s.run() else None
        r.errors += s.errors
        if r.section is not None and cert["section"]["status"] != "proved":
            r.errors.append(f"section.status: claims {cert['section']['status']!r}, but every "
                            "cell re-proves: a certificate carries only a proved section")  # fmt: skip
        if r.section is None and not s.errors:
            r.errors.append(f"section: {s.open} open cells; the section is not proved")
    return r


def _status_errors(cert: dict, r: Replay) -> list[str]:
    """The claimed ``status`` against the one the evidence shows, and claims that contradict.

    Evidence shows: a ball root, proved; else a passage, passage; else open cells beside a
    slab-section proof re-proved here, proved (a section proof excludes every rigid motion
    through plates at least its thickness thick, and a straight passage would pass every
    plate); else open cells, undecided; else (every cell of the domain excluded), proved. Open
    cells are counted only by a walk without errors, so with other errors only the claims
    themselves are compared.
    """
    claim, errors = cert["status"], []
    if claim not in STATUSES:
        errors.append(f"status: {claim!r} is not one of {', '.join(STATUSES)}")
    if cert["root"] and cert["passage"]:
        errors.append("passage: a ball proof (root) and a passage contradict each other")
    if cert["passage"] and cert.get("section") is not None:
        errors.append("passage: a slab-section proof (section) and a passage contradict each other")
    if errors or r.errors:
        return errors
    if cert["passage"] and not r.open:
        return ["passage: every cell of the tree is excluded, yet a passage is claimed"]
    if cert["root"]:
        shown, why = "proved", "a ball proof at the root"
    elif cert["passage"]:
        shown, why = "passage", "a passage pose that fits"
    elif r.open and r.section is not None:
        shown, why = "proved", f"a slab-section proof re-proved, beside {r.open} open cells"
    elif r.open:
        shown, why = "undecided", f"open cells: {r.open}, and no passage"
    else:
        shown, why = "proved", "every cell of the domain excluded"
    if claim != shown:
        errors.append(f"status: claims {claim}, but the evidence shows {shown} ({why})")
    return errors


#: What a claim covers (``plate.holds_for``; :func:`sieve_mi.certify.certificate.scope`).
ANY_PLATE, THICK_PLATES = "any plate", "plates at least the diameter thick"
SECTION_PLATES = "plates at least the section's thickness thick"
#: Lengths within this many scene units count as equal (``geometry.plate.LENGTH_SLACK``).
LENGTH_SLACK = 1e-6


def mesh_diameter(vertices: np.ndarray) -> float:
    """Largest distance between two of the points (over their convex hull's vertices), exact."""
    from scipy.spatial import ConvexHull

    p = np.asarray(vertices, dtype=np.float64)
    try:
        p = p[ConvexHull(p).vertices]
    except Exception:  # flat or collinear: every point
        pass
    best = 0.0
    for i in range(0, len(p), 1024):
        best = max(best, float(((p[i : i + 1024, None] - p[None]) ** 2).sum(-1).max()))
    return math.sqrt(best)


def _plate_scope(cert: dict, r: Replay) -> tuple[dict, list[str]]:
    """What the claim covers, from the evidence, and the certificate's ``plate`` entry checked.

    A ball proof and a passage hold on any plate; a complete cell-tree proof on plates at least
    the diameter thick; a slab-section proof (re-proved, with a complete tree or open cells) on
    plates at least its thickness thick; an undecided claim on none.
    """
    claim = cert["status"]
    holds = ANY_PLATE if claim == "passage" or (claim == "proved" and cert["root"]) else None
    tree = claim == "proved" and not cert["root"]
    holds = THICK_PLATES if tree and not r.open else holds
    if tree and r.section is not None:
        holds = SECTION_PLATES  # a slab-section proof, re-proved here (open cells or none)
    diameter = mesh_diameter(r.vertices[np.unique(r.faces)])
    plate, errors = cert.get("plate"), []
    thickness = plate.get("thickness") if plate else None
    if plate:
        if plate.get("holds_for") != holds:
            why = {ANY_PLATE: "a ball proof or a passage holds on any plate",
                   THICK_PLATES: "a cell-tree proof holds only on plates at least the shape's "
                                 "diameter thick (a thinner one may let it through tilted)",
                   SECTION_PLATES: "a section proof holds on plates at least section.thickness "
                                   "thick",
                   None: "an undecided claim holds for nothing"}[holds]  # fmt: skip
            errors.append(f"plate.holds_for: claims {plate.get('holds_for')!r}, but {why}")
        d = plate.get("diameter")
        if d is None or abs(d - diameter) > 1e-9 * max(diameter, 1e-300):
            errors.append(f"plate.diameter: claims {d!r}, the mesh's is {diameter!r}")
    covers = None
    if thickness is not None and holds is not None:
        need = r.section if holds == SECTION_PLATES else diameter
        covers = holds == ANY_PLATE or thickness + LENGTH_SLACK >= need
    info = {"holds_for": holds, "diameter": diameter, "thickness": thickness}
    if holds == SECTION_PLATES:
        info["section_thickness"] = r.section
    return {**info, "covers_plate": covers}, errors
