"""sieve-mi's version, in one place (``sieve_mi.__version__``; pyproject.toml reads it from here)."""

from __future__ import annotations

__all__ = ["VERSION"]

#: sieve-mi's version.
VERSION = "0.1.0"
