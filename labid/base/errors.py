"""Errors a user can cause. The command line turns them into one line, exit 2."""
from __future__ import annotations

import re

#: the most characters of one value an error message echoes (issue 27: a 10 MB value was echoed whole)
VALUE_CHARS = 80
#: the longest message kept (the list of what was expected included)
MESSAGE_CHARS = 600
_QUOTED = re.compile(r"(?<!\w)(?:'(?:[^'\\]|\\.)*'|\"(?:[^\"\\]|\\.)*\")(?!\w)")
_TOKEN = re.compile(r"\S{%d,}" % (2 * VALUE_CHARS + 1))   # paths named in prose keep 160


def clip(text: str, n: int = VALUE_CHARS) -> str:
    """``text`` cut to at most ``n`` characters (ending in '...' when cut)."""
    text = str(text)
    return text if len(text) <= n else text[:n - 3] + "..."


def shown(value: object) -> str:
    """``repr(value)`` for an error message, at most ``VALUE_CHARS`` characters."""
    try:
        text = repr(value)
    except Exception:  # noqa: BLE001 - a value whose repr fails is still named
        text = f"<{type(value).__name__}>"
    return clip(text)


_OPEN = {"[": "]", "{": "}", "(": ")"}
_SPECIAL = re.compile(r"[\[\]{}()'\"\\]")


def _group_end(message: str, i: int) -> int:
    """Index of the bracket closing the one at ``i`` (brackets inside quotes not counted;
    the message's end when it never closes)."""
    depth, quote, skip = 0, "", -1
    for m in _SPECIAL.finditer(message, i):
        j, d = m.start(), m.group()
        if j == skip:
            continue
        if quote:
            if d == "\\":
                skip = j + 1
            elif d == quote:
                quote = ""
        elif d in "'\"":
            if j == 0 or not message[j - 1].isalnum():
                quote = d
        elif d in _OPEN:
            depth += 1
        elif d in ")]}":
            depth -= 1
            if depth == 0:
                return j
    return len(message) - 1


def _clip_groups(message: str, limit: int = 2 * VALUE_CHARS) -> str:
    """Bracketed groups (a list, dict or tuple echoed) longer than ``limit`` cut to
    ``VALUE_CHARS`` characters."""
    out, i = [], 0
    while True:
        k = min((message.find(b, i) for b in _OPEN if message.find(b, i) >= 0), default=-1)
        if k < 0:
            out.append(message[i:])
            return "".join(out)
        j = _group_end(message, k)
        if j - k + 1 > limit:
            out.append(message[i:k] + clip(message[k:j + 1]))
            i = j + 1
        else:
            out.append(message[i:k + 1])
            i = k + 1


def clip_values(message: str) -> str:
    """``message`` with every echoed list, quoted value or unbroken run of more than
    ``VALUE_CHARS`` characters cut to that length, the whole to ``MESSAGE_CHARS``."""
    if len(message) <= VALUE_CHARS:
        return message
    if len(message) > 20_000:                  # the start and the end hold the words; cheap to scan
        message = f"{message[:10_000]} ... {message[-2_000:]}"
    message = _clip_groups(message)
    message = _QUOTED.sub(lambda m: clip(m.group(0)), message)
    message = _TOKEN.sub(lambda m: clip(m.group(0), 2 * VALUE_CHARS), message)
    return clip(message, MESSAGE_CHARS)


class UserError(Exception):
    """A mistake in user input: bad file, key, option or unphysical value.

    ``str(err)`` is the one line shown to the user; it names the file and key
    where known, the value found (at most ``VALUE_CHARS`` characters of it) and
    what was expected.
    """

    def __init__(self, message: str, *, file: str | None = None, key: str | None = None):
        message = clip_values(str(message))
        file = clip(file, 300) if file is not None else None
        key = clip(key) if key is not None else None
        self.file, self.key, self.detail = file, key, message
        where = ": ".join(x for x in (file, key) if x)
        super().__init__(f"{where}: {message}" if where else message)


class Cancelled(Exception):
    """Raised by a long job (identification, multi-start) that stops early on request."""
