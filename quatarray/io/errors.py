"""What can go wrong with the user's files and requests, as exceptions that say it.

The library raises them with a one-line message naming the file, the row or
the option and what is wrong; it does not decide what a program does with
them. The command line (:mod:`quatarray.app.cli`) prints the line and maps the
class to its exit status (:data:`quatarray.app.cli.EXIT_STATUS`).
"""


class DataError(Exception):
    """Bad data in an input: the message names the file, the line or row, and what
    is wrong, e.g. ``walk.csv:1234: expected 8 numbers, got 7``."""


class UsageError(Exception):
    """A request that cannot be carried out as asked: a bad option value, an output
    of the wrong kind, a feature that needs a package that is not installed."""


class OutputError(UsageError):
    """An output cannot be written: an unwritable folder, a full disk, a file-size
    limit (the data are fine)."""
