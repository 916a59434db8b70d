"""The passage scene shared by ``report.html`` and ``passage.gif``: the plate, every A sliding down
through its hole and every B's best attempt coming to rest on the plate.

Coordinates are the fabrication's (:mod:`sieve_mi.outputs.fabrication`): scene units, the hole around the
xy origin, the plate from z = -T to z = 0. Each shape keeps its pose's rotation and its xy
translation; only its height changes with the animation's phase ``s`` in [0, 1]:

* the phase is cut into equal slots, one for all of A and then one per B; a shape is shown only
  during its slot (so the shapes never overlap), and moves with its slot's local phase u in [0, 1];
* every A starts ``gap`` above the plate (its lowest point at z = gap) and ends ``gap`` below it
  (its highest point at z = -T - gap), at constant speed;
* a blocked B (as report.json says) starts the same way and descends at the speed it would need
  to pass, until it rests on the plate: its lowest point over the plate's material touches z = 0
  (:func:`rest_offset`); it stays there to the end of its slot. A B that is not blocked passes
  like an A.
* a B that passes a thin plate by a found motion (report.json's ``thin_plate``) follows that
  motion instead: its ``keys`` are the motion's poses, each at a local phase proportional to how
  far the shape has moved (:func:`sieve_mi.motion.path.segment_reach`), its ``vertices`` are in
  its own frame, and :meth:`Piece.matrix` places it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sieve_mi.geometry.outline import Boundary, placed_vertices
from sieve_mi.geometry.rotations import to_matrix
from sieve_mi.motion.path import interpolate, segment_reach

__all__ = ["Passage", "Piece", "build", "rest_offset", "surface_points"]


@dataclass
class Piece:
    """One shape of the passage.

    Attributes
    ----------
    name : str
    role : {"pass", "block"}
    index : int
        Position in the scene's list of that role.
    vertices : (V, 3) ndarray of float64
        The posed mesh at height offset 0 (rotated about its centre, moved by its xy translation),
        scene units.
    faces : (F, 3) ndarray of int64
    start, end : float
        Height offsets (added to z) at phase 0 and where the motion ends, scene units.
    stop : float
        Local phase u in [0, 1] at which the shape reaches ``end`` (1 for a shape that passes;
        earlier for a B that comes to rest on the plate).
    slot : (float, float)
        The phases during which it is shown and moves.
    passes : bool
        Whether it goes through (every A; a B whose attempt fits the hole).
    centre : (2,) ndarray
        Its pose's xy translation, scene units.
    keys : (k, 8) ndarray or None
        A found thin-plate motion: rows (u, w, x, y, z, tx, ty, tz), the local phase and the pose
        (rotation about the shape's centre, the centre's position); ``vertices`` are then in the
        shape's own frame (centred, unrotated).
    """

    name: str
    role: str
    index: int
    vertices: np.ndarray
    faces: np.ndarray
    start: float
    end: float
    stop: float
    passes: bool
    centre: np.ndarray
    slot: tuple = (0.0, 1.0)
    keys: np.ndarray | None = None

    def matrix(self, s: float) -> np.ndarray:
        """(4, 4) transform of ``vertices`` at phase ``s``: the motion's pose for a piece with
        ``keys``, else a lift by :meth:`offset`."""
        m = np.eye(4)
        if self.keys is None:
            m[2, 3] = self.offset(s)
            return m
        t0, t1 = self.slot
        u = min(max((float(s) - t0) / (t1 - t0), 0.0), 1.0)
        k = int(
            np.clip(np.searchsorted(self.keys[:, 0], u, side="right") - 1, 0, len(self.keys) - 2)
        )
        a, b = self.keys[k], self.keys[k + 1]
        f = 0.0 if b[0] <= a[0] else (u - a[0]) / (b[0] - a[0])
        q, t = interpolate((a[1:5], a[5:]), (b[1:5], b[5:]), f)
        m[:3, :3], m[:3, 3] = to_matrix(q), t
        return m

    def offset(self, s: float) -> float:
        """Height offset at phase ``s`` in [0, 1], scene units."""
        t0, t1 = self.slot
        u = (float(s) - t0) / (t1 - t0)
        f = min(max(u, 0.0), self.stop) / self.stop if self.stop > 0 else 1.0
        return self.start + f * (self.end - self.start)

    def visible(self, s: float) -> bool:
        """Whether it is shown at phase ``s`` (within its slot; the last slot includes 1)."""
        t0, t1 = self.slot
        return t0 <= s < t1 or (t1 >= 1.0 and s >= 1.0)


@dataclass
class Passage:
    """The plate and the moving shapes (see the module docstring).

    Attributes
    ----------
    plate_vertices : (V, 3) ndarray
    plate_faces : (F, 3) ndarray
    thickness : float
        Plate thickness T, scene units.
    gap : float
        Clearance above and below the plate at the ends of the motion, scene units.
    pieces : list of Piece
        Every A, then every B.
    """

    plate_vertices: np.ndarray
    plate_faces: np.ndarray
    thickness: float
    gap: float
    pieces: list

    def bounds(self) -> np.ndarray:
        """(2, 3) box around the plate and every shape over the whole motion, scene units."""
        lo, hi = self.plate_vertices.min(0), self.plate_vertices.max(0)
        for p in self.pieces:
            if p.keys is not None:
                placed = [p.vertices @ to_matrix(k[1:5]).T + k[5:] for k in p.keys]
            else:
                placed = [p.vertices + [0.0, 0.0, dz] for dz in (p.start, p.end)]
            for v in placed:
                lo, hi = np.minimum(lo, v.min(0)), np.maximum(hi, v.max(0))
        return np.array([lo, hi])


def surface_points(vertices: np.ndarray, faces: np.ndarray, n: int = 4) -> np.ndarray:
    """Points on every triangle: its corners and a barycentric lattice of ``n`` steps per edge.

    Returns a (K, 3) array (deterministic, no random sampling).
    """
    tri = vertices[faces]  # (F, 3, 3)
    ws = [(i / n, j / n, 1 - (i + j) / n) for i in range(n + 1) for j in range(n + 1 - i)]
    w = np.array(ws)  # (W, 3)
    return np.einsum("wk,fkc->fwc", w, tri).reshape(-1, 3)


def rest_offset(
    vertices: np.ndarray, faces: np.ndarray, hole, plate_box: np.ndarray
) -> float | None:
    """Height offset at which a posed shape rests on the plate, or None if it fits the hole.

    The shape comes down vertically; it stops when a point of its surface over the plate's
    material (outside the hole, inside the plate's xy box) reaches the plate's top z = 0. Points
    are :func:`surface_points` (a visual approximation of the contact, accurate to the mesh's
    triangle size / 4).

    Parameters
    ----------
    vertices : (V, 3) ndarray
        The posed shape, scene units.
    faces : (F, 3) ndarray
    hole : manifold3d.CrossSection
        The exact hole H.
    plate_box : (2, 2) ndarray
        The plate's xy box ``[[x0, y0], [x1, y1]]``.
    """
    pts = surface_points(vertices, faces)
    xy = pts[:, :2]
    over = np.all((xy >= plate_box[0]) & (xy <= plate_box[1]), axis=1) & ~Boundary(hole).inside(xy)
    if not over.any():
        return None
    return -float(pts[over, 2].min())


def build(result, plate_mesh=None) -> Passage:
    """The passage scene of a solve (:class:`sieve_mi.game.result.Result`).

    The plate is :func:`sieve_mi.outputs.fabrication.plate` with the thickness and border of the printed
    sieve (``sieve.stl``): ``plate_mesh``, the one the save already built
    (:func:`sieve_mi.outputs.fabrication.plate_files`), or built here when none was (no plate files).
    """
    from sieve_mi.outputs.fabrication import plate, plate_thickness

    thickness, _ = plate_thickness(result)
    if plate_mesh is None:
        plate_mesh = plate(result.outline, thickness, result.scene.fabrication.border).mesh
    pv = np.array(plate_mesh.vertices, dtype=np.float64)
    box = np.array([pv[:, :2].min(0), pv[:, :2].max(0)])
    size = float(np.max(pv.max(0) - pv.min(0)))
    gap = 0.15 * size
    pieces = []
    n = 1 + len(result.block_shapes)
    records = result.blocks  # each B's record: blocked after all, its thin-plate answer
    for i, shape in enumerate(result.pass_shapes):
        v = placed_vertices(shape, result.pass_quats[i], result.pass_trans[i])
        pieces.append(_falling(shape, "pass", i, v, thickness, gap, result.pass_trans[i]))
        pieces[-1].slot = (0.0, 1.0 / n)
    for j, shape in enumerate(result.block_shapes):
        q, t = result.attack.quats[0, j], result.attack.trans[0, j]
        v = placed_vertices(shape, q, t)
        piece = _falling(shape, "block", j, v, thickness, gap, t)
        piece.slot = ((j + 1) / n, (j + 2) / n)
        thin = records[j].thin_plate
        if thin is not None and thin.status == "passage":
            piece = _moving(shape, j, thin.poses, piece.slot)
        elif records[j].blocked:
            rest = rest_offset(v, shape.faces, result.outline, box)
            rest = (
                -float(v[:, 2].min()) if rest is None else rest
            )  # a sliver: rest on its lowest point
            piece.stop = (piece.start - rest) / (piece.start - piece.end)
            piece.end, piece.passes = rest, False
        pieces.append(piece)
    return Passage(pv, np.array(plate_mesh.faces, dtype=np.int64), float(thickness), gap, pieces)


def _moving(shape, index: int, poses: np.ndarray, slot: tuple) -> Piece:
    """A B that threads through a thin plate along a found motion ((k, 7) poses)."""
    reach = [segment_reach((a[:4], a[4:]), (b[:4], b[4:]), shape.radius)
             for a, b in zip(poses[:-1], poses[1:])]  # fmt: skip
    u = np.concatenate([[0.0], np.cumsum(reach)])
    u = u / u[-1] if u[-1] > 0 else np.linspace(0.0, 1.0, len(poses))
    return Piece(
        name=shape.name,
        role="block",
        index=index,
        vertices=np.asarray(shape.vertices, dtype=np.float64),
        faces=np.asarray(shape.faces, dtype=np.int64),
        start=float(poses[0, 6]),
        end=float(poses[-1, 6]),
        stop=1.0,
        passes=True,
        centre=np.asarray(poses[0, 4:6], dtype=np.float64).copy(),
        slot=slot,
        keys=np.column_stack([u, poses]),
    )


def _falling(shape, role: str, index: int, v: np.ndarray, thickness: float, gap: float, t) -> Piece:
    """A shape that goes all the way through: from ``gap`` above the plate to ``gap`` below it."""
    start = gap - float(v[:, 2].min())
    end = -thickness - gap - float(v[:, 2].max())
    return Piece(
        name=shape.name,
        role=role,
        index=index,
        vertices=v,
        faces=np.asarray(shape.faces, dtype=np.int64),
        start=start,
        end=end,
        stop=1.0,
        passes=True,
        centre=np.asarray(t, dtype=np.float64)[:2].copy(),
    )
