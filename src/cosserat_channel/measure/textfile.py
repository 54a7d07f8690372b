"""Text files of the reports, written atomically.

A convenience over :func:`cosserat_channel.files.atomic_output`, through which every file of the
package goes: a report rewritten in place is replaced only by a complete one.
"""

from __future__ import annotations

from ..files import atomic_output


def write_text(path, text: str) -> None:
    """Write ``text`` to ``path`` (UTF-8, newlines as given) atomically."""

    def write(tmp):
        # newline="": the text's own line ends, on every platform (the CSV's "\n" stays "\n").
        with open(tmp, "w", encoding="utf-8", newline="") as fh:
            fh.write(text)

    atomic_output(path, write)
