"""Geometry of shapes, rasters and holes. Rule: geometry knows nothing of the game.

Modules
-------
rotations
    Unit quaternions (w, x, y, z): products, matrices, axis-angle, alignment.
meshes
    Reading meshes into :class:`~sieve_mi.geometry.meshes.Shape` (vertices, faces, radius).
plate
    The plate as solid geometry: B's diameter (the safe thickness), an exact convex decomposition.
pattern
    A perforated sheet: copies of the hole on a square or hexagonal lattice, the web between
    them checked exactly, and the copies within a shape's reach for the proofs.
solid
    Exact point queries against a triangle mesh: distances to its triangles, winding numbers.
cliques
    Groups of a lattice's sites that one set of bounded diameter can touch together (maximal
    cliques up to lattice moves), for the proofs on a sheet.
pixels
    A raster image's physical pixel size: PNG's ``pHYs`` chunk, written and read.
raster
    :class:`~sieve_mi.geometry.raster.Frame`: the square pixel lattice a hole is drawn on.
outline
    Exact polygons (manifold3d): projections, silhouettes, offsets, unions, signed distances
    (:class:`~sieve_mi.geometry.outline.Boundary`), the hole polygon H.
canonical
    Canonical views of a shape: principal axes, thinnest and largest faces.
silhouettes
    Raster silhouettes rendered with Mitsuba (ray casting, the ``silhouette`` integrator).
hole
    Raster holes (:class:`~sieve_mi.geometry.hole.Hole`, stacks, distance fields).
sieve
    Reading a given plate mesh once: its through-holes along an axis and the slab around them
    (the thickness proofs use), for ``check``, ``certify`` and ``shake``.
hole_image
    Reading a given hole image: its hole pixels, and its holes on a frame (``check --hole``).
pose_words
    A pose in a maker's words: which extent stands upright (end on, on its side, face down),
    its tilt, how far from a resting pose.
size
    Size measures: canonical extents, passage and end-first radii (the cascade's order and rules).
bodies
    What the exact containment rules need of a shape (hull, axes, inscribed ball, convexity).
containment
    The least growth of one shape's hull that holds another (the feasibility test's proof).
window
    The turning window's hole: every A at each turn within ±δ, with a chord bound.
stand_in
    A closed mesh simplified within a tolerance (Manifold's edge collapses): player A's search
    plays it, the verdict the full mesh.
congruence
    Whether two raster holes are one up to a rotation, mirror and shift of the plane (within a
    fraction of a pixel), and that motion; shapes' poses moved with it.
"""

__all__ = [
    "bodies",
    "canonical",
    "congruence",
    "containment",
    "hole",
    "hole_image",
    "meshes",
    "outline",
    "pose_words",
    "raster",
    "rotations",
    "sieve",
    "silhouettes",
    "size",
]
