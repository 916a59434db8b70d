"""One palette for every picture sieve-mi draws.

overlay.png, figure.png, the report page (its 3D view, hole view and toggles), passage.gif and
cascade.png take their colours from here, so a colour means the same everywhere:

========== ======================================== ===========
name       what                                     colour
========== ======================================== ===========
pass       a shape of A (must pass; part of H)      green
blocked    a B that H blocks                        red
escaped    a B that gets through H                  orange
plate      the sieve plate (3D)                     grey
material   the plate around the hole (2D views)     light grey
hole       the hole H (2D views)                    white
edge       the hole's outline (2D views)            dark grey
curve      plotted values (convergence)             blue
tray       what a cascade's tray holds              sand
background the page's 3D view                       off-white
========== ======================================== ===========

Colours are sRGB display values in [0, 1] (what a PNG, a web page or matplotlib shows).
Mitsuba's renderers take reflectances in linear RGB: :func:`linear` converts, so a lit surface
shows about the palette's colour.
"""

from __future__ import annotations

__all__ = ["PALETTE", "block_colour", "css_variables", "hex_colour", "linear"]

#: name -> sRGB (r, g, b) in [0, 1].
PALETTE: dict[str, tuple[float, float, float]] = {
    "pass": (0.161, 0.620, 0.239),  # #299e3d
    "blocked": (0.800, 0.122, 0.102),  # #cc1f1a
    "escaped": (0.961, 0.549, 0.102),  # #f58c1a
    "plate": (0.620, 0.631, 0.659),  # #9ea1a8
    "material": (0.725, 0.737, 0.761),  # #b9bcc2
    "hole": (1.0, 1.0, 1.0),  # #ffffff
    "edge": (0.333, 0.333, 0.333),  # #555555
    "curve": (0.122, 0.435, 0.698),  # #1f6fb2
    "tray": (0.992, 0.682, 0.420),  # #fdae6b
    "background": (0.97, 0.97, 0.98),  # #f7f7fa
}


def hex_colour(name: str) -> str:
    """A palette colour as ``#rrggbb`` (matplotlib, SVG, CSS)."""
    return "#" + "".join(f"{round(255 * c):02x}" for c in PALETTE[name])


def block_colour(blocked: bool) -> str:
    """The palette name of a B: ``"blocked"`` (red) or ``"escaped"`` (orange, it gets through)."""
    return "blocked" if blocked else "escaped"


def linear(name: str) -> tuple[float, float, float]:
    """A palette colour in linear RGB (the sRGB transfer function undone), for Mitsuba's BSDFs."""
    return tuple(c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4 for c in PALETTE[name])


def css_variables() -> str:
    """A ``<style>`` rule declaring every colour as a CSS variable (``--pass``, ``--blocked``, ...)."""
    body = " ".join(f"--{name}: {hex_colour(name)};" for name in PALETTE)
    return f":root {{ {body} }}\n"
