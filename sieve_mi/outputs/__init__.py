"""Everything a run writes: files, pictures, the page. Rule: outputs read results, never play.

Modules
-------
report
    ``report.json``, the rasters and EXR masks, overlay and convergence plots, the console table;
    :func:`~sieve_mi.outputs.report.write_outputs` writes a solve's folder.
viewer
    ``report.html`` (and the ``check`` page): one offline page with a 3D view (``assets/``).
figure
    ``figure.png``: a Mitsuba rendering of the sieve.
plots
    The layout of the matplotlib pictures: text off the shapes, axes and scale bars in 2D views.
animation
    ``passage.gif``: the shapes moving through (or stopping at) the plate.
passage
    The 3D passage scene shared by the page and the GIF.
fabrication
    The printable plate (STL, 3MF), ``hole.svg`` and the placed shapes.
outdir
    Safe output folders: validated up front, written aside and swapped in.
provenance
    Seed, variant, versions, machine and input hashes of a run.
"""

__all__ = [
    "animation",
    "fabrication",
    "figure",
    "outdir",
    "passage",
    "plots",
    "provenance",
    "report",
    "viewer",
]
