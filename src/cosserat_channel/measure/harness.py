"""What every benchmark and report shares: best-of timing, the header, verdicts, a JSON record.

A script in ``benchmarks/`` builds its parser with :func:`parser` (which adds ``--json PATH``),
opens a :class:`Record` (which prints the header: command, date, machine, commit, versions),
times with :func:`best_of`, judges each target with :meth:`Record.check`, keeps its numbers with
:meth:`Record.add` and ends with :meth:`Record.finish`, which writes everything as JSON when
``--json`` was given. The reports of ``cosserat-channel bench`` and ``stability`` word their
verdicts with :class:`Verdict` too, so PASS and FAIL mean the same everywhere.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import shlex
import sys
import time
from dataclasses import dataclass
from typing import Callable, NamedTuple

from . import machine

WORDS = {True: "PASS", False: "FAIL", None: "NOT MEASURED"}


# ---------------------------------------------------------------------------------------------
# Timing
# ---------------------------------------------------------------------------------------------
class Timing(NamedTuple):
    """What :func:`best_of` measured."""

    seconds: float  # per call, the fastest repeat
    result: object  # what the last call returned
    times: tuple  # per call, each repeat in order


def best_of(call: Callable[[], object], repeat: int = 5, *, inner: int = 1,
            min_seconds: float = 0.0, max_inner: int = 1_000_000, warm_up: bool = False,
            clock: Callable[[], float] = time.perf_counter) -> Timing:
    """Time ``call()``: the fastest of ``repeat`` timings of ``inner`` calls each, per call.

    The fastest, because on a shared machine other jobs only ever add time. With
    ``min_seconds`` a first call (untimed, it also warms up) sets ``inner`` so that one timing
    lasts about that long (at most ``max_inner`` calls): a call much shorter than the clock's
    resolution or a scheduler tick is timed in bulk. ``warm_up`` makes the first call without
    ``min_seconds``. ``clock`` is ``time.perf_counter`` (wall) or ``time.thread_time`` (CPU of
    this thread, blind to waiting for a core).
    """
    result = None
    if warm_up or min_seconds > 0:
        t0 = clock()
        result = call()
        once = clock() - t0
        if min_seconds > 0:
            inner = max(inner, min(max_inner, int(min_seconds / max(once, 1e-9))))
    times = []
    for _ in range(max(1, repeat)):
        t0 = clock()
        for _ in range(inner):
            result = call()
        times.append((clock() - t0) / inner)
    return Timing(min(times), result, tuple(times))


# ---------------------------------------------------------------------------------------------
# Verdicts
# ---------------------------------------------------------------------------------------------
def word(passed: bool | None) -> str:
    """``PASS``, ``FAIL`` or ``NOT MEASURED`` (``passed`` True, False or None)."""
    return WORDS[None if passed is None else bool(passed)]


@dataclass
class Verdict:
    """One target and how a run did against it.

    ``passed`` is None when the run could not measure it; a target that is not ``required`` is
    reported, never a reason to fail. ``note`` qualifies a verdict without changing it (a result
    more accurate than a tolerance band asks for still passes, and says so).
    """

    text: str
    passed: bool | None
    detail: str = ""
    required: bool = True
    note: str = ""

    @property
    def word(self) -> str:
        return word(self.passed) + (f" ({self.note})" if self.note else "")

    @property
    def missed(self) -> bool:
        """A required target measured and not met."""
        return self.required and self.passed is False

    def line(self, bold: bool = False) -> str:
        """``PASS: text: detail`` (``**PASS**`` in markdown)."""
        w = f"**{self.word}**" if bold else self.word
        return f"{w}: {self.text}" + (f": {self.detail}" if self.detail else "")

    def as_dict(self) -> dict:
        return {"target": self.text, "verdict": word(self.passed), "passed": self.passed,
                "required": self.required, "note": self.note, "detail": self.detail}


# ---------------------------------------------------------------------------------------------
# The header and the record
# ---------------------------------------------------------------------------------------------
def header(argv=None, **others) -> dict:
    """Where and with what a measurement ran: command, date, machine (CPU, cores, OS), git
    commit and versions (``others``: more ``name=version`` pairs, e.g. ``dask=...``)."""
    argv = sys.argv if argv is None else argv
    versions = machine.version_table(**others)
    return {
        "command": shlex.join([sys.executable, *map(str, argv)]),
        "date": datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z"),
        "machine": {"cpu": machine.cpu_model(), "cores": os.cpu_count(), "os": machine.os_name()},
        "commit": versions["git"],
        "versions": versions,
    }


def header_lines(head: dict) -> list[str]:
    """The header as the lines a benchmark prints first."""
    m = head["machine"]
    return [f"command:  {head['command']}", f"date:     {head['date']}",
            f"machine:  {m['cpu']}, {m['cores']} cores, {m['os']}",
            f"versions: {machine.format_versions(head['versions'])}"]


def json_problem(path: str, overwrite: bool = False) -> str | None:
    """Why ``--json PATH`` cannot be written (one line), or None: the package's rule for every
    output (:func:`cosserat_channel.files.output_problem`): an existing file is kept unless
    ``overwrite``, a character device or a FIFO receives the JSON as a stream, anything else
    that is not a regular file is refused and left as it is."""
    from ..files import output_problem

    return output_problem(path, overwrite=overwrite)


class _Parser(argparse.ArgumentParser):
    """An ArgumentParser that checks ``--json PATH`` as soon as the arguments are parsed, before
    any work."""

    def parse_known_args(self, args=None, namespace=None):
        ns, rest = super().parse_known_args(args, namespace)
        if getattr(ns, "json", None) is not None:
            problem = json_problem(ns.json, ns.overwrite)
            if problem:
                self.error(f"--json: {problem}")
        return ns, rest


def parser(doc: str) -> argparse.ArgumentParser:
    """An ArgumentParser described by ``doc``'s first line, with ``--json PATH`` and
    ``--overwrite``."""
    ap = _Parser(description=doc.strip().splitlines()[0])
    ap.add_argument("--json", metavar="PATH",
                    help="also write the header, the numbers and the verdicts to PATH as JSON")
    ap.add_argument("--overwrite", action="store_true",
                    help="replace the --json file if it exists (without it an existing file is "
                    "kept and the run refused before any work)")
    return ap


def plain(value):
    """``value`` with numpy scalars and arrays as Python numbers and lists, tuples as lists and
    non-finite floats as None (JSON has no NaN)."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if hasattr(value, "tolist"):  # numpy scalar or array
        return plain(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


class Record:
    """One run of a benchmark: its header, numbers and verdicts, printed and kept for JSON.

    Parameters
    ----------
    name : str
        The benchmark (``bench_point``, ...).
    json : str, optional
        Where :meth:`finish` writes the JSON (``--json``); nothing is written without it.
    echo : bool
        Print the header now.
    others :
        More ``name=version`` pairs for the header.
    """

    def __init__(self, name: str, json: str | None = None, *, echo: bool = True, argv=None,
                 **others):
        self.name = name
        self.json = json
        self.header = header(argv, **others)
        self.results: dict = {}
        self.verdicts: list[Verdict] = []
        if echo:
            for line in header_lines(self.header):
                print(line, flush=True)

    def add(self, key: str, value) -> None:
        """Keep ``value`` (a number, a dict of numbers, a list of rows) under ``key``."""
        self.results[key] = value

    def row(self, table: str, **values) -> None:
        """Append one row (a dict) to the list ``results[table]``."""
        self.results.setdefault(table, []).append(values)

    def check(self, text: str, passed: bool | None, detail: str = "", **kw) -> Verdict:
        """Record a verdict on ``text`` and return it (its ``word`` goes into the caller's line)."""
        v = Verdict(text, None if passed is None else bool(passed), detail, **kw)
        self.verdicts.append(v)
        return v

    def as_dict(self) -> dict:
        return plain({"benchmark": self.name, "header": self.header, "results": self.results,
                      "verdicts": [v.as_dict() for v in self.verdicts]})

    def finish(self) -> int:
        """Write the JSON (with ``--json``) and return the exit code: 0 (a missed target is a
        result of the measurement, printed as FAIL, not a failure to measure)."""
        if self.json:
            from ..files import write_text

            write_text(self.json, json.dumps(self.as_dict(), indent=1, allow_nan=False) + "\n")
            print(f"wrote {self.json}")
        return 0
