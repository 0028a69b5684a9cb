"""Errors a user can cause. The command line turns them into one line, exit 2."""
from __future__ import annotations


class UserError(Exception):
    """A mistake in user input: bad file, key, option or unphysical value.

    ``str(err)`` is the one line shown to the user; it names the file and key
    where known, the value found and what was expected.
    """

    def __init__(self, message: str, *, file: str | None = None, key: str | None = None):
        self.file, self.key, self.detail = file, key, message
        where = ": ".join(x for x in (file, key) if x)
        super().__init__(f"{where}: {message}" if where else message)


class Cancelled(Exception):
    """Raised by a long job (identification, multi-start) that stops early on request."""
