"""Groups of a lattice's sites that a set of bounded diameter can touch together.

The proofs on a perforated sheet (:meth:`sieve_mi.geometry.pattern.Pattern.patches`) need, up to
lattice moves, every largest group of copies pairwise close enough for one set to touch them all:
the maximal cliques of the graph joining sites at most a given distance apart.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["cliques", "sites_within"]


def sites_within(a1, a2, radius: float) -> list[tuple[int, int]]:
    """Lattice indices (i, j) with ``|i a1 + j a2| <= radius``, (0, 0) first."""
    basis = np.column_stack([a1, a2])
    inverse_norm = np.linalg.norm(np.linalg.inv(basis), 2)  # |(i, j)| <= this * |x|
    m = int(math.ceil(radius * inverse_norm)) + 1
    out = [(0, 0)]
    for i in range(-m, m + 1):
        for j in range(-m, m + 1):
            if (i, j) != (0, 0) and np.linalg.norm(i * a1 + j * a2) <= radius:
                out.append((i, j))
    return out


def cliques(a1, a2, near: float, symmetric: bool = False) -> list[list[tuple[int, int]]]:
    """The maximal cliques of sites through (0, 0), two sites joined when their positions are
    at most ``near`` apart, one of each class under lattice translation (and the half turn
    (i, j) -> (-i, -j) where ``symmetric``) and none that such a move of another contains; each
    as a list of (i, j), (0, 0) first.

    Examples
    --------
    On a hexagonal lattice of unit pitch with only nearest neighbours joined, the groups are
    the two triangles (pointing up and down):

    >>> import numpy as np
    >>> sorted(len(g) for g in cliques(np.array([1.0, 0]), np.array([0.5, 0.866]), 1.01))
    [3, 3]

    and the one triangle up to a half turn:

    >>> cliques(np.array([1.0, 0]), np.array([0.5, 0.866]), 1.01, symmetric=True)
    [[(0, 0), (0, 1), (1, 0)]]
    """
    import networkx as nx

    sites = sites_within(a1, a2, near)  # a clique through (0, 0) lies within ``near`` of it
    pos = {s: s[0] * np.asarray(a1) + s[1] * np.asarray(a2) for s in sites}
    graph = nx.Graph()
    graph.add_nodes_from(sites)
    for m, s in enumerate(sites):
        for t in sites[m + 1 :]:
            if np.linalg.norm(pos[s] - pos[t]) <= near:
                graph.add_edge(s, t)
    found = []
    for clique in nx.find_cliques(graph):
        if (0, 0) not in clique:
            continue
        lo = min(clique)
        found.append(frozenset((i - lo[0], j - lo[1]) for i, j in clique))
    found = sorted(set(found), key=lambda c: (-len(c), sorted(c)))
    kept = []
    for c in found:
        moves = [c, frozenset((-i, -j) for i, j in c)] if symmetric else [c]
        if not any(
            {(i - min(m)[0] + s[0], j - min(m)[1] + s[1]) for i, j in m} <= k
            for m in moves
            for k in kept
            for s in k
        ):
            kept.append(c)
    return [sorted(c, key=lambda s: (s != (0, 0), s)) for c in kept]
