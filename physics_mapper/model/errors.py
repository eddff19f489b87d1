"""User-facing errors and the exit codes of ``physics-mapper`` and the node.

Kept apart from :mod:`physics_mapper.cli` so that ``python -m physics_mapper`` (which runs the
CLI as ``__main__``) and the command modules share one ``InputError`` class.
"""

EXIT_FAILURE = 1
EXIT_BAD_INPUT = 2
#: ``evaluate`` and ``sweep``: the report was written, but some bags could not be evaluated (listed in it).
EXIT_INCOMPLETE = 3
#: Stopped by Ctrl-C (SIGINT), 128 + its signal number, as shells report it.
EXIT_INTERRUPTED = 130


class InputError(Exception):
    """A user-facing error about an input (file, bag, argument): printed without a traceback."""
