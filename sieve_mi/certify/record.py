"""A certificate's dictionary, assembled from what a search found (format: :mod:`sieve_mi.certify.certificate`).

:func:`build` makes the certificate of a straight search (the cell tree or the ball at its root),
:func:`certificate_entry` the ``section`` entry of a slab-section search; both renumber the
evidence's points into the few the certificate stores.
"""

from __future__ import annotations

import json
import os
from typing import NamedTuple

import numpy as np

from sieve_mi.certify.certificate import FORMAT, mesh_hash, scope
from sieve_mi.geometry.meshes import Shape

__all__ = ["Evidence", "build", "certificate_entry", "tree_to_dict"]


def tree_to_dict(node) -> dict:
    """A search :class:`~sieve_mi.certify.search.Node` as a certificate node."""
    if node.children:
        return {"c": [tree_to_dict(c) for c in node.children]}
    if node.evidence is not None:
        return {"e": node.evidence}
    return {"open": True}


class Evidence(NamedTuple):
    """What a certificate's status rests on.

    Attributes
    ----------
    symmetry : str
        The shape's symmetry group the rotations were reduced by ("none" when not used).
    root : dict or None
        The ball proof at the root (``kind``, ``centre``, ``radius``), or None.
    outcome : object or None
        The cell search's outcome (roots, points used, candidates, passage), or None.
    """

    symmetry: str
    root: dict | None
    outcome: object


def build(
    shape: Shape,
    contours: list,
    status: str,
    evidence: Evidence,
    settings,
    scale: float = 1.0,
    diameter: float | None = None,
) -> dict:
    """The certificate dictionary (format in the module docstring); ``diameter`` (scene units)
    gives its ``plate`` entry (the thickness is set by :meth:`Certification.on_plate`).

    Point indices in the evidence are renumbered into ``shape.points``.
    """
    symmetry, root, outcome = evidence
    used = sorted(outcome.points) if outcome is not None else []
    renumber = {old: new for new, old in enumerate(used)}
    vertices = shape.vertices[np.unique(shape.faces)]
    if outcome is not None and outcome.candidates is not None:
        vertices = outcome.candidates
    on_edge = [outcome.on_edge.get(u) for u in used] if outcome is not None else []

    def renum(node: dict) -> dict:
        if "c" in node:
            return {"c": [renum(c) for c in node["c"]]}
        if "e" in node:
            e = dict(node["e"])
            e["points"] = [renumber[p] for p in e["points"]]
            return {"e": e}
        return node

    tree = [renum(tree_to_dict(n)) for n in outcome.roots] if outcome is not None else []
    return {
        "format": FORMAT,
        "status": status,
        "shape": {
            "name": shape.name,
            "path": os.path.abspath(shape.path) if shape.path else "",
            "scale": scale,
            "sha256": mesh_hash(shape),
            "vertices": shape.vertices.tolist(),
            "faces": shape.faces.tolist(),
            "points": vertices[used].tolist(),
            "on_edge": on_edge,
        },
        "hole": [np.asarray(c, dtype=np.float64).tolist() for c in contours],
        "symmetry": symmetry,
        "root": root,
        "tree": tree,
        "settings": {
            "kappa": settings.kappa,
            "directions": settings.directions,
            "bound": settings.bound,
        },
        "passage": outcome.passage if outcome is not None else None,
        "plate": {
            "thickness": None,
            "diameter": diameter,
            "holds_for": scope(status, "ball" if root is not None else "cells"),
        },
    }


def certificate_entry(out, points: np.ndarray, on_edge: dict, kappa: float, loops=()) -> dict:
    """The certificate's ``section`` entry of a section search's outcome
    (:class:`~sieve_mi.certify.section.SectionOutcome`): pin, thickness, band, the points the
    evidence uses (renumbered), where they lie on the mesh, the tree over directions, and the
    link test's loops (each (m, 3) vertices, :mod:`~sieve_mi.certify.link`) where a leaf uses
    them."""
    used = sorted(out.points)
    renumber = {old: new for new, old in enumerate(used)}

    def renum(node: dict) -> dict:
        if "c" in node:
            return {"c": [renum(c) for c in node["c"]]}
        if "e" not in node:
            return node
        e = dict(node["e"])
        key = "pair" if e["kind"] == "diameter" else "points"
        e[key] = [renumber[p] for p in e[key]]
        return {"e": e}

    entry = {
        "status": out.status,
        "pin": [float(c) for c in out.pin],
        "thickness": float(out.thickness),
        "band": 0.5 * float(out.thickness),
        "kappa": float(kappa),
        "points": points[used].tolist(),
        "on_edge": [on_edge.get(u) for u in used],
        "tree": [renum(n.to_dict()) for n in out.roots],
    }
    if len(loops) and '"kind": "link"' in json.dumps(entry["tree"]):
        entry["loops"] = [np.asarray(q, dtype=np.float64).tolist() for q in loops]
    return entry
