"""The one exception that panomap raises for bad input.

The CLI prints its message as one line on stderr and exits non-zero; library
users catch it like any ``ValueError``.
"""

from __future__ import annotations


class PanomapError(ValueError):
    """Bad input or an impossible request, with a message that says why.

    Parameters
    ----------
    message : str
        What is wrong, in one line.
    source : str or path-like, optional
        The file (or argument) the problem is in; prefixed to the message.
    """

    def __init__(self, message: str, source: object | None = None) -> None:
        self.source = None if source is None else str(source)
        self.detail = message
        super().__init__(message if source is None else f"{source}: {message}")


def printable(text: str, keep: str = "") -> str:
    """``text`` with every control and format character escaped (``\\x1b``, ``\\u202e``), for a terminal.

    A name read from a file (a landmark's, a path's) can hold escape sequences that retitle or
    rewrite the user's terminal, or bidirectional overrides that show it reversed: everything
    printed that came from a file goes through here. Characters in ``keep`` (``"\\n"`` for a
    multi-line listing) pass unchanged.
    """
    import unicodedata

    def escaped(char: str) -> str:
        if char in keep or unicodedata.category(char) not in ("Cc", "Cf", "Zl", "Zp"):
            return char
        code = ord(char)
        return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"

    return "".join(escaped(char) for char in text)
