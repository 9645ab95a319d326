"""The two kinds of user error the command line reports without a traceback."""


class DataError(Exception):
    """Bad data in an input file (exit status 1).

    The message is one line that names the file, the line or row, and what
    is wrong, e.g. ``walk.csv:1234: expected 8 numbers, got 7``.
    """


class UsageError(Exception):
    """A bad command line or a refused operation (exit status 2)."""


class OutputError(UsageError):
    """OUT cannot be written: an unwritable folder, a full disk, a file-size limit
    (exit status 2, as a refused operation: the data are fine)."""
