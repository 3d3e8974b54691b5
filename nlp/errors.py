"""User-facing input errors.

A user mistake (a bad case file or data file) is reported as one `InputError`
that names the file, the key and what was expected. The CLI prints the message
and exits with status 2, without a traceback. Programming errors stay ordinary
exceptions.
"""

__all__ = ["InputError", "SearchFailed", "ARGUMENTS", "WHOLE_FILE"]

ARGUMENTS = "<arguments>"   # the "file" of a bad command-line argument or function argument
WHOLE_FILE = "<file>"       # the "key" of an error about a whole file (missing, unreadable)


class InputError(ValueError):
    """Bad input in a case or data file.

    Parameters
    ----------
    file : str
        The file the bad value came from (or ``ARGUMENTS`` for the CLI).
    key : str
        The key, column or channel that is wrong, as a dotted path
        (``"model.masses[2]"``).
    expected : str
        What a valid value looks like, in words.
    got : object, optional
        The offending value, shown shortened.
    """

    def __init__(self, file, key, expected, got=None):
        self.file = str(file)
        self.key = str(key)
        self.expected = expected
        self.got = got
        msg = f"{self.file}: '{self.key}': expected {expected}"
        if got is not None:
            text = repr(_plain(got))
            if len(text) > 80:
                text = text[:77] + "..."
            msg += f", got {text}"
        super().__init__(msg)


def _plain(x):
    """Numbers as plain Python values, so messages read 1019.0, not np.float64(1019.0)."""
    if hasattr(x, "tolist") and callable(x.tolist):  # numpy scalars and arrays
        return x.tolist()
    if isinstance(x, (list, tuple)):
        return type(x)(_plain(v) for v in x)
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    return x


class SearchFailed(RuntimeError):
    """No local solve of the search converged; nothing is written (CLI exit status 3)."""
