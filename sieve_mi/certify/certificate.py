"""The result of a certification and its certificate file (JSON).

Certificate format (``"format": "sieve-mi-certificate/1"``; lengths in scene units):

* ``shape``: ``path``, ``scale``, the centred mesh (``vertices`` (V, 3), ``faces`` (F, 3)), its
  ``sha256`` (see :func:`mesh_hash`; the replay compares it with the file at ``path`` when that
  exists), ``points``: the (k, 3) points the evidence refers to by index, and ``on_edge``: per
  point null (a vertex) or ``[i, j, lam]`` (the point v_i + lam (v_j - v_i) on the mesh edge
  (i, j), 0 <= lam <= 1; only with symmetry "none").
* ``hole``: the contours of H (list of (m, 2) lists; outer counter-clockwise, holes clockwise).
* ``symmetry``: ``"none"``, ``"klein"`` or ``"octahedral"``: the domain searched (module
  :mod:`sieve_mi.certify.symmetry`).
* ``root``: ``{"kind": "ball", "centre", "radius"}`` when the shape is blocked for all rotations at
  once, else null.
* ``tree``: one node per domain face, in order; a node is ``{"e": evidence}`` (an excluded leaf),
  ``{"c": [8 nodes]}`` (split into octants: child c takes the upper half of component j iff bit
  (2 - j) of c is set) or ``{"open": true}``. Evidence is ``{"kind": "width", "direction": m,
  "points": [...]}`` (direction m of ``directions`` unit vectors over a half circle) or
  ``{"kind": "translations", "points": [...]}``.
* ``settings``: ``kappa`` (slack, see :class:`~sieve_mi.certify.search.Settings`), ``directions``,
  ``bound``: ``"first-order"`` (each point's displacement bound over a cell is the smaller of the
  first-order bound and 2 sin(theta) |p|; docs/certify.md) or ``"isotropic"`` (2 sin(theta) |p|
  only; certificates without ``bound`` were written before the first-order bound and mean this).
* ``status`` and ``passage`` (quaternion, translation) as found: the answer for *straight*
  passage (the shape translated along the hole's axis), the paper's model.
* ``plate``: what that answer covers: ``diameter``, ``holds_for`` (:data:`ANY_PLATE`,
  :data:`THICK_PLATES`, :data:`SECTION_PLATES` or null), the asked ``thickness``; the replay recomputes the diameter and rejects a ``holds_for`` the evidence does not give.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from dataclasses import dataclass, field

from sieve_mi.errors import SieveError
from sieve_mi.geometry.meshes import Shape, mesh_sha256
from sieve_mi.geometry.plate import LENGTH_SLACK

__all__ = [
    "ANY_PLATE",
    "Certification",
    "FORMAT",
    "MAX_CERTIFICATE_BYTES",
    "REQUIRED",
    "SECTION_PLATES",
    "excluded_percent",
    "is_certificate",
    "mesh_hash",
    "read_certificate_file",
    "scope",
    "writable_certificate",
]

FORMAT = "sieve-mi-certificate/1"

#: ``holds_for`` of a ball proof or a straight passage: a plate of any thickness.
ANY_PLATE = "any plate"
#: ``holds_for`` of a cell-tree proof: the thick-plate argument (docs/certify.md, "The claim").
THICK_PLATES = "plates at least the diameter thick"
#: ``holds_for`` of a proof with a slab-section proof (``section``): plates at least the
#: section's thickness thick (docs/certify.md, "Thin plates").
SECTION_PLATES = "plates at least the section's thickness thick"
#: The straight answers a proved section completes: a proof by cells, or cells left open.
STRAIGHT_OPEN = ("proved", "undecided")


def excluded_percent(fraction: float, complete: bool, digits: int = 2) -> str:
    """``fraction`` as a percentage with ``digits`` decimals, rounded down: "100" only for a
    ``complete`` search (every cell excluded), so an undecided run never reads "100.00".

    Examples
    --------
    >>> excluded_percent(0.9999977, False), excluded_percent(1.0, False)
    ('99.99', '99.99')
    >>> excluded_percent(0.9999999999, True), excluded_percent(0.123456, False, 1)
    ('100.00', '12.3')
    """
    if complete:
        return f"{100:.{digits}f}"
    scale = 10**digits
    steps = math.floor(round(100 * scale * max(float(fraction), 0.0), 6))  # 0.29 is 28.999...
    shown = min(steps, 100 * scale - 1) / scale
    return f"{shown:.{digits}f}"


def scope(status: str, method: str) -> str | None:
    """What a straight-passage answer covers: :data:`ANY_PLATE` for a ball proof or a passage,
    :data:`THICK_PLATES` for a cell-tree proof, None for an undecided run (nothing is claimed).

    Examples
    --------
    >>> scope("proved", "ball"), scope("passage", "cells")
    ('any plate', 'any plate')
    >>> scope("proved", "cells"), scope("undecided", "cells")
    ('plates at least the diameter thick', None)
    """
    if status == "passage" or (status == "proved" and method == "ball"):
        return ANY_PLATE
    return THICK_PLATES if status == "proved" else None


def mesh_hash(shape: Shape) -> str:
    """SHA-256 of the shape's centred vertices (float64) and faces (int64), hex."""
    return mesh_sha256(shape.vertices, shape.faces)


@dataclass
class Certification:
    """Whether a shape can pass a hole, with the evidence.

    Attributes
    ----------
    status : str
        ``"proved"`` (no rotation and translation lets it through), ``"passage"`` (a pose that
        fits was found) or ``"undecided"`` (the budget or the smallest cell size was reached, or,
        after :meth:`on_plate`, a straight proof that does not cover the plate's thickness).
    seconds : float
    method : str
        ``"ball"`` (root-level inscribed-ball test) or ``"cells"`` (branch and bound).
    cells_examined, cells_excluded, cells_open : int
    excluded_fraction : float
        Excluded share of the searched rotation domain, measured by volume in face coordinates.
    depth : int
        Levels of the cell tree.
    symmetry : str
        Symmetry group used to shrink the domain.
    passage : dict or None
        ``quaternion`` (w, x, y, z) about the shape's centre and ``translation`` (x, y) in the
        hole's frame, scene units.
    margin : float or None
        A proved margin m >= 0, scene units: the shape is also proved blocked by the hole grown
        by m, so every pose sticks out of the hole by more than m (:func:`prove_margin`; None when
        not tried or not proved).
    margin_certificate : dict
        The certificate of that proof against the grown hole (empty when m = 0 or None).
    margin_steps : int
        Steps of the margin bisection that ran (0: the margin was not bisected).
    straight : str or None
        The answer for straight passage (the search's status, the paper's model).
    holds_for : str or None
        What the claim covers (:func:`scope`): :data:`ANY_PLATE`, :data:`THICK_PLATES`,
        :data:`SECTION_PLATES` (a proved slab section, :meth:`with_section`, also beside an
        undecided ``straight``) or None (undecided).
    diameter : float or None
        The shape's diameter, scene units.
    thickness : float or None
        The plate's thickness (:meth:`on_plate`), scene units; None for an outline without a
        plate, or a plate whose thickness could not be measured (then ``plate_note`` says why).
    plate_note : str
        Why the plate's thickness is unknown (empty otherwise).
    section : dict or None
        The slab-section proof tried on a plate thinner than the diameter, or after a straight
        search that left cells open (:meth:`with_section`): ``status``, ``thickness``, ``pin``,
        ``seconds``, ``cells_examined``, ``cells_excluded``, ``cells_open``; None when none was
        tried.
    """

    status: str
    seconds: float
    method: str
    cells_examined: int = 0
    cells_excluded: int = 0
    cells_open: int = 0
    excluded_fraction: float = 0.0
    depth: int = 0
    symmetry: str = "none"
    passage: dict | None = None
    certificate: dict = field(default_factory=dict, repr=False)
    margin: float | None = None
    margin_certificate: dict = field(default_factory=dict, repr=False)
    margin_steps: int = 0
    straight: str | None = None
    holds_for: str | None = None
    diameter: float | None = None
    thickness: float | None = None
    plate_note: str = ""
    section: dict | None = None

    @property
    def proved_section(self) -> dict | None:
        """The ``section`` entry when it is a proof that counts: a proved section, whether the
        straight search proved or left cells open (None otherwise; never beside a passage).

        A section proof at t shows that no rigid motion carries the shape through a plate at
        least t thick. A straight passage (a pose whose projection fits H, translated along the
        vertical) would pass every plate, so the section proof excludes straight passage too: it
        is a complete proof on plates at least t thick, even when the cell tree has open cells.
        """
        s = self.section
        ok = s is not None and s["status"] == "proved" and self.straight in STRAIGHT_OPEN
        return s if ok else None

    @property
    def by_section(self) -> bool:
        """Whether the proof rests on the slab-section proof alone: a proved section where the
        straight search left cells open (its excluded share is then short of 100 %)."""
        return self.proved_section is not None and self.straight != "proved"

    @property
    def covers_plate(self) -> bool | None:
        """Whether ``straight`` holds on the plate: None without a plate (:meth:`on_plate` not
        called) or when nothing is claimed (undecided); False for a cell-tree proof on a plate
        thinner than the diameter (lengths within ``LENGTH_SLACK`` count as equal, as for the
        thin-plate verdict) or of unknown thickness."""
        if (self.thickness is None and not self.plate_note) or self.holds_for is None:
            return None
        if self.holds_for == ANY_PLATE:
            return True
        if self.holds_for == SECTION_PLATES:
            need = self.section["thickness"]
            return self.thickness is not None and self.thickness + LENGTH_SLACK >= need
        return (
            self.thickness is not None
            and self.diameter is not None
            and self.thickness + LENGTH_SLACK >= self.diameter
        )

    def on_plate(self, thickness: float | None, note: str = "") -> Certification:
        """This answer judged on a plate of ``thickness`` (None: not measured, ``note`` says why).

        A straight proof that holds only for plates at least the shape's diameter thick
        (:data:`THICK_PLATES`, a cell tree) becomes ``"undecided"`` on a thinner plate, or one of
        unknown thickness: a tilted passage is not excluded. A ball proof and a passage keep
        their status (they hold on any plate). A proved section (:data:`SECTION_PLATES`)
        makes it "proved" on plates at least the section's thickness, "undecided" on thinner
        ones, whatever ``straight`` says (short of a passage). The certificate records the
        thickness (its ``status`` stays the claim, qualified by ``plate.holds_for``).

        Returns
        -------
        Certification
            A copy; this one is not changed.
        """
        import copy

        out = copy.copy(self)
        out.thickness = None if thickness is None else float(thickness)
        out.plate_note = "" if thickness is not None else (note or "thickness not measured")
        if out.straight is None:
            out.straight = self.status
        if out.straight == "proved" or out.proved_section is not None:
            out.status = "proved" if out.covers_plate else "undecided"  # by the plate it covers
        if self.certificate:
            out.certificate = {**self.certificate}
            out.certificate["plate"] = {**self.certificate.get("plate", {}),
                                        "thickness": out.thickness}  # fmt: skip
        return out

    def with_section(self, outcome, entry: dict) -> Certification:
        """This answer completed by a slab-section proof (:mod:`sieve_mi.certify.section`).

        A proved section at thickness t makes the claim hold on plates at least t thick
        (:data:`SECTION_PLATES`), and the certificate carries the proof (``section``) for the
        replay; an unproved one is only recorded in :attr:`section`. That holds whether the
        straight search proved or left cells open (:attr:`proved_section`): then ``status`` and
        the certificate's ``status`` become "proved" (``straight`` keeps the tree's own answer,
        and the replay accepts open cells beside a section it re-proves). A passage is never
        overruled.

        Returns
        -------
        Certification
            A copy; this one is not changed.
        """
        import copy

        out = copy.copy(self)
        out.section = {
            "status": outcome.status,
            "thickness": float(outcome.thickness),
            "pin": [float(c) for c in outcome.pin],
            "seconds": float(outcome.seconds),
            "cells_examined": outcome.examined,
            "cells_excluded": outcome.excluded,
            "cells_open": outcome.open_cells,
        }
        out.seconds = self.seconds + float(outcome.seconds)
        if outcome.status != "proved" or self.straight not in STRAIGHT_OPEN:
            return out
        out.holds_for = SECTION_PLATES
        out.status = "proved" if out.thickness is None or out.covers_plate else "undecided"
        if self.certificate:
            out.certificate = {**self.certificate, "section": entry, "status": "proved"}
            out.certificate["plate"] = {**self.certificate.get("plate", {}),
                                        "holds_for": SECTION_PLATES}  # fmt: skip
        return out

    def excluded_percent(self, digits: int = 2) -> str:
        """The excluded share of rotations as a percentage, never rounded up to 100 (see
        :func:`excluded_percent`)."""
        complete = (self.straight or self.status) == "proved"
        return excluded_percent(self.excluded_fraction, complete, digits)

    def scope_line(self, units: str = "mm") -> str:
        """One line on what the answer covers (empty for an undecided straight search)."""
        d = f"{self.diameter:.4g} {units}" if self.diameter is not None else "its diameter"
        if self.holds_for == ANY_PLATE and self.straight == "passage":
            return "the passage is straight through: it passes a plate of any thickness"
        if self.holds_for == ANY_PLATE:
            return (
                "holds on a plate of any thickness (a ball inside the part is wider than any "
                "disk in the hole)"
            )
        if self.holds_for == SECTION_PLATES:
            t = self.section["thickness"]
            line = (
                f"holds on plates at least {t:.4g} {units} thick, by any motion (the part's slab "
                f"section about a pinned point never fits the hole; the part is {d} across)"
            )
            if self.by_section:
                line += (
                    "; proved by the section alone: the straight search left cells open, and "
                    "a straight passage would pass every plate"
                )
            return line
        if self.holds_for != THICK_PLATES:
            return ""
        if self.thickness is None and not self.plate_note:
            return (
                f"proved for straight passage, or plates at least the part's {d} diameter thick "
                "(an outline has no thickness; a thinner plate may let it through tilted)"
            )
        if self.covers_plate:
            return f"holds on this plate: {self.thickness:.4g} {units} thick, the part {d} across"
        plate = (
            f"the plate is {self.thickness:.4g} {units} thick and the part {d} across"
            if self.thickness is not None
            else f"{self.plate_note} (the part is {d} across)"
        )
        return (
            f"proved that no pose passes straight through, but {plate}: a tilted passage is not "
            "excluded (see `sieve-mi check --sieve` for a motion search)"
        )

    def to_dict(self) -> dict:
        """The result as plain JSON-ready data (without the certificate)."""
        return {
            "status": self.status,
            "seconds": self.seconds,
            "method": self.method,
            "cells_examined": self.cells_examined,
            "cells_excluded": self.cells_excluded,
            "cells_open": self.cells_open,
            "excluded_fraction": self.excluded_fraction,
            "depth": self.depth,
            "symmetry": self.symmetry,
            "passage": self.passage,
            "margin": self.margin,
            "margin_steps": self.margin_steps,
            "straight": self.straight,
            "holds_for": self.holds_for,
            "diameter": self.diameter,
            "thickness": self.thickness,
            "covers_plate": self.covers_plate,
            **({"plate_note": self.plate_note} if self.plate_note else {}),
            **({"section": self.section} if self.section is not None else {}),
        }

    def write_certificate(self, path: str, inputs: tuple[str, ...] = ()) -> None:
        """Write the certificate (JSON) to ``path``, atomically.

        ``path`` is checked first with :func:`writable_certificate` (never a file sieve-mi did
        not write, never one of ``inputs``). The JSON goes to a new temporary file in the same
        folder (created exclusively, so no file of the user's is touched), is flushed to disk and
        then renamed over ``path`` (``os.replace``): an interrupted or failed write leaves
        ``path`` as it was and no temporary file behind.

        Raises
        ------
        SieveError
            If ``path`` is refused or cannot be written.
        """
        writable_certificate(path, inputs)
        folder = os.path.dirname(os.path.abspath(path))
        try:
            fd, tmp = tempfile.mkstemp(
                prefix=f".{os.path.basename(path)}.", suffix=".tmp", dir=folder
            )
        except OSError as e:
            raise SieveError(
                f"--certificate {path}: cannot write the certificate ({e.strerror})"
            ) from None
        try:
            with os.fdopen(fd, "w") as fh:
                json.dump(self.certificate, fh)
                fh.flush()
                os.fsync(fh.fileno())
            os.chmod(tmp, _new_file_mode())
            os.replace(tmp, path)
        except OSError as e:
            raise SieveError(
                f"--certificate {path}: cannot write the certificate ({e.strerror})"
            ) from None
        finally:
            if os.path.lexists(tmp):
                os.remove(tmp)


def _new_file_mode() -> int:
    """The permission bits ``open(path, "w")`` would give a new file (0o666 less the umask)."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


#: The keys every certificate has, at the top level and in ``shape`` and ``settings`` (those of
#: the first certificates too: ``on_edge`` and ``settings.bound`` came later).
REQUIRED = {
    "": ("format", "status", "shape", "hole", "symmetry", "root", "tree", "settings", "passage"),
    "shape": ("sha256", "vertices", "faces", "points"),
    "settings": ("kappa", "directions"),
}


def is_certificate(data) -> bool:
    """Whether parsed JSON ``data`` is a sieve-mi certificate: a JSON object whose top-level
    ``format`` is :data:`FORMAT` and that has a certificate's structure (the keys of
    :data:`REQUIRED`; ``shape`` and ``settings`` objects, ``hole`` and ``tree`` lists).

    A file is recognised only by parsing it, never by a string it contains: a note that quotes
    the format line, or a JSON collection holding a certificate, is not a certificate.
    """
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        return False
    if not all(k in data for k in REQUIRED[""]):
        return False
    for part in ("shape", "settings"):
        if not isinstance(data[part], dict) or not all(k in data[part] for k in REQUIRED[part]):
            return False
    return isinstance(data["hole"], list) and isinstance(data["tree"], list)


#: Largest file :func:`read_certificate_file` parses (bytes); a larger one is not taken for one.
MAX_CERTIFICATE_BYTES = 1 << 30


def read_certificate_file(path: str):
    """The parsed JSON of the file at ``path``, or None when it is not JSON text.

    Only a file whose first non-blank character is ``{`` and of at most
    :data:`MAX_CERTIFICATE_BYTES` is parsed (a binary file, a note, a mesh or a large data set
    is never read whole); too deep a nesting or too long an integer reads as not JSON.
    """
    try:
        if os.path.getsize(path) > MAX_CERTIFICATE_BYTES:
            return None
        with open(path, "rb") as fh:
            head = fh.read(64).lstrip()
            if not head.startswith(b"{"):
                return None
            fh.seek(0)
            return json.loads(fh.read().decode("utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError, MemoryError):
        return None


def writable_certificate(path: str, inputs: tuple[str, ...] = ()) -> None:
    """Refuse, in one line, a certificate path that writing would lose data at.

    The same rule as ``--out``: sieve-mi replaces only a certificate it wrote itself (recognised
    by parsing it, :func:`is_certificate`), never one of the run's ``inputs`` (mesh, plate, SVG),
    a folder, a symbolic link, a read-only file, any other file, or a file in a folder it cannot
    write to. Called before any work and again just before the write.

    Raises
    ------
    SieveError
    """
    if not isinstance(path, (str, os.PathLike)) or not os.fspath(path):
        raise SieveError(f"--certificate {path!r}: name a file (e.g. cert.json)")
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    if os.path.isdir(path) or path.endswith((os.sep, "/")):
        example = os.path.join(path.rstrip("/" + os.sep) or os.sep, "cert.json")
        raise SieveError(f"--certificate {path}: is a folder; name a file (e.g. {example})")
    if os.path.islink(path):
        raise SieveError(f"--certificate {path}: is a symbolic link; name a regular file")
    if not os.path.isdir(folder):
        raise SieveError(f"--certificate {path}: its folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise SieveError(f"--certificate {path}: its folder {folder} is not writable")
    if not os.path.lexists(path):
        return
    _existing_is_replaceable(path, inputs)


def _existing_is_replaceable(path: str, inputs: tuple[str, ...]) -> None:
    """Refuse an existing ``path`` unless it is a writable certificate that is no input."""
    for given in inputs:
        if given and os.path.exists(given) and os.path.samefile(path, given):
            raise SieveError(f"--certificate {path}: is an input of this run; name another file")
    if not os.path.isfile(path) or not is_certificate(read_certificate_file(path)):
        raise SieveError(
            f"--certificate {path}: exists and is not a sieve-mi certificate; name another file "
            "(sieve-mi never overwrites a file it did not write)"
        )
    if not os.access(path, os.W_OK):
        raise SieveError(f"--certificate {path}: is read-only; name another file")
