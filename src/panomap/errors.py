"""The one exception that panomap raises for bad input.

The CLI prints its message as one line on stderr and exits non-zero; library
users catch it like any ``ValueError``.
"""

from __future__ import annotations


class PanomapError(ValueError):
    """Bad input or an impossible request, with a message that says why.

    The first line of the message says what is missing and what to do, in the user's words and
    without the command line's option names (the CLI adds those); lines after it, where there are
    any, give the figures behind it (``panomap fit --verbose`` prints them).

    Parameters
    ----------
    message : str
        What is wrong, in one line (at most about 140 characters), then optionally the detail.
    source : str or path-like, optional
        The file (or argument) the problem is in; prefixed to the message.
    """

    def __init__(self, message: str, source: object | None = None) -> None:
        self.source = None if source is None else str(source)
        self.detail = message
        super().__init__(message if source is None else f"{source}: {message}")

    @property
    def summary(self) -> str:
        """The message's first line, with its source: what is missing and what to do."""
        return str(self).split("\n", 1)[0]

    @property
    def figures(self) -> str:
        """The lines after the first (the figures behind it), or ""."""
        parts = str(self).split("\n", 1)
        return parts[1].strip() if len(parts) > 1 else ""


def refusal(summary: str, figures: str) -> str:
    """A refusal's message: ``summary`` (what is missing, what to do; one line) and the ``figures`` behind it on
    the lines after (:attr:`PanomapError.figures`)."""
    return f"{summary}\n{figures}"


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
