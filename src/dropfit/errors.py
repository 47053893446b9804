"""The one exception type for problems with a user's input, and how messages quote the user's text."""

from __future__ import annotations

import re
import unicodedata

#: Longest quoted value (a cell, a column name) in a message, characters.
QUOTE_LIMIT = 60
#: Longest path in a message, characters (its end, with the file name, is kept).
PATH_LIMIT = 100
#: Longest message line, characters: a guard only, far above any message dropfit composes (its longest, a
#: refused video's with the tracker's help, are about 1000). A message is never shortened for length: the user
#: text it quotes is (:func:`shown`, :func:`shown_path`), its diagnosis and advice are not. The old limit of 284
#: cut a 726-character refusal in its middle, where the diagnosis and the options were.
LINE_LIMIT = 4000
#: Terminal escape sequences (CSI such as ``ESC[31m``, OSC such as a window title, and two-byte ones).
_ESCAPES = re.compile(r"\x1b\[[0-?]*[ -/]*[@-~]|\x1b\][^\x07\x1b]*(?:\x07|\x1b\\)?|\x1b[@-Z\\-_]|\x9b[0-?]*[ -/]*[@-~]")
_LINE_BREAKS = re.compile(r"[\r\n\t\v\f\x85\u2028\u2029]+")


class InputError(Exception):
    """A recording or configuration that cannot be analysed.

    The message is one line that names the file, says what is wrong and, where it helps, what to
    do. The command line prints it without a traceback.
    """


class OutputError(InputError):
    """An output that cannot be written because of the user's environment: a folder without write permission, a
    read-only or full disk, a file where a folder belongs (:func:`dropfit.files.writing`). The message names the
    path and what to do; no failure record is written (it would meet the same disk)."""


class NotFreeFallError(InputError):
    """The flights of a recording do not fall with g: its units or scale are wrong, or (a video) what was
    tracked is not the ball in flight.

    Attributes
    ----------
    acceleration_m_s2 : float
        The flights' shared downward acceleration, m/s².
    """

    def __init__(self, message, acceleration_m_s2):
        super().__init__(message)
        self.acceleration_m_s2 = acceleration_m_s2


def shown(text, limit=QUOTE_LIMIT, keep="start"):
    """User text (a cell value, a column name, a path) made safe to quote in a one-line message.

    A terminal escape sequence (a colour, a cursor move, a window title) becomes one ``?``, line breaks
    and tabs become one space, other control and format characters (NUL, bidirectional overrides, …)
    become ``?``, and text longer than ``limit``
    characters is cut with an ellipsis: at its end (``keep="start"``), at its start (``keep="end"``,
    for paths, whose file name is at the end) or in the middle (``keep="both"``).

    Parameters
    ----------
    text : object
        The text (anything else is converted with ``str``).
    limit : int
        Most characters returned.
    keep : str
        ``"start"``, ``"end"`` or ``"both"``: which part of a long text to keep.
    """
    text = str(text)
    if len(text) > 8 * limit + 64:  # a 5 MB cell: cleaning only what can be shown keeps this fast
        text = text[: 4 * limit + 32] + "\u2026" + text[-(4 * limit + 32):] if keep == "both" else \
            text[-(8 * limit + 64):] if keep == "end" else text[: 8 * limit + 64]
    text = _LINE_BREAKS.sub(" ", _ESCAPES.sub("?", text))
    text = "".join("?" if unicodedata.category(char) in ("Cc", "Cf", "Cs", "Co") else char for char in text)
    if len(text) <= limit:
        return text
    if keep == "end":
        return "\u2026" + text[-(limit - 1):]
    if keep == "both":
        head = (limit - 1) * 2 // 3
        return text[:head] + "\u2026" + text[-(limit - 1 - head):]
    return text[: limit - 1] + "\u2026"


def shown_path(path):
    """A path as quoted in a message: :func:`shown`, keeping its end (the file name)."""
    return shown(path, PATH_LIMIT, keep="end")


def one_line(message):
    """A whole message as printed and recorded, on one line: :func:`shown` (escape sequences, line breaks
    and control characters made harmless), whole up to :data:`LINE_LIMIT` characters, a guard against user
    text quoted without :func:`shown` (shortened in the middle, so that the file named at its start and the
    advice at its end stay)."""
    return shown(message, LINE_LIMIT, keep="both")
