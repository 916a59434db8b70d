"""A pose in a maker's words: which way up a part is when it goes through a hole.

The hole lies in the xy plane and a part passes it along z, falling towards -z (the plates
sieve-mi writes span z in [-thickness, 0] and the shake trials' gravity is -z). A rotation q
(w, x, y, z, as everywhere in sieve-mi) turns the part about its centre; :func:`describe_pose`
says

* which of the part's extents stands *upright* (along the passage): its extents are measured
  along the principal axes of its convex hull (:func:`sieve_mi.geometry.canonical.principal_axes`,
  the frame of :func:`sieve_mi.geometry.size.canonical_extents`), and the axis that q turns
  closest to z is the upright one. The shortest extent upright is *face down* (lying flat), the
  middle one *on its side*, the longest *end on* (standing on its short end); extents within
  :data:`SAME_EXTENT` of each other count as one (a coin standing up is *on its side*, a cube is
  *any way up*). The *tilt* is the angle between that axis and z;
* how far the pose is from a *resting pose*, the way a part lies when it has settled on a flat
  plate: the angle between the body direction q points down and the nearest stable face's
  outward normal. The resting poses are trimesh's quasi-static ones
  (``trimesh.poses.compute_stable_poses``: the hull's faces over which the centre of mass lies,
  each with the share of random drops that topple onto it), not the principal-axis poses: a
  part resting on a plate is held by its hull and its centre of mass, and for a box the two
  agree, while for a wedge or a part with studs only the hull knows which faces it can rest on.
  With ``sigma=0`` the estimate is deterministic (the centre of mass is not sampled). Only the
  tilt counts: turning about z keeps a resting part resting. trimesh's estimate grows faster
  than the square of the hull's size (on the shared 2-core VM: a ball of 642 hull vertices
  0.6-2.8 s, of 2,562 32 s, of 10,242 113 s), so a hull of more than :data:`REST_VERTICES` vertices is first thinned to one vertex per cell
  of a grid (:func:`rest_points`): a hull inside the part's, within a cell's diagonal of it.
* the share of random drops that settle *showing the same silhouette*: the nearest resting
  face's share, plus that of every face in the same position whose silhouette is the same
  polygon turned and shifted in the plane (:func:`same_silhouette`). A brick lying studs up or
  studs down shows one rectangle, so both count; an S lying face up shows Ƨ, its mirror image,
  which no turn of an S-shaped hole admits, so only the S's own face counts (about 30 % of
  drops, not the 60 % that settle face down on either face).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from sieve_mi.geometry.canonical import principal_axes
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.rotations import normalize, to_matrix, to_rotvec

__all__ = [
    "POSITIONS",
    "REST_VERTICES",
    "SAME_EXTENT",
    "PoseWords",
    "describe_pose",
    "euler_xyz",
    "pose_sentence",
    "positions_of",
    "rest_points",
    "resting_poses",
    "same_silhouette",
    "silhouette_share",
]

#: Extents within this fraction of the larger one count as equal (a coin's rim polygon is a
#: fraction of a percent narrower one way than the other).
SAME_EXTENT = 0.02

#: The most hull vertices the resting poses are computed on (:func:`rest_points`).
REST_VERTICES = 256

#: Two silhouettes are the same polygon (:func:`same_silhouette`) when, turned and shifted onto
#: each other, their symmetric difference is at most this fraction of the area.
SAME_SILHOUETTE = 0.01

#: The named positions: which extent stands upright.
POSITIONS = ("face down", "on its side", "end on", "any way up")


@dataclass
class PoseWords:
    """One pose of a part, in words and angles.

    Attributes
    ----------
    position : str
        One of :data:`POSITIONS`: "face down" (shortest extent upright), "on its side" (the
        middle one, or a rod lying down, or one of a disc's two equal long ones), "end on" (the
        longest), "any way up" (three equal extents).
    gloss : str
        The same in other words, e.g. "standing on its short end".
    upright : float
        The extent that stands along the passage, scene units.
    extents : list of float
        The part's extents along its principal axes, largest first, scene units.
    tilt_deg : float
        Angle between the upright principal axis and the passage (z), degrees, 0 to 90.
    rest_deg : float or None
        Angle between this pose's down direction and the nearest resting pose's, degrees
        (None for a flat part, which has no resting poses).
    rest_position : str or None
        The nearest resting pose's position (one of :data:`POSITIONS`): named by the part's
        width along the face's normal, the extent it stands on that face (a hex nut resting
        on one of its flats is *on its side*, its across-flats width upright, whichever
        principal axis that flat's normal is nearest).
    rest_share : float or None
        The share of random drops that settle in that position showing the same silhouette up
        to a turn and a shift (quasi-static estimate, :func:`silhouette_share`: a brick lying
        studs up or studs down, both; an S face up, whose silhouette is the mirror image, not).
    position_share : float or None
        The share that settle in that position on any of its faces (both faces of an S).
    quaternion : list of float
        The rotation (w, x, y, z), w >= 0.
    euler_xyz_deg : list of float
        The same rotation as extrinsic angles about x, then y, then z, degrees (as a slicer's
        rotate tool takes them; near a quarter turn about y the x and z angles are ill-defined).
    turn_deg : float
        The same rotation as one turn: its angle, degrees, 0 to 180 ...
    turn_axis : list of float
        ... about this unit axis (x, y, z) ([0, 0, 1] for no turn).
    """

    position: str
    gloss: str
    upright: float
    extents: list
    tilt_deg: float
    rest_deg: float | None
    rest_position: str | None
    rest_share: float | None
    position_share: float | None
    quaternion: list
    euler_xyz_deg: list
    turn_deg: float
    turn_axis: list

    @property
    def words(self) -> str:
        """The position with its gloss, e.g. "end on (standing on its short end)"."""
        return f"{self.position} ({self.gloss})"

    def sentence(self, units: str = "mm") -> str:
        """One line for a maker (:func:`pose_sentence`)."""
        return pose_sentence(self.to_dict(), units)

    def to_dict(self) -> dict:
        """The fields and :attr:`words`, JSON-ready."""
        return {**asdict(self), "words": self.words}


def pose_sentence(pose: dict, units: str = "mm") -> str:
    """One line for a maker from :meth:`PoseWords.to_dict`'s dict (as check's report.json holds
    it): the position, the upright extent, the tilt and the nearest resting pose.

    Examples
    --------
    >>> print(pose_sentence({"words": "end on (standing on its short end)", "upright": 15.8,
    ...     "tilt_deg": 1.24, "rest_deg": 1.24, "rest_position": "end on", "rest_share": 0.16}))
    end on (standing on its short end): its 15.8 mm extent upright, tilted 1.2°; 1.2° from resting end on (about 16 % of random drops settle end on)

    Where the position's other faces show another silhouette (an S face up shows its mirror
    image), the sentence says both shares:

    >>> print(pose_sentence({"words": "face down (lying flat)", "upright": 12.0, "tilt_deg": 0.0,
    ...     "rest_deg": 0.0, "rest_position": "face down", "rest_share": 0.299,
    ...     "position_share": 0.598}))
    face down (lying flat): its 12 mm extent upright; 0.0° from resting face down (about 30 % of random drops settle face down showing this silhouette, 60 % face down on any face)
    """
    out = f"{pose['words']}: its {pose['upright']:.4g} {units} extent upright"
    out += f", tilted {pose['tilt_deg']:.1f}°" if pose["tilt_deg"] >= 0.05 else ""
    if pose["rest_deg"] is None:
        return out + "; a flat part has no resting pose"
    where, share = pose["rest_position"], _percent(pose["rest_share"])
    out = f"{out}; {pose['rest_deg']:.1f}° from resting {where} (about {share} of random drops"
    whole = pose.get("position_share")  # absent from report.json files of before 2026-12-04
    if whole is None or _percent(whole) == share:
        return f"{out} settle {where})"
    return f"{out} settle {where} showing this silhouette, {_percent(whole)} {where} on any face)"


def _percent(share: float) -> str:
    return f"{100 * share:.0f} %" if share >= 0.005 else "under 1 %"


def euler_xyz(quat) -> np.ndarray:
    """Extrinsic x-y-z Euler angles of a rotation (w, x, y, z), degrees, (3,): the rotation is
    a turn about x, then about y, then about z (scipy's ``as_euler("xyz")``)."""
    import warnings

    from scipy.spatial.transform import Rotation

    w, x, y, z = normalize(quat)
    with warnings.catch_warnings():  # a quarter turn about y: gimbal lock, the z angle set to 0
        warnings.simplefilter("ignore", UserWarning)
        return Rotation.from_quat([x, y, z, w]).as_euler("xyz", degrees=True)


def _frame(shape: Shape) -> tuple[np.ndarray, np.ndarray]:
    """Principal axes (3, 3), one per row, and the hull's extent along each (3,), scene units."""
    axes = principal_axes(shape)
    proj = shape.hull @ axes.T
    return axes, proj.max(axis=0) - proj.min(axis=0)


def _position(extents: np.ndarray, k: int) -> tuple[str, str]:
    """The position and its gloss for a part whose extent ``k`` (of ``extents``, any order)
    stands upright."""
    big = float(extents.max())
    same = np.abs(extents - extents[k]) <= SAME_EXTENT * max(big, 1e-300)
    longer = int(np.sum((extents > extents[k]) & ~same))
    if same.sum() == 3:
        return "any way up", "its three extents are equal"
    if same.sum() == 2 and longer:  # a rod's short extent (or a cylinder's diameter) upright
        return "on its side", "lying along its length"
    if same.sum() == 2:  # one of a disc's (a coin's, a square brick's) two long extents upright
        return "on its side", "one of its two equal long extents upright"
    glosses = ("standing on its short end", "its middle extent upright", "lying flat")
    return ("end on", "on its side", "face down")[longer], glosses[longer]


def _upright(axes: np.ndarray, extents: np.ndarray, down: np.ndarray) -> tuple[int, float]:
    """Index of the principal axis closest to ``down`` (body frame, unit) and its angle, degrees.

    Equal extents (within :data:`SAME_EXTENT`) make their axes interchangeable: the angle is then
    measured from the plane (or all directions) they span.
    """
    cos = np.abs(axes @ down)
    k = int(np.argmax(cos))
    same = np.abs(extents - extents[k]) <= SAME_EXTENT * max(float(extents.max()), 1e-300)
    c = min(1.0, float(np.linalg.norm(cos[same])))  # the part of down in the tied axes' span
    return k, float(np.degrees(np.arccos(c)))


def rest_points(points: np.ndarray, limit: int = REST_VERTICES) -> np.ndarray:
    """At most ``limit`` of the hull's vertices for the resting-pose estimate.

    Parameters
    ----------
    points : (N, 3) ndarray
        The hull's vertices, scene units.
    limit : int
        The most points returned.

    Returns
    -------
    (M, 3) ndarray
        ``points`` itself when N <= limit; else one point per occupied cell of the finest grid
        of cubes (side: the bounding box's longest side over 64, 48, ... 4) that keeps at most
        ``limit``, else of the coarsest. Their hull lies inside the points' hull, and every
        point is within a cell's diagonal of a kept one.
    """
    if len(points) <= limit:
        return points
    lo = points.min(axis=0)
    size = max(float(np.ptp(points, axis=0).max()), 1e-300)
    for k in (64, 48, 32, 24, 16, 12, 8, 6, 4):
        keys = np.floor((points - lo) / (size / k)).astype(np.int64)
        kept = points[np.sort(np.unique(keys, axis=0, return_index=True)[1])]
        if len(kept) <= limit:
            break
    return kept


def positions_of(shape: Shape, downs: np.ndarray) -> list[str]:
    """The position (one of :data:`POSITIONS`) of the resting poses whose down directions (body
    frame, unit, (K, 3)) are ``downs``, named as :func:`describe_pose` names them (the part's
    width along each)."""
    extents = _frame(shape)[1]
    return _rest_positions(shape, extents, np.atleast_2d(downs))


def resting_poses(shape: Shape) -> tuple[np.ndarray, np.ndarray] | None:
    """The part's resting poses on a flat plate: each one's down direction and share of drops.

    Returns
    -------
    (normals, shares) or None
        ``normals`` (R, 3): unit outward normals of the hull faces it rests on, in the shape's
        frame (the body direction that points down); ``shares`` (R,): the quasi-static share
        of random drops that settle on each (trimesh ``compute_stable_poses``, sigma 0), summing
        to 1. None for a flat part, or one whose centre of mass is not inside its hull. A hull
        of more than :data:`REST_VERTICES` vertices is thinned first (:func:`rest_points`).
    """
    import warnings

    import trimesh
    from trimesh.poses import compute_stable_poses

    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")  # trimesh warns about flat hulls; checked below
            hull = trimesh.convex.convex_hull(rest_points(shape.hull))
            flat = not hull.volume > 1e-9 * max(shape.radius, 1e-300) ** 3
    except Exception:  # noqa: BLE001 - a flat or degenerate point set has no 3D hull
        return None
    if flat:
        return None
    mesh = trimesh.Trimesh(shape.vertices, shape.faces, process=False)
    com = mesh.center_mass if mesh.is_volume else hull.center_mass
    if not np.all(np.einsum("ij,ij->i", com - hull.triangles_center, hull.face_normals) < 0):
        return None  # trimesh would sample for ever
    tfs, shares = compute_stable_poses(hull, center_mass=com, sigma=0.0, n_samples=1, seed=0)
    # each transform puts its face down: row 2 of its rotation is minus that face's normal
    return -np.asarray(tfs)[:, 2, :3], np.asarray(shares, dtype=np.float64)


def _rest_positions(shape: Shape, extents: np.ndarray, normals: np.ndarray) -> list[str]:
    """The position of each resting pose (``normals`` (R, 3), unit, body frame): the part's
    width along the normal (its hull's, scene units) matched to the nearest of ``extents``."""
    proj = shape.hull @ normals.T
    widths = proj.max(axis=0) - proj.min(axis=0)
    nearest = np.argmin(np.abs(widths[:, None] - extents[None, :]), axis=1)
    return [_position(extents, int(k))[0] for k in nearest]


def describe_pose(shape: Shape, quat) -> PoseWords:
    """Name the pose ``quat`` of ``shape`` (see the module's notes).

    Parameters
    ----------
    shape : Shape
        The part, scene units.
    quat : (4,) array_like
        Its rotation (w, x, y, z) about its centre, as check and solve report it.

    Returns
    -------
    PoseWords

    Examples
    --------
    A 2 x 4 x 8 box turned a quarter turn about y stands its 8 extent along z: end on.

    >>> import numpy as np, trimesh
    >>> from sieve_mi.geometry.meshes import shape_from_trimesh
    >>> box = shape_from_trimesh(trimesh.creation.box((8, 4, 2)), name="box")
    >>> describe_pose(box, [np.cos(np.pi / 4), 0, np.sin(np.pi / 4), 0]).position
    'end on'
    """
    q = normalize(np.asarray(quat, dtype=np.float64))
    down = to_matrix(q).T @ np.array([0.0, 0.0, -1.0])  # the body direction pointing down
    axes, extents = _frame(shape)
    k, tilt = _upright(axes, extents, down)
    rest_deg = rest_position = rest_share = position_share = None
    rest = resting_poses(shape)
    if rest is not None:
        normals, shares = rest
        i = int(np.argmax(normals @ down))
        rest_deg = float(np.degrees(np.arccos(np.clip(normals[i] @ down, -1.0, 1.0))))
        named = _rest_positions(shape, extents, normals)
        rest_position = named[i]
        position_share = float(sum(p for p, n in zip(shares, named) if n == rest_position))
        rest_share = silhouette_share(shape, normals, shares, named, i)
    position, gloss = _position(extents, k)
    rotvec = to_rotvec(q)
    angle = float(np.linalg.norm(rotvec))
    axis = rotvec / angle if angle > 1e-12 else np.array([0.0, 0.0, 1.0])
    return PoseWords(
        position=position,
        gloss=gloss,
        upright=float(extents[k]),
        extents=[float(e) for e in np.sort(extents)[::-1]],
        tilt_deg=tilt,
        rest_deg=rest_deg,
        rest_position=rest_position,
        rest_share=rest_share,
        position_share=position_share,
        quaternion=[float(x) for x in q],
        euler_xyz_deg=[float(a) + 0.0 for a in euler_xyz(q)],  # + 0.0: no -0.0
        turn_deg=float(np.degrees(angle)),
        turn_axis=[float(a) + 0.0 for a in axis],
    )


def _moments(section) -> tuple[float, np.ndarray, np.ndarray]:
    """Area, centroid (2,) and central second moments (2, 2) (∫ x x^T dA about the centroid) of
    a CrossSection, from its contours (holes wound the other way subtract)."""
    loops = [np.asarray(c, dtype=np.float64) for c in section.to_polygons()]
    if not loops:
        return 0.0, np.zeros(2), np.zeros((2, 2))
    ref = np.concatenate(loops).mean(axis=0)  # about a point near the polygon: less rounding
    area, first, second = 0.0, np.zeros(2), np.zeros((2, 2))
    for loop in loops:
        a = loop - ref
        b = np.roll(a, -1, axis=0)
        cross = a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1]
        area += cross.sum() / 2.0
        first += ((a + b) * cross[:, None]).sum(axis=0) / 6.0
        sxx = ((a[:, 0] ** 2 + a[:, 0] * b[:, 0] + b[:, 0] ** 2) * cross).sum() / 12.0
        syy = ((a[:, 1] ** 2 + a[:, 1] * b[:, 1] + b[:, 1] ** 2) * cross).sum() / 12.0
        sxy = ((a[:, 0] * b[:, 1] + 2 * a[:, 0] * a[:, 1] + 2 * b[:, 0] * b[:, 1]
                + b[:, 0] * a[:, 1]) * cross).sum() / 24.0  # fmt: skip
        second += np.array([[sxx, sxy], [sxy, syy]])
    c = first / area
    return float(area), ref + c, second - area * np.outer(c, c)


def same_silhouette(p, q, tol: float = SAME_SILHOUETTE) -> bool:
    """Whether two polygons are the same up to a turn and a shift in the plane (no mirroring).

    Both are moved to their centroids. Where the second moments have two distinct principal
    axes (anisotropy over 5 %), a turn taking one polygon onto the other takes its major axis
    onto the other's: the two turns that do (0° and 180° apart) are tried. Otherwise every
    whole degree is tried, and the best refined to a hundredth of a degree. The polygons are
    the same when the symmetric difference at the best turn is at most ``tol`` of the area;
    the first turn tried that is within ``tol`` decides (the best is at least as good).

    Parameters
    ----------
    p, q : manifold3d.CrossSection
        Scene units.
    tol : float
        Fraction of the area.

    Returns
    -------
    bool
    """
    (ap, cp, mp), (aq, cq, mq) = _moments(p), _moments(q)
    if ap <= 0.0 or abs(ap - aq) > tol * ap:
        return False
    (lp, vp), (lq, vq) = np.linalg.eigh(mp), np.linalg.eigh(mq)
    spread = abs(lp[1] - lp[0]) / max(lp.sum(), 1e-300)
    if abs(spread - abs(lq[1] - lq[0]) / max(lq.sum(), 1e-300)) > tol:
        return False
    p0, q0 = p.translate([-cp[0], -cp[1]]), q.translate([-cq[0], -cq[1]])

    def off(turn: float) -> float:  # the symmetric difference's area (``^`` intersects)
        return ap + aq - 2.0 * float((p0.rotate(turn) ^ q0).area())

    # Each refinement's turns include the previous best, so the best turn found is at least as
    # good as every turn tried: the first turn within ``tol`` already decides "the same".
    limit = tol * ap
    if spread > 0.05:
        major = np.degrees(np.arctan2(vq[1, 1], vq[0, 1]) - np.arctan2(vp[1, 1], vp[0, 1]))
        return off(major) <= limit or off(major + 180.0) <= limit
    turns = np.arange(360.0)
    for step in (1.0, 0.1, 0.01):
        values = []
        for t in turns:
            values.append(off(t))
            if values[-1] <= limit:
                return True
        at = float(turns[int(np.argmin(values))])
        turns = at + step * np.arange(-10, 11) / 10.0
    return False


def silhouette_share(shape: Shape, normals: np.ndarray, shares: np.ndarray, positions: list,
                     k: int) -> float:  # fmt: skip
    """The share of random drops that settle showing rest pose ``k``'s silhouette up to a turn
    and a shift: its own share and that of each rest pose in the same position (``positions``)
    whose silhouette :func:`same_silhouette` finds the same (an S's other face shows its mirror
    image: not counted).

    Parameters
    ----------
    shape : Shape
    normals : (R, 3) ndarray
        The rest poses' down directions (body frame, unit), as :func:`resting_poses` gives them.
    shares : (R,) ndarray
        Their shares of random drops.
    positions : list of str
        Their positions (:func:`positions_of`).
    k : int
        The rest pose asked about.

    Returns
    -------
    float
    """
    from sieve_mi.geometry.outline import silhouette
    from sieve_mi.geometry.rotations import align

    def seen(i: int):
        return silhouette(shape, align(normals[i], [0.0, 0.0, -1.0]), [0.0, 0.0])

    own = seen(k)
    total = float(shares[k])
    for j, where in enumerate(positions):
        if j != k and where == positions[k] and same_silhouette(own, seen(j)):
            total += float(shares[j])
    return total
