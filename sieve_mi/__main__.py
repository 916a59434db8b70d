"""``python -m sieve_mi``: the ``sieve-mi`` command."""

from sieve_mi.cli import run

run()
