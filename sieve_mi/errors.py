"""User-facing errors.

Every problem a user can fix (a missing file, a bad key, an unreadable mesh) is raised as
:class:`SieveError`; the command line prints its message as one line and exits with code 2.
"""

__all__ = ["SieveError"]


class SieveError(Exception):
    """An error in the user's input or environment, with a one-line message saying what to do."""
