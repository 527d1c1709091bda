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
