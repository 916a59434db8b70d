"""Everything a run writes: files, pictures, the page. Rule: outputs read results, never play.

Modules
-------
report
    ``report.json``; :func:`~sieve_mi.outputs.report.write_outputs` writes a solve's folder.
images
    The rasters on the hole's lattice: ``hole.png``, ``hole.exr``, the EXR masks.
plots
    The matplotlib pictures (``overlay.png``, ``convergence.png``) and their layout: text off the
    shapes, axes and scale bars in 2D views.
palette
    One palette for every picture sieve-mi draws.
console
    What is printed on the terminal: the result tables and summary lines of solve and check.
viewer
    ``report.html`` (and the ``check`` page): one offline page with a 3D view (``assets/``); it
    places other commands' cards in the page (:func:`~sieve_mi.outputs.viewer.insert_card`).
svg
    The pages' inline SVG pictures: the 2D hole view and the convergence plot.
stage
    The Mitsuba stage of ``figure.png`` and ``passage.gif``: the RGB variant, a camera looking at
    a box, sky and sun, the palette's materials on meshes, sRGB.
figure
    ``figure.png``: a Mitsuba rendering of the sieve.
animation
    ``passage.gif``: the shapes moving through (or stopping at) the plate.
pictures
    ``figure.png`` and ``passage.gif`` rendered in a worker process beside the rest of the save
    (the command line forks it first thing, beside its own start).
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
    "console",
    "fabrication",
    "figure",
    "images",
    "outdir",
    "passage",
    "pictures",
    "plots",
    "provenance",
    "report",
    "stage",
    "svg",
    "viewer",
]
